"""Gradient ÷ forward cost of the ``gradients`` bench cases, by wall and by CPU time.

For the RLC and the torn double pendulum of ``diracvi.bench.gradients``, times
``jax.jit(loss)``, ``jax.jit(jax.grad(loss))`` with the default ``adjoint="checkpoint"``
and with ``adjoint="full"``, and ``jax.jvp(loss)``, warm, interleaved in one process;
prints the minimum over ``repeats`` of the wall time and of the process's CPU time and
each as a ratio to the forward run. CPU time is the figure to read on a loaded machine:
a long call is preempted where a short one is not.

    PYTHONPATH=src python benchmarks/gradient_cost.py [repeats]
"""

from __future__ import annotations

import argparse
import functools
import time

import jax
import jax.numpy as jnp

import diracvi as dv
from diracvi.bench import gradients as cases


def _with_adjoint(adjoint):
    simulate = dv.simulate

    @functools.wraps(simulate)
    def run(*args, **kwargs):
        kwargs["adjoint"] = adjoint
        return simulate(*args, **kwargs)

    return run


def measure(make, steps, repeats):
    loss, arg = make(steps)
    fns = {
        "forward": jax.jit(loss),
        "grad checkpoint": jax.jit(jax.grad(loss)),
        "jvp": jax.jit(lambda a: jax.jvp(loss, (a,), (jnp.ones_like(a),))),
    }
    simulate = dv.simulate
    dv.simulate = _with_adjoint("full")  # the cases look dv.simulate up when traced
    try:
        full, _ = make(steps)
        fns["grad full"] = jax.jit(jax.grad(full))
        jax.block_until_ready(fns["grad full"](arg))  # traced here, with adjoint="full"
    finally:
        dv.simulate = simulate
    for fn in fns.values():
        jax.block_until_ready(fn(arg))
    wall = {k: [] for k in fns}
    cpu = {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t, c = time.perf_counter(), time.process_time()
            jax.block_until_ready(fn(arg))
            cpu[k].append(time.process_time() - c)
            wall[k].append(time.perf_counter() - t)

    def line(times):
        base = min(times["forward"])
        return " ".join(f"{k}={min(v) * 1e3:.3f}ms({min(v) / base:.2f}x)" for k, v in times.items())

    return f"WALL {line(wall)}\n    CPU {line(cpu)}"


def main(repeats: int = 15) -> None:
    for label, make, steps in (
        ("RLC", cases._rlc_case, 100),
        ("torn", cases._pendulum_case, 200),
        ("RLC", cases._rlc_case, 400),
        ("torn", cases._pendulum_case, 1000),
    ):
        print(f"{label} {steps}:", measure(make, steps, repeats), flush=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("repeats", nargs="?", type=int, default=15, help="timing rounds")
    main(parser.parse_args().repeats)
