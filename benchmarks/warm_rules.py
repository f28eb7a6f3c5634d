"""Warm ``dv.simulate`` calls of one problem under several rules, alternated in one process.

    PYTHONPATH=src taskset -c 1 python benchmarks/warm_rules.py \\
        [--problems four-bar double-pendulum-torn andrews] [--rules lobatto lobatto@268c605^] \\
        [--rounds 20] [--block 3]

A rule ``NAME@COMMIT`` is the file ``src/diracvi/discretization/NAME.py`` of that commit
(``git show``), its class registered beside today's under the name ``NAME@COMMIT``
(``register_rule``): two versions of a rule timed in one process, so the machine's load
and the process's own state weigh on both alike. Per problem: a first call of each rule,
then ``--rounds`` rounds of ``--block`` calls of each (the order reversed every round);
the min and the median CPU ms per call, and the largest ``|Δq|`` of each rule's
trajectory from the first rule's.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import time
import types
from pathlib import Path

import numpy as np

from diracvi import problems
from diracvi.bench._core import simulate_problem
from diracvi.discretization.base import QuadratureRule
from diracvi.discretization.rules import register_rule

ROOT = Path(__file__).resolve().parents[1]


def old_rule(name: str, commit: str) -> str:
    """Register the rule class of ``discretization/<name>.py`` at ``commit`` as
    ``name@commit``; returns that name."""
    path = f"src/diracvi/discretization/{name}.py"
    text = subprocess.run(
        ["git", "show", f"{commit}:{path}"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    # its relative imports made absolute (the module is loaded outside the package)
    text = re.sub(r"^from \.\.(\w)", r"from diracvi.\1", text, flags=re.M)
    text = re.sub(r"^from \.(\w)", r"from diracvi.discretization.\1", text, flags=re.M)
    module = types.ModuleType(f"_old_{name}")
    exec(compile(text, f"{commit}:{path}", "exec"), module.__dict__)
    label = f"{name}@{commit}"
    (cls,) = [
        c
        for c in vars(module).values()
        if isinstance(c, type)
        and issubclass(c, QuadratureRule)
        and c.__module__ == module.__name__
        and c().name == name
    ]

    def init(self):
        cls.__init__(self)
        self.name = label

    register_rule(type(f"{cls.__name__}At", (cls,), {"__init__": init}))
    return label


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--problems", nargs="+", default=["four-bar", "double-pendulum-torn", "andrews"]
    )
    parser.add_argument("--rules", nargs="+", default=["lobatto", "lobatto@268c605^"])
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--block", type=int, default=3)
    args = parser.parse_args()
    rules = [old_rule(*r.split("@", 1)) if "@" in r else r for r in args.rules]
    with open("/proc/loadavg") as f:
        print(f"load average at start: {f.read().split()[0]}")
    for name in args.problems:
        problem = problems.get(name)

        def call(rule, problem=problem):
            return simulate_problem(problem, rule)

        q = {rule: np.asarray(call(rule).q) for rule in rules}
        cpu = {rule: [] for rule in rules}
        for k in range(args.rounds):
            for rule in rules if k % 2 == 0 else rules[::-1]:
                for _ in range(args.block):
                    start = time.process_time()
                    call(rule)
                    cpu[rule].append(time.process_time() - start)
        cells = [
            f"{rule} {1e3 * min(cpu[rule]):.2f} / {1e3 * statistics.median(cpu[rule]):.2f}"
            + (f" (|Δq| {np.max(np.abs(q[rule] - q[rules[0]])):.1e})" if rule != rules[0] else "")
            for rule in rules
        ]
        print(
            f"{name} ({problem.steps} steps), CPU ms min / median: " + "; ".join(cells), flush=True
        )


if __name__ == "__main__":
    main()
