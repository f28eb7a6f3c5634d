"""The fixed cost of a warm ``dv.simulate`` call on the paper's two examples, two ways.

python benchmarks/warm_call.py [--repeats N]

1. **back to back**: the same call N times in a row, min (how a helper timed it);
2. **interleaved with the NumPy baseline** (how ``diracvi bench --only spring-chain``
   times it): every round runs the NumPy run, the full diracvi run, a 1-step diracvi
   call and the dispatch floor, so each call starts with caches the others filled.

Fixed cost = the 1-step call less one step (the cost per step from the full run); its
Python side = the 1-step call less its compiled program called directly on the same input
(argument checks, plan lookup, the initial-data check, the Trajectory). The
dispatch floor is a jitted ``x + 1`` on one small array, copied back to NumPy: no call
that runs a compiled program can cost less. The two protocols differ by the cache
misses of a call that follows a 20 ms NumPy loop, and both move with the machine's load
(printed; compare numbers taken in one run only).
"""

import argparse
import os

import jax
import numpy as np

import diracvi as dv
from diracvi import problems
from diracvi.bench import rlc, spring_chain
from diracvi.bench._core import interleaved
from diracvi.bench._paper import in_order
from diracvi.reproduce.paper import RLC, SPRING_CHAIN


def examples():
    chain = problems.spring_chain_torn(dt=SPRING_CHAIN["dt"], steps=SPRING_CHAIN["steps"])
    prm = RLC["parameters"]
    circuit = problems.rlc_torn(prm["R"], prm["l"], prm["C"], dt=RLC["dt"], steps=RLC["steps"])
    for name, problem, paper, module, numpy_run in (
        ("spring chain", chain, SPRING_CHAIN, spring_chain, spring_chain.numpy_torn_chain),
        ("RLC circuit", circuit, RLC, rlc, rlc.numpy_torn_rlc),
    ):
        coords = problem.system.coords
        q0 = in_order(paper["q0"], module.COORDS, coords)
        p0 = in_order(paper["p0"], module.MOMENTA, coords)
        yield (
            name,
            problem,
            lambda p=paper, f=numpy_run, q=q0, m=p0: f(p["parameters"], q, m, p["dt"], p["steps"]),
        )


def one_step_program(system, q0, p0, dt):
    """The compiled 1-step chunk of the warm call, called directly on the same input:
    the call less this is the Python side (checks, plan lookup, Trajectory)."""
    from diracvi.driver.simulate import check_run, prepared_plan

    dv.simulate(system, q0, p0, dt=dt, steps=1)
    run = check_run(system, "plus", "retraction", dt, 1, 1, None)
    plan = prepared_plan(system, run, None, q0, p0)  # the call's cached plan
    chunk = plan.chunk(plan.step_map is not None, 1, True, 1)
    x = chunk.flat_input(plan.h_array, np.zeros(2), (q0, p0, q0, np.zeros(system.m)))
    return lambda: chunk.run(x)


def measure(name: str, problem, numpy_run, floor, repeats: int) -> None:
    system, q0, p0, dt = problem.system, problem.q0, problem.p0, problem.dt
    calls = {
        "full": lambda: dv.simulate(system, q0, p0, dt=dt, steps=problem.steps),
        "one": lambda: dv.simulate(system, q0, p0, dt=dt, steps=1),
        "program": one_step_program(system, q0, p0, dt),
        "floor": floor,
    }
    for protocol in ("back to back", "with NumPy"):
        if protocol == "back to back":  # each call alone, N times in a row
            t = {k: interleaved({k: f}, repeats)[k].min() for k, f in calls.items()}
        else:
            both = interleaved({**calls, "numpy": numpy_run}, repeats)
            t = {k: v.min() for k, v in both.items()}
        per_step = (t["full"] - t["one"]) / (problem.steps - 1)
        fixed = t["one"] - per_step
        python = t["one"] - t["program"]
        line = (
            f"{name:13s} {protocol:13s} fixed {fixed * 1e6:6.1f}  Python side "
            f"{python * 1e6:5.1f}  floor "
            f"{t['floor'] * 1e6:5.1f}  per step {per_step * 1e9:5.0f} ns  "
            f"{problem.steps} steps {t['full'] * 1e6:6.1f}"
        )
        if "numpy" in t:
            line += f"  NumPy {t['numpy'] * 1e3:5.2f} ms = {t['numpy'] / t['full']:5.1f}×"
        print(line)


def main(repeats: int) -> None:
    floor_fn = jax.jit(lambda x: x + 1.0)
    x = np.zeros(16)

    def floor():
        return np.asarray(floor_fn(x))

    print(f"load average {os.getloadavg()}; min of {repeats}; µs")
    for name, problem, numpy_run in examples():
        measure(name, problem, numpy_run, floor, repeats)
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    main(parser.parse_args().repeats)
