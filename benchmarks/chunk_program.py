"""The compiled program of a warm run, timed alone (no argument checks, no Trajectory).

python benchmarks/chunk_program.py [--problem spring-chain|rlc] [--steps N] [--rounds R]

Runs ``dv.simulate`` once on the paper's torn example, then times the whole-run chunk's
program called directly on the same flat input (``CompiledChunk.run``: the dispatch,
the program and the copy of its packed output to NumPy): min and median over
``rounds`` rounds of 3 × 100 calls. Prints whether CPU programs ran on the calling
thread (diracvi's default) or were handed to JAX's worker thread; compare the two modes
in separate processes, e.g.::

    python benchmarks/chunk_program.py
    DIRACVI_CPU_ASYNC_DISPATCH=1 python benchmarks/chunk_program.py
    DIRACVI_CPU_ASYNC_DISPATCH=1 taskset -c 0 python benchmarks/chunk_program.py
"""

import argparse
import os
import timeit

import numpy as np

import diracvi as dv
from diracvi import problems
from diracvi.driver.simulate import check_run, prepared_plan
from diracvi.reproduce.paper import RLC, SPRING_CHAIN
from diracvi.runtime.dispatch import synchronous


def example(name: str, steps: int | None):
    if name == "spring-chain":
        paper = SPRING_CHAIN
        problem = problems.spring_chain_torn(dt=paper["dt"], steps=paper["steps"])
    else:
        paper, prm = RLC, RLC["parameters"]
        problem = problems.rlc_torn(
            prm["R"], prm["l"], prm["C"], dt=paper["dt"], steps=paper["steps"]
        )
    return problem, steps or paper["steps"]


def main(name: str, steps: int | None, rounds: int) -> None:
    problem, steps = example(name, steps)
    system, q0, p0, dt = problem.system, problem.q0, problem.p0, problem.dt
    dv.simulate(system, q0, p0, dt=dt, steps=steps)
    run = check_run(system, "plus", "retraction", dt, steps, 1, None)
    plan = prepared_plan(system, run, None, q0, p0)  # the call's cached plan
    chunk = plan.chunk(plan.step_map is not None, 1, True, steps)
    x = chunk.flat_input(plan.h_array, np.zeros(2), (q0, p0, q0, np.zeros(system.m)))
    chunk.run(x)
    times = [
        min(timeit.repeat(lambda: chunk.run(x), number=100, repeat=3)) / 100 for _ in range(rounds)
    ]
    mode = {True: "on the calling thread", False: "asynchronous", None: "unknown"}[synchronous()]
    print(
        f"{name}, {steps} steps, program alone (CPU dispatch: {mode}; load "
        f"{os.getloadavg()[0]:.2f}): min {min(times) * 1e6:.1f} µs, "
        f"median {np.median(times) * 1e6:.1f} µs"
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problem", choices=("spring-chain", "rlc"), default="spring-chain")
    parser.add_argument("--steps", type=int, default=None)
    parser.add_argument("--rounds", type=int, default=9)
    args = parser.parse_args()
    main(args.problem, args.steps, args.rounds)
