"""A warm in-process ``dv.simulate`` of the 1000-stage ladder against ``ngspice -b``, by
what the run keeps (issue 30: "warm in-process simulate ≤ 0.2× ngspice").

    PYTHONPATH=src python benchmarks/warm_ladder_save.py [STAGES] [--rounds 5]

The deck is :func:`diracvi.bench.ladders.ladder` (R, L, C per stage, a 1 kHz sine,
2000 fixed steps of 1 µs, ``uic``). Each round runs, one after the other in this process:

- **ngspice** ``-b`` of the deck as :mod:`diracvi.bench.ladder_scaling` runs it (maximum
  step 1 µs, three probes written): CPU seconds of the whole process (``RUSAGE_CHILDREN``);
- **every state** (``dv.simulate``'s default: q, p, the multipliers, the constraint
  residuals, the nodal momenta and the energies of every step);
- **SPICE's default set** with ``save_only=``: what ngspice saves without ``.save`` —
  every node voltage (the KCL rows' multipliers) and the voltage sources' and
  inductors' currents (their charges);
- **three probes** with ``save_only=``: ``v(n1)``, ``v(n10)``, ``i(L1)``'s columns, what
  the ngspice run writes.

Every diracvi call is warm (after a first call of each) and timed in CPU seconds
(``time.process_time``); the ratios are to the ngspice run of the same round, so the
machine's load moves both. The kept columns are checked equal, bit for bit, to the
whole run's. The table's rows: the median of the rounds' ratios, and the min of each
column's CPU seconds.
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("stages", type=int, nargs="?", default=1000)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    os.environ["DIRACVI_CACHE_DIR"] = os.environ.get("DIRACVI_CACHE_DIR") or tempfile.mkdtemp()
    import diracvi as dv
    from diracvi import spice
    from diracvi.bench.ladder_scaling import _ngspice
    from diracvi.bench.ladders import ladder

    text = ladder(args.stages)
    netlist = spice.read(text)
    system, assembly = netlist.system, netlist.assembly
    kw = dict(dt=netlist.dt, steps=netlist.steps, discretization="midpoint")
    # SPICE's default set: node voltages from the KCL rows, V and L currents from charges
    default = []
    for _, key in netlist.vectors:
        kind, name = key[0], key[2:-1]
        default.append(assembly.kcl_rows[name] if kind == "v" else assembly.currents[name])
    probes = [assembly.kcl_rows["n1"], assembly.kcl_rows["n10"], assembly.currents["L1"]]
    runs = {
        "every state (default)": {},
        f"save_only: SPICE's default set ({len(default)} columns)": {"save_only": default},
        "save_only: 3 probes": {"save_only": probes},
    }
    full = dv.simulate(system, netlist.q0, netlist.p0, **kw)
    for name, extra in runs.items():
        if not extra:
            continue
        traj = dv.simulate(system, netlist.q0, netlist.p0, **kw, **extra)
        qi = [system.coords.index(c) for c in traj.coords]
        mi = [system.constraint_names.index(c) for c in traj.constraint_names]
        same = np.array_equal(traj.q, full.q[:, qi]) and np.array_equal(
            traj.multipliers, full.multipliers[:, mi]
        )
        print(f"{name}: kept columns equal to the whole run's bit for bit: {same}")
    print(f"path: {full.solver}; load average at start {os.getloadavg()[0]:.1f}")
    cpu = {"ngspice -b": []} | {name: [] for name in runs}
    for _ in range(args.rounds):
        with tempfile.TemporaryDirectory() as tmp:
            c0 = _children_cpu()
            _ngspice(text, Path(tmp))
            cpu["ngspice -b"].append(_children_cpu() - c0)
        for name, extra in runs.items():
            c = time.process_time()
            dv.simulate(system, netlist.q0, netlist.p0, **kw, **extra)
            cpu[name].append(time.process_time() - c)
    print(f"load average at end {os.getloadavg()[0]:.1f}; {args.rounds} rounds\n")
    ng = np.array(cpu["ngspice -b"])
    head = f"| {args.stages}-stage ladder, warm | CPU s, min (median) |"
    print(head + " ÷ ngspice CPU, median of rounds |")
    print("|---|---|---|")
    for name, values in cpu.items():
        v = np.array(values)
        ratio = "—" if name == "ngspice -b" else f"{statistics.median(v / ng):.2f}"
        print(f"| {name} | {v.min():.3f} ({np.median(v):.3f}) | {ratio} |")


if __name__ == "__main__":
    main()
