"""Where a corpus deck's error lies: ``python benchmarks/deck_worst.py DECK [--top N]``.

For one deck of ``tests/data/netlists/EXPECTED.toml``, run at its own settings through
``diracvi.spice.run`` and compared with its committed fine ngspice reference as
``tests/_corpus.py`` compares (``max |diracvi − ngspice| / peak |ngspice|`` over the
reference's times, diracvi read by ``result.at``), print per signal its error, the
reference time where it is worst, both values there, and the run's steps around that
instant (the step sizes and the nodes' times): whether the worst point sits at a
breakpoint, after a step across a corner, or inside a ringing, is what the step sizes
show first.

    --top N     the N worst signals (default: all)
    --around K  K steps either side of the worst instant (default 4)

The corpus's figure for the deck is the first line's error (``benchmarks/corpus.py``
reports the same number, from the same comparison).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

# one BLAS thread, as the tests and benchmarks/corpus.py run (see its comment)
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "src"))  # this checkout's diracvi, as the tests import it

import numpy as np  # noqa: E402  (after the environment above)

import _corpus as corpus  # noqa: E402


def worst_points(have: dict, t: np.ndarray, ref: dict) -> list[tuple]:
    """``(error, vector, time, diracvi, ngspice, peak)`` per reference signal, worst first
    (the error as :func:`_corpus.compare_sampled` measures it)."""
    have = {k.lower(): np.asarray(v, dtype=float) for k, v in have.items()}
    rows = []
    for vector, values in ref.items():
        key = next((k for k in corpus.diracvi_keys(vector) if k in have), None)
        if key is None:
            continue
        floor = corpus.ABSTOL if vector.lower().startswith("i(") else corpus.VNTOL
        peak = max(float(np.max(np.abs(values))), floor)
        error = np.abs(have[key] - values) / peak
        j = int(np.argmax(error))
        rows.append((float(error[j]), vector, float(t[j]), have[key][j], values[j], peak))
    return sorted(rows, key=lambda row: -row[0])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("deck")
    parser.add_argument("--top", type=int, default=None)
    parser.add_argument("--around", type=int, default=4)
    args = parser.parse_args(argv)
    entry = corpus.load_expected()[args.deck]
    t, ref = corpus.load_reference(args.deck)
    from diracvi import spice

    c0 = time.process_time()
    result = spice.run(corpus.DATA / entry["file"])
    cpu = time.process_time() - c0
    nodes = np.asarray(result.trajectory.t, dtype=float)
    steps = np.diff(nodes)
    print(f"{args.deck}: {len(steps)} steps, {cpu:.1f} s CPU (spice.run, compile included)")
    for error, vector, at, mine, theirs, peak in worst_points(result.at(t), t, ref)[: args.top]:
        k = int(np.searchsorted(nodes, at))
        lo, hi = max(k - args.around, 0), min(k + args.around, len(steps))
        print(
            f"{vector:28s} {error:.3g} of peak at t = {at:.10g}: "
            f"{mine:.5g} against {theirs:.5g} (peak {peak:.3g})"
        )
        print("    nodes:", " ".join(f"{x:.10g}" for x in nodes[lo : hi + 1]))
        print("    steps:", " ".join(f"{x:.3g}" for x in steps[lo:hi]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
