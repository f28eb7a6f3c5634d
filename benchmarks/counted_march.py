"""Warm cost of the counted march against a march compiled for exactly the run's length.

python benchmarks/counted_march.py [--repeats 30]

For each (problem, steps, save_every), the plan's counted chunk (compiled for
``capacity(steps / save_every)`` records, the count an input: what ``simulate`` runs) and
a static chunk of exactly ``steps / save_every`` records (what ``simulate`` ran before)
are called on the same input, interleaved (``diracvi.bench._core.interleaved``), min
wall of the repeats. ``513`` steps is the worst case of the ladder (capacity 1024: half
the records are filler), ``512`` the best. The last column names the saved outputs that
are not bitwise equal, with their largest difference in units of the value's ulp.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

import diracvi as dv
from diracvi import problems
from diracvi.bench._core import interleaved
from diracvi.discretization.rules import get_rule
from diracvi.driver.chunk import CompiledChunk, capacity
from diracvi.driver.plan import get_plan

CASES = (
    ("cartesian-pendulum", "midpoint", 512, 1),
    ("cartesian-pendulum", "midpoint", 513, 1),
    ("four-bar", "midpoint", 512, 1),
    ("four-bar", "midpoint", 513, 1),
    ("four-bar", "lobatto", 513, 1),
    ("double-pendulum-torn", "midpoint", 513, 1),
    ("four-bar", "midpoint", 5130, 10),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=30)
    args = parser.parse_args()
    print(f"load average at start: {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")
    print("| problem | rule | steps / save_every | capacity | static ms | counted ms | ratio "
          "| outputs |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for name, rule, steps, k in CASES:
        problem = problems.get(name)
        dv.simulate(problem.system, problem.q0, problem.p0, dt=problem.dt, steps=k,
                    save_every=k, discretization=rule)  # fmt: skip
        plan = get_plan(problem.system, get_rule(rule), "plus", problem.dt, None,
                        problem.q0, problem.p0)  # fmt: skip
        assert plan.step_map is None, "a solver's march (the affine map's is not counted)"
        blocks = steps // k
        counted = plan.chunk(False, k, True, blocks)
        static = CompiledChunk(plan.stepped_system, plan.rule, "plus", plan.fallback, k, True,
                               blocks, guard=None)  # fmt: skip
        carry = (problem.q0, problem.p0, problem.q0, np.zeros(plan.system.m))
        x_counted = counted.flat_input(plan.h_array, (0.0, 0.0), carry)
        x_static = static.flat_input(plan.h_array, (0.0, 0.0), carry)
        ours, theirs = (
            counted.layout.unpack(counted.run(x_counted)),
            static(plan.h_array, np.zeros(2), carry),
        )
        unequal = []
        for field, a in ours[2].items():
            b = theirs[2][field]
            if not np.array_equal(a, b):
                ulps = np.max(np.abs(a - b) / np.spacing(np.maximum(np.abs(b), 1e-300)))
                unequal.append(f"{field} {ulps:.0f} ulp")
        calls = {
            "static": lambda s=static, x=x_static: s.run(x),
            "counted": lambda c=counted, x=x_counted: c.run(x),
        }
        times = interleaved(calls, args.repeats)
        t_s, t_c = times["static"].min() * 1e3, times["counted"].min() * 1e3
        print(f"| {name} | {rule} | {steps} / {k} | {capacity(blocks)} | {t_s:.2f} | "
              f"{t_c:.2f} | {t_c / t_s:.3f} | {', '.join(unequal) or 'bitwise'} |")  # fmt: skip
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
