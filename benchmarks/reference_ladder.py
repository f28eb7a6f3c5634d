"""What does ngspice converge to on a deck? ``python benchmarks/reference_ladder.py DECK``.

Runs ngspice 39 on the deck as its reference is made (``_corpus.wrapper``: the deck's own
``.tran``, ``reltol``, ``TMAX = TSTEP/divisor``) down a ladder of settings, each rung's
run taken as a reference is (``_corpus.thin``: the kept vectors at every m-th point plus
each one's min and max) and measured against the next, finer rung by the corpus's own
measure (``_corpus.compare_ngspice``: the finer run linear between its points, each
signal's error over its peak, the worst signal; "PCHIP" the finer run by its monotone
cubic, see ``reference_audit.py``), and the committed reference against every rung. Two
successive rungs within ``1e-4`` of peak (a tenth of the corpus's tolerance) say where
ngspice has converged. With ``--save DIR`` each rung's thinned run is written as
``DIR/<deck>_d<divisor>_r<reltol>.csv.gz`` (``_corpus.write_reference``'s format, so that
``_corpus.load_reference`` style reading and diracvi's comparison can use it).

    python benchmarks/reference_ladder.py es_transformer --divisor 50 --divisor 500 \\
        --divisor 5000 --divisor 50000                     # TMAX ladder at reltol 1e-7
    python benchmarks/reference_ladder.py liec_doubler --divisor 5000 --reltol 1e-7 \\
        --reltol 1e-8 --reltol 1e-9                        # reltol ladder at one TMAX

Several ``--divisor`` and several ``--reltol`` make the rungs their product, TMAX varying
fastest. Each run is limited to ``--cpu`` seconds of CPU (default 600). The raw file is
read streaming, the kept vectors only (``_corpus.read_raw``), so a 1e7-point run's memory
is its array.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

import numpy as np  # noqa: E402
from reference_audit import pchip_error, run_limited  # noqa: E402
from scipy.interpolate import PchipInterpolator  # noqa: E402

import _corpus as corpus  # noqa: E402  (after the path set-up above)


def thinned(names, data, tran):
    """The run taken as a reference is: ``(t, {vector: values})``."""
    keep = corpus.thin(data[:, 0], tran.start, [data[:, j] for j in range(1, len(names))])
    return data[keep, 0], {n: data[keep, j] for j, n in enumerate(names) if j}


def dense(names, data, prev_names, prev) -> str:
    """The worst error of this run at *all* its points against the previous run's PCHIP
    interpolant, over the previous run's peak (worst signal and time): a thinned run
    misses a few points' glitch in a finer one (ngspice's trapezoidal rule ringing after a
    step cut, ``es_transformer``), this does not; it holds the previous run's
    interpolation error too."""
    t, tp = data[:, 0], prev[:, 0]
    inc = np.append(np.diff(tp) > 0, True)  # a breakpoint written twice: its later value
    worst = (0.0, "", 0.0)
    for j, n in enumerate(names):
        if j == 0 or n not in prev_names:
            continue
        ref = prev[:, prev_names.index(n)]
        err = np.abs(data[:, j] - PchipInterpolator(tp[inc], ref[inc])(t))
        floor = corpus.ABSTOL if n.startswith("i(") else corpus.VNTOL
        err /= max(float(np.max(np.abs(ref))), floor)
        k = int(np.argmax(err))
        if err[k] > worst[0]:
            worst = (float(err[k]), n, float(t[k]))
    return f"{worst[0]:.2g} {worst[1]} at {worst[2]:.6g}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("deck")
    parser.add_argument("--divisor", type=float, action="append", default=[])
    parser.add_argument("--reltol", type=float, action="append", default=[])
    parser.add_argument("--cpu", type=float, default=600.0)
    parser.add_argument("--save", type=Path)
    args = parser.parse_args(argv)
    entry = corpus.load_expected()[args.deck]
    deck = corpus.DATA / entry["file"]
    tran = corpus.find_tran(deck.read_text(errors="replace"))
    divisors = args.divisor or [corpus.reference_divisor(deck)]
    reltols = args.reltol or [corpus.RELTOL]
    committed = corpus.load_reference(args.deck)
    print(f"{args.deck}: reference at TSTEP/{corpus.reference_divisor(deck):g}, reltol 1e-7")
    print(
        "divisor  reltol  points  CPU s | prev vs this (PCHIP) worst | committed vs this"
        " (PCHIP) | dense: this at all its points vs prev's PCHIP"
    )
    previous = full = None
    for reltol in reltols:
        for divisor in divisors:
            names, data, cpu = run_limited(deck, divisor, reltol, args.cpu)
            if names is None:
                print(f"{divisor:7g}  {reltol:6.0e}  timeout past {cpu:.0f} s CPU", flush=True)
                previous = full = None
                continue
            cells = [f"{divisor:7g}  {reltol:6.0e}  {len(data):7d}  {cpu:6.1f}"]
            for ref in (previous, committed):
                if ref is None:
                    cells.append("-")
                    continue
                worst, errors, _ = corpus.compare_ngspice(names, data, *ref)
                cells.append(
                    f"{worst:.2g} ({pchip_error(names, data, *ref):.2g}) "
                    f"{max(errors, key=errors.get)}"
                )
            cells.append("-" if full is None else dense(names, data, *full))
            print(" | ".join(cells), flush=True)
            previous, full = thinned(names, data, tran), (names, data)
            if args.save:
                path = args.save / f"{args.deck}_d{divisor:g}_r{reltol:g}.csv.gz"
                corpus.write_reference(path, *previous)
    print(f"(load {os.getloadavg()[0]:.1f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
