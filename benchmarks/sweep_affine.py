"""A 400-member sweep of a linear circuit (affine step maps) and of a nonlinear one (Newton).

python benchmarks/sweep_affine.py [--repeats N] [--members 400] [--only linear|nonlinear]

*linear*: the paper's series RLC (``problems.build_rlc``, h = 0.1, 400 steps) over a
20 × 20 grid of R × C, one batch. The plan is the affine step map, one per member (their
matrices depend on R and C).
*nonlinear*: a pendulum of length ``l`` and mass ``m`` (an ``equinox.Module``
Lagrangian, so the members group), 20 × 20 over l × m, 400 steps: stepped by Newton.

Prints the first call's time (in this process: tracing, compiling — or loading from the
on-disk program store unless ``DIRACVI_CACHE_DIR=""`` — and running) and the warm time
(min over ``--repeats`` further calls). To compare two trees, run this with
``PYTHONPATH=<tree>/src`` for each, one after the other, in fresh processes.
"""

import argparse
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import diracvi as dv
from diracvi import problems

DT, STEPS = 0.1, 400


class _Pendulum(eqx.Module):
    """``L = ½ m l² θ̇² + m g l cos θ``."""

    length: jax.Array
    mass: jax.Array

    def __call__(self, q, v):
        ml = self.mass * self.length
        return 0.5 * ml * self.length * v[0] ** 2 + 9.81 * ml * jnp.cos(q[0])


def build_pendulum(length, mass):
    system = dv.LagrangeDiracSystem(
        ("theta",), _Pendulum(jnp.asarray(length), jnp.asarray(mass)), name="pendulum"
    )
    return system, np.array([1.0]), np.array([0.0])


CASES = {
    "linear": (problems.build_rlc, ("R", (0.2, 2.0)), ("C", (1.0, 5.0)), 0.1),
    "nonlinear": (build_pendulum, ("length", (0.5, 2.0)), ("mass", (0.5, 3.0)), 0.01),
}


def _time(call):
    start = time.perf_counter()
    out = call()
    return time.perf_counter() - start, out


def main(repeats: int, members: int, only) -> None:
    side = round(members**0.5)
    for name in only or CASES:
        build, (a, ra), (b, rb), dt = CASES[name]
        grid = {a: np.linspace(*ra, side), b: np.linspace(*rb, side)}

        def call(build=build, grid=grid, dt=dt):
            return dv.sweep(build, grid, dt=dt, steps=STEPS, progress=False)

        first, ds = _time(call)
        warm = min(_time(call)[0] for _ in range(repeats))
        solvers = sorted(set(np.asarray(ds.solver.values).ravel()))
        failed = int((ds.status.values != 0).sum())
        print(
            f"{name:9s} {side * side} members × {STEPS} steps: first call {first:6.3f} s, "
            f"warm {warm:6.3f} s (min of {repeats}); solver {solvers}; failed {failed}"
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--members", type=int, default=400)
    parser.add_argument("--only", action="append", choices=tuple(CASES))
    args = parser.parse_args()
    main(args.repeats, args.members, args.only)
