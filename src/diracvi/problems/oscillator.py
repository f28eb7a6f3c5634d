r"""A damped harmonic oscillator: ``L = ½ m v² − ½ k q²``, ``F = −c v``.

The simplest check that forces enter with the dissipative sign: ``dE/dt = −c v² ≤ 0``.
"""

from __future__ import annotations

import numpy as np

from ..model.system import LagrangeDiracSystem
from ._problem import Problem, linear_flow


def damped_oscillator(
    mass: float = 1.0,
    stiffness: float = 1.0,
    damping: float = 0.1,
    q0: float = 1.0,
    p0: float = 0.0,
    dt: float = 0.01,
    steps: int = 2000,
) -> Problem:
    """A damped harmonic oscillator ``L = ½ m v² − ½ k q²``, ``F = −c v`` (``diracvi run
    damped-oscillator``).

    Equation: ``m q̈ = −k q − c q̇``; energy decays, ``dE/dt = −c q̇² ≤ 0``. ``exact(t)`` is the
    closed-form flow (a matrix exponential).

    Args:
        mass: ``m``.
        stiffness: ``k``.
        damping: ``c``.
        q0: initial position.
        p0: initial momentum ``p = m v``.
        dt: the time step used by ``diracvi run``.
        steps: the number of steps used by ``diracvi run``.

    Returns:
        A [`Problem`][diracvi.problems.Problem]. Nothing is checked here; a model
        that cannot be stepped (e.g. ``mass=0``) fails in ``dv.simulate`` with
        ``ModelError`` or ``UnsolvableStepError``.
    """
    m, k, c = float(mass), float(stiffness), float(damping)
    system = LagrangeDiracSystem(
        ("x",),
        lambda q, v: 0.5 * m * v @ v - 0.5 * k * q @ q,
        force=lambda q, v: -c * v,
        name="oscillator",
    )
    gen = np.array([[0.0, 1.0], [-k / m, -c / m]])

    def exact(t):
        return linear_flow(gen, np.array([q0, p0 / m]), t)[:, :1]

    return Problem(
        name="damped-oscillator",
        description="Mass on a spring with a linear damper (forces must remove energy)",
        system=system,
        q0=np.array([q0]),
        p0=np.array([p0]),
        dt=dt,
        steps=steps,
        exact=exact,
        reference="textbook",
        parameters={"m": m, "k": k, "c": c},
    )
