r"""The Chaplygin sleigh: a rigid body on a knife edge, nonholonomic with a closed-form speed.

Coordinates ``(x, y, θ)``: the contact point of the blade and the heading. The centre of
mass lies a distance ``a`` ahead of the contact point along the blade, at
``(x + a cos θ, y + a sin θ)``; mass ``m``, moment of inertia ``I`` about the centre of
mass::

    L = ½ m ((ẋ − a sin θ θ̇)² + (ẏ + a cos θ θ̇)²) + ½ I θ̇²,
    −sin θ ẋ + cos θ ẏ = 0                       (the blade does not slide sideways).

In the body's speed ``u = cos θ ẋ + sin θ ẏ`` and turning rate ``ω = θ̇`` the motion is
(Bloch 2003, §1.7; Neimark & Fufaev 1972)::

    u̇ = a ω²,        (I + m a²) ω̇ = −m a u ω,

which conserves ``E = ½ m u² + ½ J ω²`` (``J = I + m a²``) and has the closed form

    u(t) = U tanh(κ (t − t*)),     ω(t) = ω_max sech(κ (t − t*)),
    U = √(2E/m),  κ = m a U / J,   ω_max = sign(ω₀) √(m/J) U,  tanh(−κ t*) = u₀/U,
    θ(t) = θ₀ + (ω_max/κ) (gd(κ (t − t*)) − gd(−κ t*)),   gd(s) = arctan(sinh s):

the sleigh turns less and less and runs off along a straight line at the speed ``U``.
The contact point ``(x, y)`` follows ``ẋ = u cos θ``, ``ẏ = u sin θ`` (quadrature, done by
``numerical_solution`` with DOP853 on the reduced equations in NumPy).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model.system import LagrangeDiracSystem
from ._problem import Problem


def chaplygin_sleigh(
    mass: float = 1.0,
    inertia: float = 0.5,
    offset: float = 0.5,
    speed: float = 0.2,
    turn_rate: float = 1.5,
    heading: float = 0.3,
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    """The Chaplygin sleigh (``diracvi run chaplygin-sleigh``), a nonholonomic system.

    Args:
        mass: ``m``.
        inertia: ``I`` about the centre of mass.
        offset: ``a``, the distance from the contact point to the centre of mass.
        speed: ``u₀``, the initial speed along the blade.
        turn_rate: ``ω₀``, the initial turning rate.
        heading: ``θ₀``.
        dt: the time step used by ``diracvi run``.
        steps: the number of steps used by ``diracvi run``.

    Returns:
        A [`Problem`][diracvi.problems.Problem] whose initial velocity satisfies the
        constraint; ``numerical_solution(t)`` is the reference (the closed form of the
        module docstring for ``θ``, DOP853 for the contact point); ``parameters`` carry
        ``speed_and_turn(t)``, the closed form of ``(u, ω)``.
    """
    m, inertia, a = float(mass), float(inertia), float(offset)
    u0, w0, th0 = float(speed), float(turn_rate), float(heading)
    big_j = inertia + m * a**2

    def lagrangian(q, v):
        s, c = jnp.sin(q[2]), jnp.cos(q[2])
        vx, vy = v[0] - a * s * v[2], v[1] + a * c * v[2]
        return 0.5 * m * (vx**2 + vy**2) + 0.5 * inertia * v[2] ** 2

    def blade(q):
        return jnp.array([[-jnp.sin(q[2]), jnp.cos(q[2]), 0.0]])

    system = LagrangeDiracSystem(
        ("x", "y", "theta"),
        lagrangian,
        constraints=blade,
        name="sleigh",
        constraint_names=("blade",),
    )
    q0 = np.array([0.0, 0.0, th0])
    v0 = np.array([u0 * np.cos(th0), u0 * np.sin(th0), w0])
    # p = ∂L/∂v: the centre of mass's momentum, and its moment about the contact point
    com = np.array([v0[0] - a * np.sin(th0) * w0, v0[1] + a * np.cos(th0) * w0])
    p0 = np.array(
        [
            m * com[0],
            m * com[1],
            m * a * (-np.sin(th0) * com[0] + np.cos(th0) * com[1]) + inertia * w0,
        ]
    )

    energy = 0.5 * m * u0**2 + 0.5 * big_j * w0**2
    big_u = np.sqrt(2.0 * energy / m)
    kappa = m * a * big_u / big_j
    w_max = np.sign(w0) * np.sqrt(m / big_j) * big_u
    shift = np.arctanh(u0 / big_u) / kappa  # −t*

    def speed_and_turn(t):
        """``(u(t), ω(t))``, the closed form (shape (len(t), 2))."""
        s = kappa * (np.atleast_1d(np.asarray(t, dtype=np.float64)) + shift)
        return np.stack([big_u * np.tanh(s), w_max / np.cosh(s)], axis=1)

    def heading_at(t):
        s = kappa * (np.asarray(t, dtype=np.float64) + shift)
        return th0 + (w_max / kappa) * (np.arctan(np.sinh(s)) - np.arctan(np.sinh(kappa * shift)))

    def rhs(t, y):
        u = big_u * np.tanh(kappa * (t + shift))
        th = heading_at(t)
        return [u * np.cos(th), u * np.sin(th)]

    def numerical_solution(t):
        from .linkages import _dop853  # SciPy, imported only for the reference

        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        xy = _dop853(rhs, [0.0, 0.0], 0.0, t)
        return np.concatenate([xy, heading_at(t)[:, None]], axis=1)

    return Problem(
        name="chaplygin-sleigh",
        description="Chaplygin sleigh (knife edge, nonholonomic; closed-form speed and heading)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        numerical_solution=numerical_solution,
        reference="Bloch, Nonholonomic Mechanics and Control (2003), §1.7",
        parameters={
            "m": m,
            "I": inertia,
            "a": a,
            "u0": u0,
            "omega0": w0,
            "theta0": th0,
            "speed_and_turn": speed_and_turn,
        },
    )
