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
    --shift     also the time shift each signal needs to agree (:func:`time_shift`), for
                diracvi and for ngspice at the deck's own settings

The time shift is not the corpus's measure (that stays the pointwise error above): it
says what an error is on an edge. A signal off by 0.075 of its peak where it switches in
picoseconds is late or early by some time, and an engineer reads that time against the
edge and the deck's TSTEP.

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


def matched(have: dict, ref: dict):
    """``(vector, diracvi, ngspice, peak)`` per reference signal that ``have`` reports
    (names as :func:`_corpus.compare_sampled` matches them, the peak with its floor)."""
    have = {k.lower(): np.asarray(v, dtype=float) for k, v in have.items()}
    for vector, values in ref.items():
        key = next((k for k in corpus.diracvi_keys(vector) if k in have), None)
        if key is not None:
            floor = corpus.ABSTOL if vector.lower().startswith("i(") else corpus.VNTOL
            yield vector, have[key], values, max(float(np.max(np.abs(values))), floor)


def worst_points(have: dict, t: np.ndarray, ref: dict) -> list[tuple]:
    """``(error, vector, time, diracvi, ngspice, peak)`` per reference signal, worst first
    (the error as :func:`_corpus.compare_sampled` measures it)."""
    rows = []
    for vector, mine, values, peak in matched(have, ref):
        error = np.abs(mine - values) / peak
        j = int(np.argmax(error))
        rows.append((float(error[j]), vector, float(t[j]), mine[j], values[j], peak))
    return sorted(rows, key=lambda row: -row[0])


def _nearest_within(g, d, t_i, y_i, tol):
    """The time nearest ``t_i`` where the polyline ``(g, d)`` is within ``tol`` of
    ``y_i`` (``inf`` where it never is)."""
    a, b, fa, fb = g[:-1], g[1:], d[:-1] - y_i, d[1:] - y_i
    candidates = [np.where(np.abs(fa) <= tol, a, np.nan), np.where(np.abs(fb) <= tol, b, np.nan)]
    slope = fb - fa
    with np.errstate(divide="ignore", invalid="ignore"):
        for level in (tol, -tol):  # where the segment enters the band
            s = (level - fa) / slope
            candidates.append(np.where((s >= 0.0) & (s <= 1.0), a + s * (b - a), np.nan))
    distance = np.abs(np.stack(candidates) - t_i)
    return float(np.nanmin(distance)) if np.isfinite(distance).any() else np.inf


def time_shift(grid, sampled, t, values, peak, window=512):
    """The least ``δ`` such that every reference point ``(t_i, y_i)`` has the waveform
    ``(grid, sampled)`` (linear between its points) within ``1e-3·peak`` of ``y_i``
    somewhere in ``[t_i − δ, t_i + δ]``: the corpus's tolerance read along the time
    axis, the distance in time from the reference to the band around the waveform.
    ``t`` must be points of ``grid``; searched ``window`` grid points either side of each
    failing point first, then over the whole run."""
    tol = 1e-3 * peak
    at = np.searchsorted(grid, t)
    at = np.minimum(at, grid.size - 1)
    bad = np.flatnonzero(np.abs(sampled[at] - values) > tol)
    worst = 0.0
    for i in bad:
        k = int(at[i])
        lo, hi = max(k - window, 0), min(k + window + 1, grid.size)
        shift = _nearest_within(grid[lo:hi], sampled[lo:hi], t[i], values[i], tol)
        if not shift <= min(t[i] - grid[lo], grid[hi - 1] - t[i]):
            shift = _nearest_within(grid, sampled, t[i], values[i], tol)
        worst = max(worst, shift)
    return worst


def shifts(have_at, grid, t, ref) -> dict:
    """:func:`time_shift` per reference signal (``have_at(times)`` the waveforms)."""
    grid = np.union1d(grid, t)
    return {
        vector: time_shift(grid, mine, t, values, peak)
        for vector, mine, values, peak in matched(have_at(grid), ref)
    }


def _print_shifts(label, found, tstep) -> None:
    vector = max(found, key=found.get)
    print(
        f"{label}: every signal within 1e-3 of peak after a time shift of "
        f"{found[vector]:.3g} s ({found[vector] / tstep:.3g} TSTEP), largest in {vector}"
    )


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("deck")
    parser.add_argument("--top", type=int, default=None)
    parser.add_argument("--around", type=int, default=4)
    parser.add_argument("--shift", action="store_true")
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
    if args.shift:
        deck = corpus.DATA / entry["file"]
        tstep = corpus.find_tran(deck.read_text(errors="replace")).step
        inside = (t >= nodes[0]) & (t <= nodes[-1])
        mine = shifts(result.at, nodes[(nodes >= t[0]) & (nodes <= t[-1])], t[inside],
                      {k: v[inside] for k, v in ref.items()})  # fmt: skip
        _print_shifts("diracvi", mine, tstep)
        names, data, _ = corpus.run_ngspice(deck, fine=False)
        times = data[:, 0]
        inside = (t >= times[0]) & (t <= times[-1])

        def theirs(at):
            return {n: np.interp(at, times, data[:, j]) for j, n in enumerate(names) if j}

        own = shifts(theirs, times, t[inside], {k: v[inside] for k, v in ref.items()})
        _print_shifts("ngspice at the deck's settings", own, tstep)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
