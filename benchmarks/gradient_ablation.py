"""Where a reverse-mode gradient's time goes: the implicit step rule taken apart.

For a case of ``diracvi.bench.gradients`` (``rlc`` or ``torn``), times, warm and
interleaved in one process (CPU time, min over ``repeats``), ``jax.jit(loss)`` and
``jax.jit(jax.grad(loss))`` with the step's JVP rule (``diracvi.driver.traced``)
replaced by

* ``no-jacobian``: ``dx = −∂r/∂θ dθ`` (no ``∂r/∂x``, no inverse): the forward sweep, the
  residual's VJP and the momentum lines — the floor of the rule (a wrong gradient, timed
  only);
* ``no-inverse``: ``dx = −(∂r/∂x) ∂r/∂θ dθ`` (the Jacobian's JVPs, no elimination);
* ``whole``: the rule as it is;

then prints, for the real gradient, the size of each compiled ``while`` body (XLA's
instructions and fusions): a loop-invariant Jacobian (a linear model's) is hoisted out
of them by the compiler.

    PYTHONPATH=src python benchmarks/gradient_ablation.py rlc 400 [repeats]
"""

from __future__ import annotations

import argparse
import re
import time

import jax
from jax.ad_checkpoint import checkpoint_name

from diracvi.bench import gradients as cases
from diracvi.driver import traced

CASES = {"rlc": cases._rlc_case, "torn": cases._pendulum_case}


def _rule(kind):
    """The JVP rule of ``traced._implicit_root`` with part of it left out."""

    def rule(solve, residual, primals, tangents):
        guess, solve_consts, residual_consts = primals
        out = solve(guess, *solve_consts)
        out = (*(checkpoint_name(leaf, traced.SOLUTION_NAME) for leaf in out[:4]), *out[4:])
        x = out[0]
        _, rhs = jax.jvp(lambda *c: residual(x, *c), tuple(residual_consts), tuple(tangents[2]))
        if kind == "no-jacobian":
            x_dot = -rhs
        else:
            jacobian = jax.jacfwd(lambda y: residual(y, *residual_consts))(x)
            x_dot = (
                -(jacobian @ rhs) if kind == "no-inverse" else -(traced._inverse(jacobian) @ rhs)
            )
        return out, (x_dot, *(traced._zero_tangent(leaf) for leaf in out[1:]))

    return rule


def loop_bodies(compiled_text: str) -> list[tuple[int, int]]:
    """(instructions, fusions) of each ``while`` body of a compiled HLO module's text."""
    bodies, current = {}, None
    for line in compiled_text.splitlines():
        head = re.match(r"^(?:ENTRY )?(%?[\w.\-]+) .*\{$", line)
        if head:
            current = bodies.setdefault(head.group(1), [])
        elif line.startswith("}"):
            current = None
        elif current is not None:
            current.append(line)
    names = re.findall(r"body=(%?[\w.\-]+)", compiled_text)
    return [(len(bodies[n]), sum("fusion(" in i for i in bodies[n])) for n in names]


def main(case: str, steps: int, repeats: int) -> None:
    make = CASES[case]
    loss, arg = make(steps)
    fns = {"forward": jax.jit(loss)}
    original = traced._implicit_root.jvp
    try:
        for kind in ("no-jacobian", "no-inverse", "whole"):
            traced._implicit_root.jvp = _rule(kind)
            variant, _ = make(steps)  # traced below, under this rule
            fns[kind] = jax.jit(jax.grad(variant))
            jax.block_until_ready(fns[kind](arg))
    finally:
        traced._implicit_root.jvp = original
    for fn in fns.values():
        jax.block_until_ready(fn(arg))
    cpu = {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            start = time.process_time()
            jax.block_until_ready(fn(arg))
            cpu[k].append(time.process_time() - start)
    base = min(cpu["forward"])
    print(f"{case} {steps} steps, CPU time, min of {repeats}, ÷ forward:")
    print(
        "  " + " ".join(f"{k}={min(v) * 1e3:.3f}ms({min(v) / base:.2f}x)" for k, v in cpu.items())
    )
    text = jax.jit(jax.grad(loss)).lower(arg).compile().as_text()
    print("  gradient's while bodies (instructions, fusions):", loop_bodies(text))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", choices=sorted(CASES))
    parser.add_argument("steps", type=int)
    parser.add_argument("repeats", nargs="?", type=int, default=100)
    args = parser.parse_args()
    main(args.case, args.steps, args.repeats)
