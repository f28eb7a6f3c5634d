"""When the eSim SCR decks' thyristor fires: diracvi against ngspice, as instants.

    PYTHONPATH=src python benchmarks/scr_turn_on.py [--converged] [--reltol R]

``es_fullwave_scr`` and ``es_halfwave_scr`` (``tests/data/netlists/``) fire an SCR
(``scr.sub``: an XSPICE ``aswitch`` whose control node is a gate current into ``C ∥ R``,
with the anode current fed back 100-fold) on each gate pulse. The anode falls ~190 V
(~100 V) in ~30 ns, so the corpus's measure (1e-3 of peak at the reference's thinned
points) asks for the firing instant to ~50 ps wherever a reference point falls in that
edge. This prints, for each deck, the instants the anode node falls through a level
(``out2`` through 60 V, ``a`` through 30 V) — diracvi at the deck's own settings (or at
``--reltol``), ngspice at the deck's own settings, ngspice at the corpus reference's
settings (reltol 1e-7, TMAX = TSTEP/50) and, with ``--converged``, at reltol 1e-9,
TMAX = TSTEP/500 (the fullwave deck's takes minutes) — and each one's offset from the
finest ngspice run in ns. diracvi's instants are located on its own output interpolant;
ngspice's linearly between its points. CPU seconds are this process's (diracvi,
compilation included) and the ngspice child's.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "src"))

import numpy as np  # noqa: E402

import _corpus as corpus  # noqa: E402

#: deck → (anode node, the level it falls through)
DECKS = {"es_fullwave_scr": ("out2", 60.0), "es_halfwave_scr": ("a", 30.0)}


def falls(t, y, level):
    """Where the samples ``(t, y)`` fall through ``level``, linear between them."""
    k = np.nonzero((y[:-1] > level) & (y[1:] <= level))[0]
    return t[k] + (level - y[k]) * (t[k + 1] - t[k]) / (y[k + 1] - y[k])


def diracvi_instants(deck, node, level, **settings):
    from diracvi import spice

    c0 = time.process_time()
    result = spice.run(deck, **settings)
    cpu = time.process_time() - c0
    t = np.asarray(result.trajectory.t, dtype=float)
    coarse = falls(t, np.asarray(result.at(t)[f"v({node})"]), level)
    found = []
    for x in coarse:  # located again on a 1 ps grid of ±40 ns around the step's crossing
        grid = np.linspace(x - 4e-8, x + 4e-8, 80001)
        found.append(falls(grid, np.asarray(result.at(grid)[f"v({node})"]), level)[0])
    return np.array(found), f"{len(result.trajectory.h)} steps, {cpu:.1f} s CPU"


def ngspice_instants(deck, node, level, *, fine, reltol=corpus.RELTOL, divisor=None):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    names, data, _ = corpus.run_ngspice(
        deck, fine=fine, reltol=reltol, divisor=divisor, timeout=3600
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    j = [n.lower() for n in names].index(f"v({node})")
    return falls(data[:, 0], data[:, j], level), f"{len(data)} points, {cpu:.1f} s CPU"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--converged", action="store_true")
    parser.add_argument("--reltol", type=float, default=None)
    args = parser.parse_args()
    for name, (node, level) in DECKS.items():
        deck = corpus.DATA / corpus.load_expected()[name]["file"]
        rows = [
            ("ngspice, the deck's settings", *ngspice_instants(deck, node, level, fine=False)),
            ("ngspice, reltol 1e-7, TSTEP/50", *ngspice_instants(deck, node, level, fine=True)),
        ]
        if args.converged:
            finest = ngspice_instants(deck, node, level, fine=True, reltol=1e-9, divisor=500)
            rows.append(("ngspice, reltol 1e-9, TSTEP/500", *finest))
        settings = {"reltol": args.reltol} if args.reltol else {}
        label = (
            f"diracvi, reltol {args.reltol:g}" if args.reltol else "diracvi, the deck's settings"
        )
        rows.append((label, *diracvi_instants(deck, node, level, **settings)))
        best = rows[2][1] if args.converged else rows[1][1]
        head = f"{name}: v({node}) falls through {level:g} V at (ms)"
        print(f"{head}, offset from the finest ngspice (ns)")
        for label, instants, cost in rows:
            cells = "  ".join(
                f"{x * 1e3:.9f} ({(x - b) * 1e9:+.2f})"
                for x, b in zip(instants, best, strict=False)
            )
            print(f"  {label:34s} {cells}   [{cost}]")


if __name__ == "__main__":
    main()
