"""Where the time of an RLC ladder netlist goes, phase by phase (issue 30).

    PYTHONPATH=src python benchmarks/ladder_profile.py 1000 10000 [--steps 2000] [--out]

For each ladder of N stages (R, L, C per stage, a SIN source, ``steps`` steps of 1 µs,
``uic``; :func:`diracvi.bench.ladders.ladder`), in one process, the path of
``diracvi run ladder.cir --dt 1u [--out x.nc]``: ``import diracvi``, the netlist's
parsing, ``Circuit.build`` (of it: the parts' initial momenta and the packing of alike
parts), the plan (of it: the sparse map's probes — trace, compile and the JVPs —, its
assembly and SuperLU factorization, the driven parts' check, the initial-data check),
the run (of it: the host loop, the blocks' offsets and energies, the verification of
sampled steps), the waveforms, a warm ``spice.run`` in the same process, and with
``--out`` the NetCDF file as ``diracvi run --out`` writes it. Each phase is the wall
time of the functions named, measured by wrapping them (nested phases are indented and
included in their parent). CPU seconds beside the wall time: the machine is shared.
The disk cache is off (``DIRACVI_CACHE_DIR=``) unless ``--cache`` is given, so "first"
means cold; the peak RSS is the process's high-water mark after each ladder.
"""

from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time


def _clock():
    return time.perf_counter(), time.process_time()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("stages", type=int, nargs="+")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--out", action="store_true", help="time the NetCDF output too")
    ap.add_argument("--cache", action="store_true", help="keep the disk cache on")
    args = ap.parse_args()
    if not args.cache:
        os.environ["DIRACVI_CACHE_DIR"] = ""
    w0, c0 = _clock()
    import diracvi  # noqa: F401
    from diracvi import spice
    from diracvi.bench.ladders import ladder
    from diracvi.components import network
    from diracvi.driver import plan as plan_module
    from diracvi.model import interconnect
    from diracvi.solvers import sparse_affine
    from diracvi.spice import _run

    w1, c1 = _clock()
    rows = [("import diracvi", None, w1 - w0, c1 - c0)]
    spent: dict[str, list[float]] = {}

    def timed(owner, attr, label):
        original = getattr(owner, attr, None)
        if original is None:  # (a phase of another version of the code)
            return

        def wrapper(*a, **k):
            wa, ca = _clock()
            try:
                return original(*a, **k)
            finally:
                wb, cb = _clock()
                acc = spent.setdefault(label, [0.0, 0.0])
                acc[0] += wb - wa
                acc[1] += cb - ca

        setattr(owner, attr, wrapper)

    timed(network.Circuit, "build", "build")
    timed(network, "_momenta", "momenta")
    timed(interconnect.InterconnectedSystem, "_packed", "packing")
    timed(plan_module.Plan, "__init__", "plan")
    timed(sparse_affine, "_probe", "probes")
    timed(sparse_affine, "_assemble", "assembly")
    timed(sparse_affine, "_factor", "factor")  # (before the condensation)
    timed(sparse_affine, "condense", "factor")
    timed(sparse_affine, "_use_drivers", "drivers")
    timed(plan_module, "Checker", "checker")
    timed(sparse_affine.SparseAffineMap, "run", "run")
    timed(sparse_affine.SparseAffineMap, "_block", "blocks")
    timed(sparse_affine.SparseAffineMap, "_check_steps", "verify")
    timed(_run, "waveforms", "waveforms")
    phases = [
        ("build", "Circuit.build", 0),
        ("momenta", "initial momenta", 1),
        ("packing", "packing alike parts", 1),
        ("plan", "plan", 0),
        ("probes", "probes (trace, compile, JVPs)", 1),
        ("assembly", "assembly of the sparse matrices", 1),
        ("factor", "factorization (condensed: own blocks, SuperLU of S)", 1),
        ("drivers", "driven parts' offsets checked", 1),
        ("checker", "initial-data check", 1),
        ("run", "run (first)", 0),
        ("blocks", "offsets + energies (compiled, per block)", 1),
        ("verify", "verification of sampled steps", 1),
        ("waveforms", "waveforms", 0),
    ]
    for n in args.stages:
        spent.clear()
        text = ladder(n, steps=args.steps)
        wa, ca = _clock()
        netlist = spice.read(text)
        wb, cb = _clock()
        build = spent.get("build", [0.0, 0.0])
        rows.append((f"parse ({3 * n + 1} elements)", n, wb - wa - build[0], cb - ca - build[1]))
        result = spice.run(netlist, dt=netlist.dt)
        wc, cc = _clock()
        for key, label, depth in phases:
            if key in spent:
                rows.append(("  " * depth + label, n, *spent[key]))
        rows.append(("read + first run, in all", n, wc - wa, cc - ca))
        loop = spent["run"][0] - sum(spent.get(k, [0.0])[0] for k in ("blocks", "verify"))
        rows.append(("  the host loop (steps)", n, loop, None))
        wa, ca = _clock()
        result = spice.run(netlist, dt=netlist.dt)
        wb, cb = _clock()
        rows.append(("warm spice.run", n, wb - wa, cb - ca))
        if args.out:
            with tempfile.TemporaryDirectory() as tmp:
                path = os.path.join(tmp, "x.nc")
                wa, ca = _clock()
                result.save(path)
                wb, cb = _clock()
                size = os.path.getsize(path)
                rows.append((f"NetCDF output ({size / 1e6:.1f} MB)", n, wb - wa, cb - ca))
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        rows.append((f"peak RSS so far {rss:.0f} MB; {result.trajectory.solver}", n, None, None))
    print(f"{'phase':52s} {'stages':>7s} {'wall s':>8s} {'cpu s':>8s}")
    for label, n, wall, cpu in rows:
        cells = [f"{x:8.3f}" if x is not None else " " * 8 for x in (wall, cpu)]
        print(f"{label:52s} {'' if n is None else n:>7} {cells[0]} {cells[1]}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
