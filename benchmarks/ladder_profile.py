"""Where the time of an RLC ladder netlist goes, phase by phase (issue 30).

    PYTHONPATH=src python benchmarks/ladder_profile.py 100 300 [--steps 2000] [--out]

For each ladder of N stages (R, L, C per stage, a SIN source, ``steps`` steps of 1 µs,
``uic``; :func:`diracvi.bench.ladders.ladder`), in one process: ``import diracvi``, the
netlist's parsing, ``Circuit.build`` (the parts' systems, the interconnection, ``p0``),
the plan (solver choice, affine screen and build, checks), the first ``simulate``
beyond its plan (tracing, compiling, stepping), a warm ``simulate``, and the output
(``to_dataset`` and a NetCDF write) when ``--out`` is given. The disk cache is off
(``DIRACVI_CACHE_DIR=``) unless ``--cache`` is given, so "first" means cold.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("stages", type=int, nargs="+")
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--out", action="store_true", help="time to_dataset and a NetCDF write")
    ap.add_argument("--cache", action="store_true", help="keep the disk cache on")
    args = ap.parse_args()
    if not args.cache:
        os.environ["DIRACVI_CACHE_DIR"] = ""
    t = time.perf_counter()
    import diracvi as dv
    from diracvi import spice
    from diracvi.bench.ladders import ladder
    from diracvi.components.network import Circuit
    from diracvi.driver.plan import Plan

    rows = [("import diracvi", None, time.perf_counter() - t)]
    spent: dict[str, float] = {}

    def timed(owner, attr, label):
        original = getattr(owner, attr)

        def wrapper(*a, **k):
            t0 = time.perf_counter()
            try:
                return original(*a, **k)
            finally:
                spent[label] = spent.get(label, 0.0) + time.perf_counter() - t0

        setattr(owner, attr, wrapper)

    timed(Circuit, "build", "build")
    timed(Plan, "__init__", "plan")
    for n in args.stages:
        spent.clear()
        text = ladder(n, steps=args.steps)
        t0 = time.perf_counter()
        netlist = spice.read(text)
        read = time.perf_counter() - t0
        rows += [(f"parse ({3 * n + 1} elements)", n, read - spent["build"])]
        rows += [("Circuit.build", n, spent["build"])]
        kw = dict(dt=netlist.dt, steps=netlist.steps, discretization="midpoint")
        t0 = time.perf_counter()
        traj = dv.simulate(netlist.system, netlist.q0, netlist.p0, **kw)
        first = time.perf_counter() - t0
        rows += [("plan (solver choice, affine, checks)", n, spent.get("plan", 0.0))]
        rows += [("first simulate beyond the plan", n, first - spent.get("plan", 0.0))]
        t0 = time.perf_counter()
        traj = dv.simulate(netlist.system, netlist.q0, netlist.p0, **kw)
        rows += [("warm simulate", n, time.perf_counter() - t0)]
        if args.out:
            t0 = time.perf_counter()
            ds = spice.to_dataset(netlist, traj)
            rows += [("to_dataset", n, time.perf_counter() - t0)]
            with tempfile.TemporaryDirectory() as tmp:
                t0 = time.perf_counter()
                ds.to_netcdf(os.path.join(tmp, "x.nc"), engine="h5netcdf")
                size = os.path.getsize(os.path.join(tmp, "x.nc"))
                rows += [(f"NetCDF write ({size / 1e6:.0f} MB)", n, time.perf_counter() - t0)]
        rows += [(f"  solver: {traj.solver}", n, None)]
    print(f"{'phase':48s} {'stages':>7s} {'seconds':>9s}")
    for label, n, sec in rows:
        print(f"{label:48s} {'' if n is None else n:>7} {'' if sec is None else f'{sec:9.3f}'}")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
