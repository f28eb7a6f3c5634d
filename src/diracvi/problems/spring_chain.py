r"""The paper's chain of spring masses attached to a wall (§5.1), monolithic form.

``L = Σ ½ m_i (v^i)² − ½ k_1 (q^1)² − Σ_{i≥2} ½ k_i (q^i − q^{i−1})²`` — no constraints,
so the (+) equations reduce to the discrete Euler–Lagrange equations. Paper data:
``m_i = k_i = 1``, ``q_0 = (0, 1, 2)``, ``p_0 = (0, 0, 3)``, ``h = 0.01``, 1000 steps.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from .._system import LagrangeDiracSystem
from ._problem import Problem, linear_flow, mass_spring_generator


def chain_stiffness(springs) -> np.ndarray:
    """``K`` of a wall-anchored chain: ``V = ½ qᵀ K q``."""
    k = np.asarray(springs, dtype=np.float64)
    n = k.size
    stiff = np.zeros((n, n))
    stiff[0, 0] += k[0]
    for i in range(1, n):
        stiff[i, i] += k[i]
        stiff[i - 1, i - 1] += k[i]
        stiff[i, i - 1] -= k[i]
        stiff[i - 1, i] -= k[i]
    return stiff


def chain_lagrangian(masses, springs):
    m = jnp.asarray(masses, dtype=jnp.float64)
    k = jnp.asarray(springs, dtype=jnp.float64)

    def lagrangian(q, v):
        stretch = jnp.concatenate([q[:1], q[1:] - q[:-1]])
        return 0.5 * jnp.sum(m * v**2) - 0.5 * jnp.sum(k * stretch**2)

    return lagrangian


def spring_chain(
    masses=(1.0, 1.0, 1.0),
    springs=(1.0, 1.0, 1.0),
    q0=(0.0, 1.0, 2.0),
    p0=(0.0, 0.0, 3.0),
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    """The paper's monolithic three-mass chain (or any N-mass chain)."""
    masses = np.asarray(masses, dtype=np.float64)
    n = masses.size
    coords = tuple(f"q{i + 1}" for i in range(n))
    system = LagrangeDiracSystem(coords, chain_lagrangian(masses, springs), name="chain")
    q0, p0 = np.asarray(q0, dtype=np.float64), np.asarray(p0, dtype=np.float64)
    gen = mass_spring_generator(np.diag(masses), chain_stiffness(springs))
    state0 = np.concatenate([q0, p0 / masses])

    def exact(t):
        return linear_flow(gen, state0, t)[:, :n]

    return Problem(
        name="spring-chain",
        description="Paper §5.1: three masses on springs from a wall, monolithic (DEL equations)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        exact=exact,
        reference="Parks & Leok §5.1, eqs. (mono_springs)",
        parameters={"masses": masses.tolist(), "springs": list(springs)},
    )
