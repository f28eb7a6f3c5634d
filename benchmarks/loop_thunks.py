"""What the compiled variable-step loop executes: XLA's CPU thunks, by nested loop.

    PYTHONPATH=src python benchmarks/loop_thunks.py                    # the bridge rectifier
    PYTHONPATH=src python benchmarks/loop_thunks.py --deck tests/data/netlists/ng_schmitt.cir

XLA's CPU runtime runs a compiled program as a sequence of *thunks* — a fused kernel, a
copy, a LAPACK call, a ``while`` or a ``conditional`` (whose bodies are thunk sequences of
their own). This compiles ``spice.run``'s loop (:mod:`diracvi.driver.adaptive`) afresh in a
child process (the disk cache off) with its optimized HLO dumped, and prints the tree of
``while`` bodies and ``conditional`` branches with the thunks each runs per pass, then
XLA's own account of every thunk sequence it built (``thunk_executor``'s log): how many
thunks, and whether it runs them in order (``is_sequential``: every buffer ≤ 512 bytes or
≤ 8 thunks) or as a dependency graph — each pass of which allocates its state and may hand
ready thunks to a second thread.

A ``call`` (a small loop XLA outlines, e.g. ``lu_solve``'s pivots-to-permutation loop or a
scatter's loop) is compiled into one kernel: one thunk, its loop not counted (it has no
thunk sequence in the log). Counting those loops' trips as thunks overstates a pass
several-fold (the bridge's Newton iteration: 279 "operations" against its 39 thunks); cut
from the program, they saved no measurable CPU (docs/performance.md, "Counting thunks").
"""

from __future__ import annotations

import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

#: HLO instructions that are no thunk: views, tuples, constants
FREE = {"parameter", "get-tuple-element", "tuple", "constant", "bitcast"}


def _computations(text: str):
    """``{name: [instruction lines]}`` and the entry's name, of an optimized HLO module."""
    comps, entry, current = {}, None, None
    for line in text.splitlines():
        if not line.startswith(" "):
            head = re.match(r"^(ENTRY )?%?([\w.\-]+) .*\{$", line)
            if head and ("->" in line or head.group(1)):
                current = head.group(2)
                comps[current] = []
                entry = current if head.group(1) else entry
                continue
        if line.startswith("}"):
            current = None
        elif current and "=" in line:
            comps[current].append(line.strip())
    return comps, entry


def _opcode(line: str) -> str:
    found = re.match(r"(ROOT )?%?[\w.\-]+ = .+? ([a-z\-]+)\(", line)
    return found.group(2) if found else "?"


def tree(comps, name, depth=0, out=None):
    """The lines of the tree under computation ``name``: its thunks by kind, then the
    while bodies and conditional branches it runs."""
    out = [] if out is None else out
    kinds, children = collections.Counter(), []
    for line in comps[name]:
        op = _opcode(line)
        if op in FREE:
            continue
        kinds[op] += 1
        if op == "while":
            for role in ("condition", "body"):
                children.append((role, re.search(role + r"=%?([\w.\-]+)", line).group(1)))
        elif op == "conditional":
            found = re.search(r"branch_computations=\{([^}]*)\}", line)
            names = found.group(1).split(",") if found else []
            for key in ("true_computation", "false_computation"):
                one = re.search(key + r"=%?([\w.\-]+)", line)
                names += [one.group(1)] if one else []
            children += [("branch", b.strip().lstrip("%")) for b in names]
        elif op == "custom-call":
            target = re.search(r'custom_call_target="([^"]*)"', line).group(1)
            kinds["custom-call"] -= 1
            kinds[target] += 1
    kinds = +kinds
    total = sum(kinds.values())
    detail = ", ".join(f"{k} {v}" for k, v in kinds.most_common())
    out.append(f"{'  ' * depth}{name}: {total} thunks ({detail})")
    for role, child in children:
        out.append(f"{'  ' * depth}  [{role}]")
        tree(comps, child, depth + 2, out)
    return out


def _child(deck: str | None):
    from diracvi import spice
    from diracvi.spice._ngspice import CIRCUITS

    source = CIRCUITS["bridge"][0] if deck is None else Path(deck)
    run = spice.run(spice.read(source), internal=True)
    m = run.trajectory
    print(f"steps {len(m.h)}, tries {m.tries}, Newton iterations {m.iterations}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--deck", help="a netlist file (default: CIRCUITS['bridge'])")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        _child(args.deck)
        return
    with tempfile.TemporaryDirectory(prefix="loop-thunks-") as dump:
        env = {
            **os.environ,
            "DIRACVI_CACHE_DIR": "",  # compiled here, not loaded: the dump needs it
            "XLA_FLAGS": f"--xla_dump_to={dump} --xla_dump_hlo_as_text --xla_dump_hlo_pass_re=^$",
            "TF_CPP_MIN_LOG_LEVEL": "0",
            "TF_CPP_VMODULE": "thunk_executor=2",
            "OPENBLAS_NUM_THREADS": "1",
        }
        command = [sys.executable, __file__, "--child"]
        command += ["--deck", args.deck] if args.deck else []
        done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
        if done.returncode:
            sys.exit(f"the child run failed:\n{done.stderr[-4000:]}")
        print(done.stdout.strip())
        dumps = sorted(Path(dump).glob("*jit__march.cpu_after_optimizations.txt"))
        if not dumps:
            sys.exit("no optimized HLO of diracvi.driver.adaptive._march was dumped")
        comps, entry = _computations(dumps[-1].read_text())
        print("\n".join(tree(comps, entry)))
        built = collections.Counter(
            re.sub(r".*Constructed ThunkExecutor", "ThunkExecutor", line)
            for line in done.stderr.splitlines()
            if "Constructed ThunkExecutor" in line
        )
        print("\nthunk sequences XLA built in the child process (all its programs):")
        for line, count in sorted(built.items(), key=lambda kv: -int(kv[0].split()[2])):
            print(f"  {count:3d} × {line}")


if __name__ == "__main__":
    main()
