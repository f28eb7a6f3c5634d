"""Work–precision of the heavy top: ``"lobatto"`` (order 4) against ``"midpoint"`` (order 2).

The heavy symmetric top of ``dv.problems.heavy_top`` (spin 5 rad/s, tilted 0.4 rad: it
precesses and nutates strongly) over T seconds in director form (12 coordinates, 6
orthonormality rows and the pivot's 3), each rule at four step sizes. Error: the largest
difference of any director coordinate from the Euler–Poisson reference (SciPy DOP853 at
rtol = atol = 1e-12) over the run. Time: a warm ``dv.simulate`` call (compiled first),
the minimum over the repeats; the points' calls are interleaved round by round (the
starting point rotated), so the shared machine's load hits every point alike. Run:

    OPENBLAS_NUM_THREADS=1 PYTHONPATH=src python benchmarks/top_work_precision.py [--T 1]
"""

from __future__ import annotations

import argparse
import gc
import time

import numpy as np

import diracvi as dv
from diracvi.bench._core import load_average, machine_info
from diracvi.problems.rigid_bodies import heavy_top

#: step sizes per rule: the same error range (1e-4 … 1e-8) for both
STEPS = {"midpoint": (0.004, 0.002, 0.001, 0.0005), "lobatto": (0.04, 0.02, 0.01, 0.005)}


def _point(rule: str, h: float, horizon: float):
    """A warm-callable run of the top under ``rule`` at step ``h``, and its error."""
    prob = heavy_top(dt=h, steps=round(horizon / h), spin=5.0)

    def run():
        return dv.simulate(
            prob.system,
            prob.q0,
            prob.p0,
            dt=h,
            steps=prob.steps,
            discretization=rule,
            solver=dv.NewtonSolver(),
        )

    traj = run()  # compiles
    error = np.max(np.abs(traj.q[:, 3:12] - prob.numerical_solution(traj.t)[:, 3:]))
    return run, error, prob.steps


def main(horizon: float = 1.0, repeats: int = 3) -> None:
    points = []
    for rule, hs in STEPS.items():
        for h in hs:
            run, error, steps = _point(rule, h, horizon)
            points.append({"rule": rule, "h": h, "steps": steps, "error": error, "run": run})
    best = [np.inf] * len(points)
    gc.disable()
    try:
        for r in range(repeats):
            order = list(range(len(points)))
            order = order[r % len(order) :] + order[: r % len(order)]
            for i in order:
                start = time.perf_counter()
                points[i]["run"]()
                best[i] = min(best[i], time.perf_counter() - start)
    finally:
        gc.enable()
    print(f"heavy top (spin 5 rad/s), T = {horizon} s: max director error vs DOP853")
    print("| rule | h | steps | error | time (ms, warm) | µs/step |")
    print("|---|---|---|---|---|---|")
    for p, t in zip(points, best, strict=True):
        row = f"| {p['rule']} | {p['h']} | {p['steps']} | {p['error']:.1e} | {t * 1e3:.1f} |"
        print(f"{row} {t / p['steps'] * 1e6:.0f} |")
    for rule in STEPS:
        mine = [(p["error"], t) for p, t in zip(points, best, strict=True) if p["rule"] == rule]
        errors = np.array(mine)[:, 0]
        slope = np.polyfit(np.log(STEPS[rule]), np.log(errors), 1)[0]
        print(f"{rule}: fitted order {slope:.2f}")
    info = machine_info()
    print(f"\n{info.get('cpu', '')}, load average {load_average()}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--T", type=float, default=1.0, help="horizon in seconds")
    parser.add_argument("--repeats", type=int, default=3, help="warm calls per point (min)")
    args = parser.parse_args()
    main(args.T, args.repeats)
