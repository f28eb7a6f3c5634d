r"""The vertical rolling disk: a nonholonomic system with configuration-dependent one-forms.

Coordinates ``(x, y, θ, φ)`` (contact point, rolling angle, heading);
``L = ½ m (ẋ² + ẏ²) + ½ I θ̇² + ½ J φ̇²``; rolling without slipping::

    ẋ − R cos φ θ̇ = 0,      ẏ − R sin φ θ̇ = 0.

Exact motion (Bloch 2003, §1.4): ``θ̇ = Ω`` and ``φ̇ = ω`` stay constant and the contact
point runs on a circle of radius ``R Ω/ω``::

    x(t) = x₀ + (RΩ/ω)(sin(φ₀ + ωt) − sin φ₀),   y(t) = y₀ − (RΩ/ω)(cos(φ₀ + ωt) − cos φ₀).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model.system import LagrangeDiracSystem
from ._problem import Problem


def rolling_disk(
    mass: float = 1.0,
    radius: float = 1.0,
    inertia_roll: float = 0.5,
    inertia_turn: float = 0.25,
    roll_rate: float = 1.3,
    turn_rate: float = 0.7,
    heading: float = 0.3,
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    """The vertical rolling disk, a nonholonomic system (``diracvi run rolling-disk``).

    Equations: ``m ẍ = μ₁``, ``m ÿ = μ₂``, ``I θ̈ = −R (cos φ μ₁ + sin φ μ₂)``,
    ``J φ̈ = 0`` with ``ẋ = R cos φ θ̇``, ``ẏ = R sin φ θ̇``; ``exact(t)`` is the circle of the
    module docstring.

    Args:
        mass: ``m``.
        radius: ``R``.
        inertia_roll: ``I`` (about the axle).
        inertia_turn: ``J`` (about the vertical).
        roll_rate: ``Ω = θ̇``.
        turn_rate: ``ω = φ̇``.
        heading: ``φ₀``.
        dt: the time step used by ``diracvi run``.
        steps: the number of steps used by ``diracvi run``.

    Returns:
        A [`Problem`][diracvi.problems.Problem] with initial velocities satisfying the
        constraints. Nothing is checked here; ``turn_rate=0`` makes ``exact`` divide by
        zero (a straight line), and non-positive inertias give singular step equations.
    """
    m, rad, i_roll, i_turn = (float(x) for x in (mass, radius, inertia_roll, inertia_turn))
    big_omega, omega, phi0 = float(roll_rate), float(turn_rate), float(heading)

    def lagrangian(q, v):
        kinetic = m * (v[0] ** 2 + v[1] ** 2) + i_roll * v[2] ** 2 + i_turn * v[3] ** 2
        return 0.5 * kinetic

    def forms(q):
        phi = q[3]
        return jnp.array(
            [[1.0, 0.0, -rad * jnp.cos(phi), 0.0], [0.0, 1.0, -rad * jnp.sin(phi), 0.0]]
        )

    system = LagrangeDiracSystem(
        ("x", "y", "theta", "phi"),
        lagrangian,
        constraints=forms,
        name="disk",
        constraint_names=("roll_x", "roll_y"),
    )
    q0 = np.array([0.0, 0.0, 0.0, phi0])
    v0 = np.array(
        [rad * big_omega * np.cos(phi0), rad * big_omega * np.sin(phi0), big_omega, omega]
    )
    p0 = np.array([m * v0[0], m * v0[1], i_roll * v0[2], i_turn * v0[3]])
    r_circle = rad * big_omega / omega

    def exact(t):
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        phi = phi0 + omega * t
        return np.stack(
            [
                r_circle * (np.sin(phi) - np.sin(phi0)),
                -r_circle * (np.cos(phi) - np.cos(phi0)),
                big_omega * t,
                phi,
            ],
            axis=1,
        )

    return Problem(
        name="rolling-disk",
        description="Vertical rolling disk (nonholonomic, configuration-dependent one-forms)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        exact=exact,
        reference="Bloch, Nonholonomic Mechanics and Control (2003), §1.4",
        parameters={"m": m, "R": rad, "I": i_roll, "J": i_turn, "Omega": big_omega, "omega": omega},
    )
