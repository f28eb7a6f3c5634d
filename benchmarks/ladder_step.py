"""A fixed-step RLC ladder's step, and a warm ``simulate``, against ngspice ``-b`` (issue 30).

    PYTHONPATH=src python benchmarks/ladder_step.py 100 1000 10000 [--repeats 3]

For each ladder of N stages (:func:`diracvi.bench.ladders.ladder`: R, L, C per stage, a
1 kHz sine, 2000 steps of 1 µs, ``uic``), side by side in one process:

- **ngspice** ``-b`` of the deck (as ``diracvi bench --only circuits`` runs it: maximum
  step 1 µs, three probes written): wall time and CPU seconds of the whole process
  (``RUSAGE_CHILDREN``);
- **warm in-process** ``dv.simulate`` (after a first call; the min of ``repeats``), wall
  and CPU seconds, and of it the sparse map's ``run`` alone;
- **per step**: the CPU time of each product and solve of the step (1000 calls each on
  random vectors), whatever the map's version names them, and the factor's size;
- the agreement with ngspice (max error / peak over the probes).

CPU seconds are the figures to read on a loaded machine; the disk cache is a fresh
directory (so the first call compiles, the warm ones do not).
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _pieces(m):
    """``{name: callable}`` of the step's products and solve on random vectors, and a
    description of the factored system."""
    rng = np.random.default_rng(0)
    if hasattr(m, "_augmented"):  # the condensed step, on z̃ = (q, p, 1, u)
        step = m._augmented()
        from diracvi.solvers.sparse_affine import _accumulate

        zv = rng.standard_normal(step["width"] + m._nk)  # (z̃, v)
        z, v = zv[: step["width"]], zv[step["width"] :]
        s, out = np.zeros(m._nk), np.zeros(2 * m.n)
        lu = m.lu.schur
        pieces = {
            "s = G_s z̃": lambda: _accumulate(step["g_s"], z, s),
            "v = S⁻¹ s": lambda: lu.solve(v),
            "z' = G_z (z̃, v)": lambda: _accumulate(step["g_z"], zv, out),
        }
        what = f"S: {m._nk} unknowns, nnz(L+U) {lu.L.nnz + lu.U.nnz}"
    else:  # the whole J_x (before the condensation)
        z, r = rng.standard_normal(2 * m.n), rng.standard_normal(m.size)
        lu = m.lu
        pieces = {
            "(J_z; P_z) z": lambda: m._zmap @ z,
            "J_x⁻¹ r": lambda: lu.solve(r),
            "P_x y": lambda: m.px @ r,
        }
        what = f"J_x: {m.size} unknowns, nnz(L+U) {lu.L.nnz + lu.U.nnz}"
    return pieces, what


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("stages", type=int, nargs="+")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    os.environ["DIRACVI_CACHE_DIR"] = tempfile.mkdtemp()
    import diracvi as dv
    from diracvi import spice
    from diracvi.bench.ladder_scaling import _agreement, _ngspice
    from diracvi.bench.ladders import ladder
    from diracvi.solvers import sparse_affine

    built = []
    original = sparse_affine.build

    def build(*a, **k):
        built.append(original(*a, **k))
        return built[-1]

    sparse_affine.build = build
    for n in args.stages:
        text = ladder(n)
        with tempfile.TemporaryDirectory() as tmp:
            c0 = _children_cpu()
            ng_wall, _, t_ref, ref = _ngspice(text, Path(tmp))
            ng_cpu = _children_cpu() - c0
        netlist = spice.read(text)
        kw = dict(dt=netlist.dt, steps=netlist.steps, discretization="midpoint")
        built.clear()
        dv.simulate(netlist.system, netlist.q0, netlist.p0, **kw)
        m = built[-1]
        run_cpu = []
        original_run = m.run

        def timed_run(*a, _run=original_run, _spent=run_cpu, **k):
            c = time.process_time()
            try:
                return _run(*a, **k)
            finally:
                _spent.append(time.process_time() - c)

        m.run = timed_run
        walls, cpus = [], []
        for _ in range(args.repeats):
            w, c = time.perf_counter(), time.process_time()
            traj = dv.simulate(netlist.system, netlist.q0, netlist.p0, **kw)
            walls.append(time.perf_counter() - w)
            cpus.append(time.process_time() - c)
        err = _agreement(netlist, traj, t_ref, ref)
        pieces, what = _pieces(m)
        print(f"\n{n} stages ({3 * n + 1} elements), {traj.solver}; {what}")
        print(f"  ngspice -b: wall {ng_wall:.3f} s, cpu {ng_cpu:.3f} s")
        wall, cpu = min(walls), min(cpus)
        print(
            f"  warm simulate: wall {wall:.3f} s ({wall / ng_wall:.2f}× ngspice), "
            f"cpu {cpu:.3f} s ({cpu / ng_cpu:.2f}× ngspice's cpu); "
            f"of it the map's run: cpu {min(run_cpu):.3f} s"
        )
        total = 0.0
        for name, f in pieces.items():
            c = time.process_time()
            for _ in range(1000):
                f()
            each = (time.process_time() - c) * 1e3
            total += each
            print(f"  per step, {name}: {each:.1f} µs cpu")
        print(f"  per step, the three: {total:.1f} µs cpu; max error / peak vs ngspice {err:.1e}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
