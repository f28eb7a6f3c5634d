"""Where a cold first ``dv.simulate`` of a small mechanism spends its CPU, per phase.

python benchmarks/first_call_phases.py [--problems four-bar andrews …] [--rules midpoint lobatto]

Each (problem, rule) runs in a fresh process with no disk cache (``DIRACVI_CACHE_DIR=""``):
import diracvi, build the problem, the first ``dv.simulate`` (its CPU seconds, beside JAX's
own event timings of tracing, lowering and XLA compilation — wall seconds, so under load they
can exceed the CPU —, and its compiled programs counted
and named from ``jax_log_compiles``), a second call with a new step count (a recompiled
march shows here), and warm calls (min of 3, wall). CPU seconds are the process's user +
system time: on a shared machine they move much less with the others' load than the wall.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

from _phases import child_source, table_head

PROBLEMS = ("four-bar", "double-pendulum-torn", "andrews")
RULES = ("midpoint", "lobatto")

CHILD = child_source(r"""
import json, logging, re, time
split = jax_split()  # JAX's own event timings
programs = []
class Names(logging.Handler):
    def emit(self, record):
        found = re.search(r"Finished XLA compilation of (\S+)", record.getMessage())
        if found:
            programs.append(found.group(1))
logging.getLogger("jax").addHandler(Names())
import diracvi as dv
from diracvi import problems
phases.mark("import")
problem = problems.get(sys.argv[1])
phases.mark("build")
rule = sys.argv[2]
def call(steps):
    return dv.simulate(problem.system, problem.q0, problem.p0, dt=problem.dt, steps=steps,
                       discretization=rule)
call(problem.steps)
phases.mark("first call")
first_split, first_programs = dict(split), list(programs)
call(problem.steps + 7)
phases.mark("new steps")
warm = []
for _ in range(3):
    start = time.perf_counter()
    call(problem.steps)
    warm.append(time.perf_counter() - start)
marks = {k: (c, n) for k, (_, c, n) in phases.marks.items()}
print(json.dumps({"marks": marks, "split": first_split, "programs": first_programs,
                  "again": programs[len(first_programs):], "warm": min(warm)}))
""")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=list(PROBLEMS))
    parser.add_argument("--rules", nargs="+", default=list(RULES))
    parser.add_argument("--names", action="store_true", help="list the compiled programs")
    args = parser.parse_args()
    env = {**os.environ, "DIRACVI_CACHE_DIR": "", "OPENBLAS_NUM_THREADS": "1"}
    table_head("problem", "rule", "import CPU", "first call CPU (trace/lower/XLA, wall)",
               "programs", "new steps CPU (programs)", "warm wall")  # fmt: skip
    for name in args.problems:
        for rule in args.rules:
            out = subprocess.run(
                [sys.executable, "-c", CHILD, name, rule], env=env, capture_output=True, text=True
            )
            if out.returncode != 0:
                print(f"| {name} | {rule} | failed: {out.stderr.strip().splitlines()[-1]} |")
                continue
            r = json.loads(out.stdout.strip().splitlines()[-1])
            m, s = r["marks"], r["split"]
            print(
                f"| {name} | {rule} | {m['import'][0]:.2f} | {m['first call'][0]:.2f} "
                f"({s['trace']:.2f}/{s['lower']:.2f}/{s['compile']:.2f}) "
                f"| {m['first call'][1]} | {m['new steps'][0]:.2f} ({m['new steps'][1]}) "
                f"| {1e3 * r['warm']:.1f} ms |",
                flush=True,
            )
            if args.names:
                print(f"|   first: {', '.join(r['programs'])}; new steps: {', '.join(r['again'])}")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
