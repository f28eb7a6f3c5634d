r"""First-call (compile) latency of every built-in problem, each in a fresh process.

For each problem of ``diracvi.problems.REGISTRY`` (with ``--quick``: the paper's two
torn models), a new Python process imports diracvi, builds the problem, and times its first
``dv.simulate`` call at the problem's own step, horizon and first solvable rule — tracing,
compilation, every check and the run itself, with nothing compiled or cached before it.
A fresh process is used rather than ``jax.clear_caches()`` in this one because it is the
only way to be sure no cache (JAX's, equinox's or diracvi's own) survives. The same
process then times warm calls (min of 3), so ``first ÷ warm`` shows how much of the
first call is compilation.
"""

from __future__ import annotations

import time

from ._core import Result, Row, Settings, simulate_problem
from ._worker import WorkerFailed, run_child

NAME = "compile"
DESCRIPTION = "first-call (compile) latency of each built-in problem, fresh process each"

QUICK_PROBLEMS = ("rlc-torn",)  # one fresh process: --quick stays well under a minute
TIMEOUT = 180.0
WARM_REPEATS = 3


#: the child's program: it times ``import diracvi`` itself, before anything else imports it
WORKER = """
import json, sys, time
start = time.perf_counter()
import diracvi
import_s = time.perf_counter() - start
from diracvi.bench.compile_latency import measure
print(json.dumps(measure(sys.argv[1], import_s)))
"""


def measure(name: str, import_s: float) -> dict:
    """In a fresh process (after ``import diracvi``): build, first call, warm calls (s)."""
    from diracvi import problems

    t1 = time.perf_counter()
    problem = problems.get(name)
    t2 = time.perf_counter()

    def call():
        return simulate_problem(problem, problem.discretizations[0])

    traj = call()
    t3 = time.perf_counter()
    warm = []
    for _ in range(WARM_REPEATS):
        start = time.perf_counter()
        call()
        warm.append(time.perf_counter() - start)
    return {
        "problem": name,
        "import_s": import_s,
        "build_s": t2 - t1,
        "first_call_s": t3 - t2,
        "warm_s": min(warm),
        "steps": problem.steps,
        "discretization": problem.discretizations[0],
        "solver": traj.solver,
    }


def run(settings: Settings) -> Result:
    from .. import problems

    names = QUICK_PROBLEMS if settings.quick else tuple(problems.REGISTRY)
    rows, measured = [], []
    for name in names:
        label = f"first call: {name}"
        try:
            m = run_child(["-c", WORKER, name], timeout=TIMEOUT)
        except WorkerFailed as exc:
            rows.append(
                Row(NAME, label, None, None, None, notes=f"not run: {exc}", status="not run")
            )
            continue
        measured.append(m)
        rows.append(
            Row(
                NAME,
                f"{label} ({m['steps']} steps, {m['discretization']}): first ÷ warm call",
                m["first_call_s"],
                m["warm_s"],
                m["first_call_s"] / m["warm_s"],
                solver=m["solver"],
                notes=f"fresh process; import {m['import_s']:.2f} s, build {m['build_s']:.2f} s",
            )
        )
    return Result(rows, {"problems": measured, "warm_repeats": WARM_REPEATS})
