r"""A planar double pendulum torn at the joint.

``upper``: a pendulum on a fixed pivot, ``L¹ = ½ m₁ l₁² θ̇₁² + m₁ g l₁ cos θ₁``.
``lower``: a pendulum whose pivot ``(x, y)`` is its own coordinate; its bob sits at
``(x + l₂ sin θ₂, y − l₂ cos θ₂)``, so

    L² = ½ m₂ |(ẋ + l₂ cos θ₂ θ̇₂, ẏ + l₂ sin θ₂ θ̇₂)|² − m₂ g (y − l₂ cos θ₂),

whose 3×3 mass matrix has rank 2: ``L²`` is degenerate. The joint is the interaction
"pivot moves with the upper bob", one-forms depending on θ₁::

    dx − l₁ cos θ₁ dθ₁ = 0,     dy − l₁ sin θ₁ dθ₁ = 0.

As a velocity constraint it keeps ``x = l₁ sin θ₁``, ``y = −l₁ cos θ₁`` only up to the
discretization error, so the torn model converges to the reduced ``(θ₁, θ₂)`` double
pendulum at the rule's order as h → 0.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..driver.simulate import momenta
from ..model.interaction import Interaction
from ..model.interconnect import interconnect
from ..model.system import LagrangeDiracSystem
from ._problem import Problem


def reduced_double_pendulum(m1, m2, l1, l2, g, theta0, omega0, dt, steps) -> Problem:
    """The hand-built double pendulum in ``(θ₁, θ₂)``."""

    def lagrangian(q, v):
        t1, t2 = q
        w1, w2 = v
        kinetic = (
            0.5 * (m1 + m2) * l1**2 * w1**2
            + 0.5 * m2 * l2**2 * w2**2
            + m2 * l1 * l2 * jnp.cos(t1 - t2) * w1 * w2
        )
        return kinetic + (m1 + m2) * g * l1 * jnp.cos(t1) + m2 * g * l2 * jnp.cos(t2)

    system = LagrangeDiracSystem(("theta1", "theta2"), lagrangian, name="pendulum")
    q0 = np.asarray(theta0, dtype=np.float64)
    p0 = momenta(system, q0, np.asarray(omega0, dtype=np.float64))
    return Problem(
        name="double-pendulum",
        description="Planar double pendulum in joint angles (reduced model)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        reference="textbook",
    )


def double_pendulum_torn(
    m1: float = 1.0,
    m2: float = 1.0,
    l1: float = 1.0,
    l2: float = 1.0,
    g: float = 9.81,
    theta0=(0.8, -0.4),
    omega0=(0.0, 0.5),
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    """A planar double pendulum torn at the joint (``diracvi run double-pendulum-torn``);
    see the module docstring for ``L¹``, the degenerate ``L²`` and the joint one-forms.

    ``problem.reduced`` is the hand-built ``(θ₁, θ₂)`` pendulum; the torn model converges to
    it at the rule's order as ``dt → 0`` (the joint holds at velocity level only).

    Args:
        m1: upper bob mass.
        m2: lower bob mass.
        l1: upper link length.
        l2: lower link length.
        g: gravity.
        theta0: initial angles ``(θ₁, θ₂)``.
        omega0: initial angular velocities ``(θ̇₁, θ̇₂)``.
        dt: the time step used by ``diracvi run``.
        steps: the number of steps used by ``diracvi run``.

    Returns:
        A [`Problem`][diracvi.problems.Problem] with consistent initial momenta.
        Nothing is checked here; non-positive masses or lengths give singular step
        equations that ``dv.simulate`` reports (``ModelError``/``UnsolvableStepError``).
    """

    def l_upper(q, v):
        return 0.5 * m1 * l1**2 * v[0] ** 2 + m1 * g * l1 * jnp.cos(q[0])

    def l_lower(q, v):
        _, y, t2 = q  # the pivot's x enters only through its velocity
        vx, vy, w2 = v
        bob_vx = vx + l2 * jnp.cos(t2) * w2
        bob_vy = vy + l2 * jnp.sin(t2) * w2
        return 0.5 * m2 * (bob_vx**2 + bob_vy**2) - m2 * g * (y - l2 * jnp.cos(t2))

    upper = LagrangeDiracSystem(("theta1",), l_upper, name="upper")
    lower = LagrangeDiracSystem(("x", "y", "theta2"), l_lower, name="lower")

    def joint(q):  # over (upper.theta1, lower.x, lower.y, lower.theta2)
        t1 = q[0]
        return jnp.array([[-l1 * jnp.cos(t1), 1.0, 0.0, 0.0], [-l1 * jnp.sin(t1), 0.0, 1.0, 0.0]])

    system = interconnect(
        [upper, lower], [Interaction(joint, names=("joint_x", "joint_y"))], name="pendulum"
    )
    t1, t2 = theta0
    w1, w2 = omega0
    q0 = np.array([t1, l1 * np.sin(t1), -l1 * np.cos(t1), t2])
    v0 = np.array([w1, l1 * np.cos(t1) * w1, l1 * np.sin(t1) * w1, w2])
    p0 = momenta(system, q0, v0)
    return Problem(
        name="double-pendulum-torn",
        description="Double pendulum torn at the joint (θ₁-dependent one-forms, degenerate L²)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        reference="Jacobs & Yoshimura 2014 (torn multibody systems)",
        reduced=reduced_double_pendulum(m1, m2, l1, l2, g, theta0, omega0, dt, steps),
        shared={"upper.theta1": "theta1", "lower.theta2": "theta2"},
        parameters={
            "m1": m1,
            "m2": m2,
            "l1": l1,
            "l2": l2,
            "g": g,
            "theta0": list(theta0),
            "omega0": list(omega0),
        },
    )
