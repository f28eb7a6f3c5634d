"""Where a netlist's cold variable-step march spends its CPU, program by program.

python benchmarks/march_compile.py [--decks ng_rc ng_rtlinv …] [--options JSON]

Each deck runs in a fresh process with the program store and JAX's cache off
(``DIRACVI_CACHE_DIR=""``): the deck is read and its operating point found (not timed),
then ``diracvi.spice._run._march`` runs once, cold. Its compiled loop
(``diracvi.driver.adaptive._march``) is traced, lowered and compiled here, each stage
timed in CPU seconds (``time.process_time``), with the XLA options the loop uses (or
``--options``, a JSON dict, to compare others), and its size counted: the jaxpr's
equations (sub-jaxprs included), the HLO instructions as lowered and after XLA's
optimization. The run-once analyses the march makes before its loop — the algebraic
momenta's and the rebase's probes, the inertia of inductors (``diracvi.driver.algebraic``,
``diracvi.driver.rebase``) — are timed the same way. Then the whole march again, warm
(the least CPU of three), and the run's steps, tries and Newton iterations, which a
change of options must leave as they are.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from _phases import table_head

HERE = Path(__file__).resolve().parent
NETLISTS = HERE.parent / "tests" / "data" / "netlists"
DECKS = ("ng_rc", "ng_rtlinv", "ng_schmitt", "xy_invert1")

CHILD = r"""
import json, os, re, sys, time
import equinox as eqx
import jax
import numpy as np
from _jaxpr import count_equations
from diracvi import spice
from diracvi.driver import adaptive, algebraic, rebase
from diracvi.runtime.compile import run_once_options
from diracvi.spice import _run

deck, options = sys.argv[1], json.loads(sys.argv[2])
netlist = spice.read(deck)
netlist.initial_state()
settings = _run.tran_settings(netlist)
breaks = _run.breakpoints(netlist.system, 0.0, settings.stop)
row = {"small": 0.0}


def hlo_size(text):
    return sum(1 for line in text.splitlines() if re.match(r"\s+(ROOT )?%?[\w.\-]+ = ", line))


def split(fn, args, opts):
    # (compiled, {trace, lower, compile} CPU s, its sizes) of fn on args' array leaves
    leaves, treedef = jax.tree.flatten((args, {}))
    dynamic = [i for i, leaf in enumerate(leaves) if eqx.is_array(leaf)]

    def on_arrays(*arrays):
        full = list(leaves)
        for i, a in zip(dynamic, arrays):
            full[i] = a
        a, k = jax.tree.unflatten(treedef, full)
        return fn(*a, **k)

    on_arrays.__name__ = fn.__name__
    t0 = time.process_time()
    traced = jax.jit(on_arrays, compiler_options=opts or None).trace(*(leaves[i] for i in dynamic))
    t1 = time.process_time()
    lowered = traced.lower()
    t2 = time.process_time()
    compiled = lowered.compile()
    t3 = time.process_time()
    sizes = (count_equations(traced.jaxpr.jaxpr), hlo_size(lowered.as_text(dialect="hlo")),
             hlo_size(compiled.as_text()))
    def call(*a, **k):
        l = jax.tree.leaves((a, k))
        return compiled(*(x for x in l if eqx.is_array(x)))
    return call, (t1 - t0, t2 - t1, t3 - t2), sizes


def small(module, name):
    # a run-once program of the march, timed (its compiled program then used)
    stored, kept = getattr(module, name), {}

    def timed(*args):
        if not kept:  # (the warm marches below call it again, on the same shapes)
            kept["call"], times, _ = split(stored.__wrapped__, args, run_once_options())
            row["small"] += sum(times)
        return kept["call"](*args)
    setattr(module, name, timed)


small(algebraic, "_probes")
small(algebraic, "_inertia")
small(rebase, "_probes")
compiled = {}


def loop(*args):
    if not compiled:
        opts = adaptive.loop_options() if options is None else options
        compiled["call"], row["loop"], row["size"] = split(adaptive._march, args, opts)
    return compiled["call"](*args)


adaptive._program = loop
start = time.process_time()
march = _run._march(netlist, settings, breaks)
row["cold"] = time.process_time() - start
warm = []
for _ in range(3):
    start = time.process_time()
    _run._march(netlist, settings, breaks)
    warm.append(time.process_time() - start)
row["warm"] = min(warm)
row["run"] = [len(march.h), int(march.tries), int(march.iterations)]
print(json.dumps(row))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decks", nargs="+", default=list(DECKS))
    parser.add_argument("--options", default="null", help="XLA options of the loop (JSON)")
    args = parser.parse_args()
    env = {**os.environ, "DIRACVI_CACHE_DIR": "", "OPENBLAS_NUM_THREADS": "1"}
    # the tests' jaxpr counter, and this folder, importable from the child
    env["PYTHONPATH"] = os.pathsep.join(
        [*filter(None, [env.get("PYTHONPATH")]), str(HERE.parent / "tests"), str(HERE)]
    )
    table_head(
        "deck", "cold march CPU", "loop: trace / lower / XLA", "run-once analyses",
        "jaxpr eqns / HLO / HLO optimized", "warm march CPU", "steps / tries / Newton",
    )  # fmt: skip
    for name in args.decks:
        out = subprocess.run(
            [sys.executable, "-c", CHILD, str(NETLISTS / f"{name}.cir"), args.options],
            env=env, capture_output=True, text=True,
        )  # fmt: skip
        if out.returncode != 0:
            print(f"| {name} | failed: {out.stderr.strip().splitlines()[-1]} |")
            continue
        r = json.loads(out.stdout.strip().splitlines()[-1])
        trace, lower, xla = r["loop"]
        print(
            f"| {name} | {r['cold']:.2f} | {trace:.2f} / {lower:.2f} / {xla:.2f} "
            f"| {r['small']:.2f} | {' / '.join(map(str, r['size']))} | {r['warm']:.3f} "
            f"| {' / '.join(map(str, r['run']))} |",
            flush=True,
        )
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
