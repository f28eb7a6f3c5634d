"""The quadrotor's tuning loop: what a gradient through ``dv.simulate`` costs.

For the thrust-input craft (12 coordinates) and the motor–propeller craft (16), the
tracking loss of ``diracvi.problems.quadrotor`` over ``duration`` s at ``dt`` (midpoint
rule), measured side by side in one run:

- the first call (tracing + compiling) of the jitted loss and of its jitted
  value-and-gradient;
- their warm wall times (min of ``--repeat``, the two timed alternately) and the ratio
  gradient ÷ forward;
- the frame's max ‖RᵀR − I‖ over the run, with the default Newton test and with
  ``NewtonSolver(rtol=1e-16)`` (a rotor turns ~5 rad per step, and Newton's test is
  relative to the step's largest increment).

Run (``OPENBLAS_NUM_THREADS=1``):

    PYTHONPATH=src python benchmarks/quadrotor.py [--duration 2.0] [--dt 0.01]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import diracvi as dv
from diracvi.problems import quadrotor as quad


def _timed(fn, *args):
    start = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    return time.perf_counter() - start, out


def _orthonormality(q):
    rot = np.swapaxes(np.asarray(q)[:, 3:12].reshape(-1, 3, 3), 1, 2)
    return np.max(np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3)))


def measure(motors, duration, dt, repeat):
    theta = jnp.log(jnp.asarray(quad.GAINS))
    run = {"dt": dt, "duration": duration, "motors": motors}
    forward = jax.jit(lambda g: quad.tracking_loss(g, **run))
    grad = jax.jit(jax.value_and_grad(lambda g: quad.tracking_loss(g, **run)[0]))
    first_f, (_, q) = _timed(forward, theta)
    first_g, _ = _timed(grad, theta)
    warm_f, warm_g = [], []
    for k in range(1, repeat + 1):  # interleaved: machine load hits both sides alike
        warm_f.append(_timed(forward, theta + 0.01 * k)[0])
        warm_g.append(_timed(grad, theta + 0.01 * k)[0])
    warm_f, warm_g = min(warm_f), min(warm_g)
    tight = jax.jit(lambda g: quad.tracking_loss(g, solver=dv.NewtonSolver(rtol=1e-16), **run))
    _, (_, q_tight) = _timed(tight, theta)
    return first_f, first_g, warm_f, warm_g, _orthonormality(q), _orthonormality(q_tight)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--dt", type=float, default=0.01)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    print(f"tracking loss over {args.duration} s at dt = {args.dt} (midpoint)\n")
    print(
        "| craft | first forward [s] | first gradient [s] | forward [ms] | gradient [ms] "
        "| gradient ÷ forward | ‖RᵀR − I‖ default | ‖RᵀR − I‖ rtol 1e-16 |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for motors in (False, True):
        ff, fg, wf, wg, orth, orth_tight = measure(motors, args.duration, args.dt, args.repeat)
        name = "motor–propeller (16)" if motors else "thrust input (12)"
        print(
            f"| {name} | {ff:.1f} | {fg:.1f} | {1e3 * wf:.1f} | {1e3 * wg:.1f} "
            f"| {wg / wf:.2f} | {orth:.1e} | {orth_tight:.1e} |"
        )


if __name__ == "__main__":
    main()
