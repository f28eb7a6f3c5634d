r"""Mechanisms with holonomic (position-level) constraints, and their reduced references.

- :func:`cartesian_pendulum` — a bob at ``(x, y)`` on a rod, ``g = x² + y² − ℓ² = 0``;
- :func:`four_bar` — a planar four-bar linkage (a closed kinematic loop) in its three
  link angles, with two loop-closure constraints, gravity and a driving torque;
- :func:`cart_pendulum_torn` — a cart on a spring joined to a Cartesian pendulum whose
  pivot is a port variable: a holonomic constraint inside an interconnected subsystem.

Each carries ``numerical_solution``: a reduced-coordinate ODE (one angle, or the cart
position and one angle) integrated by SciPy's DOP853 at ``rtol = atol = 1e-12``, written
here in NumPy without diracvi.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model.interaction import connect
from ..model.interconnect import interconnect
from ..model.system import LagrangeDiracSystem
from ._problem import Problem

RTOL = ATOL = 1e-12


def _dop853(rhs, y0, t0, t):
    """Dense DOP853 solution of ``ẏ = rhs(t, y)`` from ``(t0, y0)``, sampled at ``t``."""
    import scipy.integrate  # only for a reference: its import is half a second

    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    end = float(np.max(t)) if np.max(t) > t0 else t0 + 1e-12
    sol = scipy.integrate.solve_ivp(
        rhs, (t0, end), y0, method="DOP853", rtol=RTOL, atol=ATOL, dense_output=True
    )
    if not sol.success:
        raise RuntimeError(f"reference solve_ivp failed: {sol.message}")
    return sol.sol(t).T


def cartesian_pendulum(
    mass: float = 1.0,
    length: float = 1.0,
    gravity: float = 9.81,
    theta0: float = 1.0,
    omega0: float = 0.0,
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    r"""A pendulum in Cartesian coordinates: ``L = ½ m (ẋ² + ẏ²) − m g y``,
    holonomic ``g(x, y) = x² + y² − ℓ² = 0`` (enforced at every step).

    Reference: ``θ̈ = −(g/ℓ) sin θ`` with ``x = ℓ sin θ``, ``y = −ℓ cos θ`` (θ from the
    downward vertical), by DOP853. Initial data ``θ₀``, ``θ̇₀``: ``q₀`` on the circle and
    ``p₀ = m ℓ θ̇₀ (cos θ₀, sin θ₀)`` tangent to it.
    """
    m, ell, grav = float(mass), float(length), float(gravity)
    system = LagrangeDiracSystem(
        ("x", "y"),
        lambda q, v: 0.5 * m * v @ v - m * grav * q[1],
        holonomic=lambda q: jnp.atleast_1d(q @ q - ell**2),
        holonomic_names=("rod",),
        name="pendulum",
    )
    q0 = ell * np.array([np.sin(theta0), -np.cos(theta0)])
    p0 = m * ell * omega0 * np.array([np.cos(theta0), np.sin(theta0)])

    def rhs(t, y):
        return [y[1], -(grav / ell) * np.sin(y[0])]

    def numerical_solution(t):
        theta = _dop853(rhs, [theta0, omega0], 0.0, t)[:, 0]
        return ell * np.stack([np.sin(theta), -np.cos(theta)], axis=1)

    return Problem(
        name="cartesian-pendulum",
        description="Pendulum in (x, y) with the holonomic rod constraint x² + y² = ℓ²",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        numerical_solution=numerical_solution,
        reference="textbook; reduced θ-equation by DOP853",
        parameters={"m": m, "l": ell, "g": grav, "theta0": theta0, "omega0": omega0},
    )


class FourBar:
    r"""Kinematics and reduced dynamics of a four-bar linkage (NumPy, no diracvi).

    Ground pivots ``O = (0, 0)`` and ``D = (d, 0)``; crank ``OA`` (length a, angle θ₁),
    coupler ``AB`` (b, θ₂), rocker ``DB`` (c, θ₃); uniform bars of masses m₁, m₂, m₃.
    Closure ``Φ(θ) = a e(θ₁) + b e(θ₂) − c e(θ₃) − d e_x = 0`` (two equations),
    ``e(θ) = (cos θ, sin θ)``.

    Kinetic energy ``T = ½ θ̇ᵀ M(θ) θ̇`` with ``M₁₁ = m₁a²/3 + m₂a²``,
    ``M₂₂ = m₂b²/3``, ``M₃₃ = m₃c²/3``, ``M₁₂ = M₂₁ = κ cos(θ₁ − θ₂)``, ``κ = m₂ab/2``;
    potential ``V = g (m₁ a/2 sin θ₁ + m₂ (a sin θ₁ + b/2 sin θ₂) + m₃ c/2 sin θ₃)``
    (gravity along −y); torque ``τ(t) = τ₀ cos Ωt`` on the crank.

    Reduced equation in the crank angle: the closure gives ``θ₂, θ₃`` (the branch with
    the joint B on the left of A→D, "elbow up") and the velocity ratios ``θ̇ = s(θ) θ̇₁``
    (``s₁ = 1``, ``Φ_θ s = 0``); with ``θ̈ = s θ̈₁ + w``, ``Φ_θ w = −(Φ_θ θ̇)_θ θ̇``,
    Lagrange's equations ``M θ̈ + c(θ, θ̇) + ∇V = F + Φ_θᵀλ`` projected on ``s`` give

        (sᵀ M s) θ̈₁ = sᵀ (F − ∇V − c − M w),
        c = (κ sin(θ₁ − θ₂) θ̇₂², −κ sin(θ₁ − θ₂) θ̇₁², 0).
    """

    def __init__(self, a, b, c, d, m1, m2, m3, gravity, torque, torque_frequency):
        self.a, self.b, self.c, self.d = a, b, c, d
        self.m1, self.m2, self.m3 = m1, m2, m3
        self.g, self.tau0, self.om = gravity, torque, torque_frequency
        self.kappa = m2 * a * b / 2.0

    def closure(self, theta1):
        """``(θ₂, θ₃)`` closing the loop at crank angle θ₁ (elbow-up branch)."""
        a, b, c, d = self.a, self.b, self.c, self.d
        pa = a * np.array([np.cos(theta1), np.sin(theta1)])
        r = np.array([d, 0.0]) - pa
        rho = np.hypot(*r)
        along = (b**2 - c**2 + rho**2) / (2.0 * rho)
        height = np.sqrt(b**2 - along**2)
        perp = np.array([-r[1], r[0]]) / rho
        pb = pa + along * r / rho + height * perp
        return np.arctan2(pb[1] - pa[1], pb[0] - pa[0]), np.arctan2(pb[1], pb[0] - d)

    def angles(self, theta1):
        t2, t3 = self.closure(theta1)
        return np.array([theta1, t2, t3])

    def mass_matrix(self, th):
        a, b, c = self.a, self.b, self.c
        m12 = self.kappa * np.cos(th[0] - th[1])
        return np.array(
            [
                [self.m1 * a**2 / 3 + self.m2 * a**2, m12, 0.0],
                [m12, self.m2 * b**2 / 3, 0.0],
                [0.0, 0.0, self.m3 * c**2 / 3],
            ]
        )

    def potential_gradient(self, th):
        a, b, c, g = self.a, self.b, self.c, self.g
        return g * np.array(
            [
                (self.m1 / 2 + self.m2) * a * np.cos(th[0]),
                self.m2 * b / 2 * np.cos(th[1]),
                self.m3 * c / 2 * np.cos(th[2]),
            ]
        )

    def torque(self, t):
        return self.tau0 * np.cos(self.om * t)

    def _dependent(self, th, rhs):
        """Solve ``[−b sin θ₂, c sin θ₃; b cos θ₂, −c cos θ₃] x = rhs``."""
        b, c = self.b, self.c
        mat = np.array(
            [[-b * np.sin(th[1]), c * np.sin(th[2])], [b * np.cos(th[1]), -c * np.cos(th[2])]]
        )
        return np.linalg.solve(mat, rhs)

    def velocity_ratios(self, th):
        a = self.a
        s23 = self._dependent(th, np.array([a * np.sin(th[0]), -a * np.cos(th[0])]))
        return np.array([1.0, *s23])

    def rhs(self, t, y):
        theta1, omega1 = y
        th = self.angles(theta1)
        s = self.velocity_ratios(th)
        w = s * omega1
        a, b, c = self.a, self.b, self.c
        gamma = np.array(
            [
                -a * np.cos(th[0]) * w[0] ** 2
                - b * np.cos(th[1]) * w[1] ** 2
                + c * np.cos(th[2]) * w[2] ** 2,
                -a * np.sin(th[0]) * w[0] ** 2
                - b * np.sin(th[1]) * w[1] ** 2
                + c * np.sin(th[2]) * w[2] ** 2,
            ]
        )
        acc = np.array([0.0, *self._dependent(th, -gamma)])
        sd = np.sin(th[0] - th[1])
        coriolis = self.kappa * np.array([sd * w[1] ** 2, -sd * w[0] ** 2, 0.0])
        mass = self.mass_matrix(th)
        force = np.array([self.torque(t), 0.0, 0.0])
        rhs = s @ (force - self.potential_gradient(th) - coriolis - mass @ acc)
        return [omega1, rhs / (s @ mass @ s)]

    def energy(self, th, thdot):
        """``T + V`` (its rate is the torque's power ``τ θ̇₁``)."""
        a, b, c, g = self.a, self.b, self.c, self.g
        pot = g * (
            (self.m1 / 2 + self.m2) * a * np.sin(th[0])
            + self.m2 * b / 2 * np.sin(th[1])
            + self.m3 * c / 2 * np.sin(th[2])
        )
        return 0.5 * thdot @ self.mass_matrix(th) @ thdot + pot


def four_bar(
    crank: float = 1.0,
    coupler: float = 3.0,
    rocker: float = 2.5,
    ground: float = 3.0,
    masses=(1.0, 2.0, 1.5),
    gravity: float = 9.81,
    torque: float = 20.0,
    torque_frequency: float = 2.0,
    theta0: float = np.pi / 3,
    omega0: float = 0.0,
    dt: float = 0.01,
    steps: int = 200,
) -> Problem:
    r"""A Grashof crank-rocker four-bar linkage in its three link angles ``(θ₁, θ₂, θ₃)``.

    ``L = ½ θ̇ᵀ M(θ) θ̇ − V(θ)`` and the torque ``F = (τ₀ cos Ωt, 0, 0)`` as in
    :class:`FourBar`; holonomic loop closure (two rows)

        g₁ = a cos θ₁ + b cos θ₂ − c cos θ₃ − d = 0,
        g₂ = a sin θ₁ + b sin θ₂ − c sin θ₃ = 0.

    The default links ``a, b, c, d = 1, 3, 2.5, 3`` keep the transmission angle in
    [41°, 93°], far from the singular (coupler ∥ rocker) configurations. Reference: the
    1-DOF crank-angle equation of :class:`FourBar` by DOP853, the other two angles from
    the closure.
    """
    a, b, c, d = (float(x) for x in (crank, coupler, rocker, ground))
    m1, m2, m3 = (float(x) for x in masses)
    linkage = FourBar(a, b, c, d, m1, m2, m3, float(gravity), float(torque), torque_frequency)
    kappa, grav, tau0, om = linkage.kappa, linkage.g, linkage.tau0, linkage.om

    def lagrangian(q, v):
        m12 = kappa * jnp.cos(q[0] - q[1])
        kinetic = (
            0.5
            * (
                (m1 * a**2 / 3 + m2 * a**2) * v[0] ** 2
                + m2 * b**2 / 3 * v[1] ** 2
                + m3 * c**2 / 3 * v[2] ** 2
            )
            + m12 * v[0] * v[1]
        )
        potential = grav * (
            (m1 / 2 + m2) * a * jnp.sin(q[0])
            + m2 * b / 2 * jnp.sin(q[1])
            + m3 * c / 2 * jnp.sin(q[2])
        )
        return kinetic - potential

    def loop(q):
        return jnp.stack(
            [
                a * jnp.cos(q[0]) + b * jnp.cos(q[1]) - c * jnp.cos(q[2]) - d,
                a * jnp.sin(q[0]) + b * jnp.sin(q[1]) - c * jnp.sin(q[2]),
            ]
        )

    def force(q, v, t):
        return jnp.stack([tau0 * jnp.cos(om * t) + 0.0 * v[0], 0.0 * v[1], 0.0 * v[2]])

    system = LagrangeDiracSystem(
        ("theta1", "theta2", "theta3"),
        lagrangian,
        force=force,
        holonomic=loop,
        holonomic_names=("loop_x", "loop_y"),
        name="four_bar",
    )
    q0 = linkage.angles(theta0)
    v0 = linkage.velocity_ratios(q0) * omega0
    p0 = linkage.mass_matrix(q0) @ v0

    def numerical_solution(t):
        y = _dop853(linkage.rhs, [theta0, omega0], 0.0, t)
        angles = np.stack([linkage.angles(th) for th in y[:, 0]])
        # coupler and rocker of a crank-rocker swing less than π: the branch nearest q0
        angles[:, 1:] = q0[1:] + np.angle(np.exp(1j * (angles[:, 1:] - q0[1:])))
        return angles

    return Problem(
        name="four-bar",
        description="Four-bar linkage in 3 link angles, holonomic loop closure, torque + gravity",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        numerical_solution=numerical_solution,
        reference="textbook (planar four-bar); reduced crank-angle ODE by DOP853",
        parameters={
            "a": a,
            "b": b,
            "c": c,
            "d": d,
            "masses": (m1, m2, m3),
            "g": grav,
            "tau0": tau0,
            "Omega": om,
            "theta0": theta0,
            "omega0": omega0,
        },
    )


def cart_pendulum_torn(
    cart_mass: float = 2.0,
    spring: float = 4.0,
    bob_mass: float = 0.5,
    length: float = 1.0,
    gravity: float = 9.81,
    x0: float = 0.3,
    theta0: float = 0.8,
    dt: float = 0.01,
    steps: int = 500,
) -> Problem:
    r"""A cart on a spring joined to a pendulum in Cartesian coordinates.

    ``cart``: ``(x,)``, ``L¹ = ½ M ẋ² − ½ k x²``. ``pend``: ``(x_s, b_x, b_y)`` — the pivot
    ``x_s`` is a massless port variable — ``L² = ½ m (ḃ_x² + ḃ_y²) − m g b_y``, holonomic
    ``(b_x − x_s)² + b_y² − ℓ² = 0``. Interaction ``ẋ = ẋ_s`` (a one-form).

    Reference (reduced ``(x, θ)``): ``(M + m) ẍ + m ℓ (θ̈ cos θ − θ̇² sin θ) = −k x``,
    ``ℓ θ̈ + ẍ cos θ + g sin θ = 0``, by DOP853.
    """
    big_m, k, m, ell, grav = (float(x) for x in (cart_mass, spring, bob_mass, length, gravity))
    cart = LagrangeDiracSystem(
        ("x",), lambda q, v: 0.5 * big_m * v @ v - 0.5 * k * q @ q, name="cart"
    )
    pend = LagrangeDiracSystem(
        ("xs", "bx", "by"),
        lambda q, v: 0.5 * m * (v[1] ** 2 + v[2] ** 2) - m * grav * q[2],
        holonomic=lambda q: jnp.atleast_1d((q[1] - q[0]) ** 2 + q[2] ** 2 - ell**2),
        holonomic_names=("rod",),
        name="pend",
    )
    system = interconnect([cart, pend], [connect("cart.x", "pend.xs")], name="cart_pendulum")
    q0 = np.array([x0, x0, x0 + ell * np.sin(theta0), -ell * np.cos(theta0)])
    p0 = np.zeros(4)

    def rhs(t, y):
        x, th, xd, thd = y
        mat = np.array([[big_m + m, m * ell * np.cos(th)], [np.cos(th), ell]])
        vec = np.array([-k * x + m * ell * thd**2 * np.sin(th), -grav * np.sin(th)])
        xdd, thdd = np.linalg.solve(mat, vec)
        return [xd, thd, xdd, thdd]

    def numerical_solution(t):
        y = _dop853(rhs, [x0, theta0, 0.0, 0.0], 0.0, t)
        x, th = y[:, 0], y[:, 1]
        return np.stack([x, x, x + ell * np.sin(th), -ell * np.cos(th)], axis=1)

    return Problem(
        name="cart-pendulum-torn",
        description="Cart on a spring joined to a Cartesian pendulum (holonomic subsystem)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        numerical_solution=numerical_solution,
        reference="textbook (pendulum on a cart); reduced (x, θ) by DOP853",
        parameters={"M": big_m, "k": k, "m": m, "l": ell, "g": grav},
        ports=(("cart.x", "pend.xs"),),
    )


__all__ = ["FourBar", "cart_pendulum_torn", "cartesian_pendulum", "four_bar"]
