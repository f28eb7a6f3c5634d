"""Warm ``dv.simulate`` calls of nonlinear models (Newton, the full initial-data check).

python benchmarks/warm_nonlinear.py [--repeats N]

A 10-step call, so that the fixed cost of the call (argument checks, the initial-data
check with its compiled Legendre rows and, for a holonomic model, ``g(q, t)``, dispatch,
the Trajectory) shows beside the steps: min over N repeats of 50 calls each. To compare
two trees, run this alternately with ``PYTHONPATH=<tree>/src``.
"""

import argparse
import timeit

import diracvi as dv
from diracvi import problems

PROBLEMS = ("double-pendulum-torn", "four-bar", "rolling-disk")


def main(repeats: int) -> None:
    for name in PROBLEMS:
        problem = problems.get(name)

        def call(problem=problem):
            return dv.simulate(
                problem.system,
                problem.q0,
                problem.p0,
                dt=problem.dt,
                steps=10,
                discretization=problem.discretizations[0],
            )

        call()
        best = min(timeit.repeat(call, number=50, repeat=repeats)) / 50
        print(f"{name:22s} {best * 1e6:7.0f} µs per 10-step call")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20)
    main(parser.parse_args().repeats)
