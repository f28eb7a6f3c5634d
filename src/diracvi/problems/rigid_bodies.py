r"""Rigid bodies in three dimensions (director form), and their reduced references.

- :func:`free_rigid_body` — a torque-free body: Euler's ``J Ω̇ = J Ω × Ω`` with
  ``Ṙ = R Ω̂``;
- :func:`heavy_top` — a body pinned at a point of its symmetry axis by a spherical joint
  to the world, under gravity: ``J_O Ω̇ = J_O Ω × Ω + m g ℓ (e₃ × Γ)``-type torque
  ``c × (Rᵀ m g)``, ``Ṙ = R Ω̂`` (the Euler–Poisson equations), precessing and nutating;
- :func:`spatial_double_pendulum` — two links, a spherical joint to the world and a
  revolute joint between them (its reference is an external library, in the tests).

``numerical_solution`` integrates the reduced equations ``(Ω, R)`` (12 unknowns, body
angular velocity and rotation) by SciPy's DOP853 at ``rtol = atol = 1e-12``, written in
NumPy without diracvi; it returns the body's 12 director coordinates. ``euler_solution``
gives ``(Ω(t), R(t))`` itself.
"""

from __future__ import annotations

import numpy as np

from ..components.multibody import Multibody
from ..components.rigid_body import RigidBody
from ._problem import Problem
from .linkages import _dop853


def _hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def euler_solution(inertia, omega0, rotation0, t, torque=None):
    r"""``(Ω(t), R(t))`` of ``J Ω̇ = J Ω × Ω + τ(R)``, ``Ṙ = R Ω̂`` by DOP853.

    ``inertia`` is ``J`` about the fixed point (or the centre of mass), body axes;
    ``torque(R)`` the body-frame torque (``None``: a free body).
    """
    j = np.asarray(inertia, dtype=np.float64)
    j_inv = np.linalg.inv(j)

    def rhs(_, y):
        w, r = y[:3], y[3:].reshape(3, 3)
        tau = np.zeros(3) if torque is None else torque(r)
        dw = j_inv @ (np.cross(j @ w, w) + tau)
        return np.concatenate([dw, (r @ _hat(w)).reshape(9)])

    y0 = np.concatenate([omega0, np.asarray(rotation0, dtype=np.float64).reshape(9)])
    y = _dop853(rhs, y0, 0.0, t)
    return y[:, :3], y[:, 3:].reshape(-1, 3, 3)


def _coords(x, r):
    """Director coordinates ``(x, d₁, d₂, d₃)`` from positions (T, 3) and R (T, 3, 3)."""
    return np.concatenate([x, np.swapaxes(r, -1, -2).reshape(len(r), 9)], axis=1)


def _turned(rotvec) -> np.ndarray:
    """The rotation ``exp(ŵ)`` of a rotation vector (Rodrigues)."""
    w = np.asarray(rotvec, dtype=np.float64)
    angle = np.linalg.norm(w)
    if angle == 0.0:
        return np.eye(3)
    k = _hat(w / angle)
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


def free_rigid_body(
    mass: float = 2.0,
    inertia=(2.0, 3.0, 4.0),
    omega0=(0.1, 1.5, 0.05),
    rotvec0=(0.3, -0.2, 0.5),
    velocity0=(0.2, 0.0, -0.1),
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    r"""A torque-free body near its unstable middle axis (the tennis-racket flip).

    ``L = ½ m |ẋ|² + ½ tr(Ḋ E Ḋᵀ)``, ``E = ½ tr(J) I − J``, orthonormality holonomic.
    Reference: Euler's equations and ``Ṙ = R Ω̂`` by DOP853; the centre of mass moves
    uniformly. ``omega0`` is the *body* angular velocity Ω(0).
    """
    j = np.diag(np.asarray(inertia, dtype=np.float64))
    body = RigidBody(mass, j, name="body")
    r0 = _turned(rotvec0)
    w0 = np.asarray(omega0, dtype=np.float64)
    v0 = np.asarray(velocity0, dtype=np.float64)
    q0, qd0 = body.state(orientation=r0, velocity=v0, omega=r0 @ w0)

    def numerical_solution(t):
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        _, r = euler_solution(j, w0, r0, t)
        return _coords(v0[None, :] * t[:, None], r)

    return Problem(
        name="free-rigid-body",
        description="Torque-free rigid body in director form (12 coordinates, 6 holonomic rows)",
        system=body,
        q0=q0,
        p0=body.momenta(qd0),
        dt=dt,
        steps=steps,
        numerical_solution=numerical_solution,
        discretizations=("midpoint", "lobatto"),
        reference="Euler's equations + Ṙ = RΩ̂ by DOP853",
        parameters={"m": float(mass), "J": tuple(np.diag(j)), "Omega0": tuple(w0)},
    )


def heavy_top(
    mass: float = 1.0,
    inertia=(0.4, 0.4, 0.2),
    length: float = 0.5,
    gravity: float = 9.81,
    tilt: float = 0.4,
    spin: float = 20.0,
    dt: float = 0.002,
    steps: int = 500,
) -> Problem:
    r"""A symmetric top pinned at its tip: a :class:`RigidBody` whose reference point is
    the tip, centre of mass ``c = (0, 0, ℓ)`` on its symmetry axis ``d₃``, joined to the
    world by a spherical joint, gravity ``−g e_z``. It starts tilted by ``tilt`` about
    the world x-axis, spinning at ``spin`` about ``d₃`` with no precession rate, so it
    precesses and nutates.

    Reference: the Euler–Poisson equations about the tip, ``J_O Ω̇ = J_O Ω × Ω +
    c × Rᵀ(−m g e_z)``, ``J_O = J + m (|c|² I − c cᵀ)``, ``Ṙ = R Ω̂``, by DOP853.
    ``inertia`` is J about the centre of mass.
    """
    j = np.diag(np.asarray(inertia, dtype=np.float64))
    c = np.array([0.0, 0.0, float(length)])
    g = np.array([0.0, 0.0, -float(gravity)])
    body = RigidBody(mass, j, name="top", com=c, gravity=g)
    mb = Multibody("heavy_top")
    r0 = _turned([tilt, 0.0, 0.0])
    w0 = np.array([0.0, 0.0, float(spin)])
    mb.add(body, orientation=r0, omega=r0 @ w0)
    mb.joint("spherical", "top.origin", "world", name="pivot")
    model = mb.build()
    j_o = j + mass * (c @ c * np.eye(3) - np.outer(c, c))

    def numerical_solution(t):
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        _, r = euler_solution(j_o, w0, r0, t, torque=lambda r: np.cross(c, r.T @ (mass * g)))
        return _coords(np.zeros((len(t), 3)), r)

    return Problem(
        name="heavy-top",
        description="Heavy symmetric top on a spherical joint (director form)",
        system=model.system,
        q0=model.q0,
        p0=model.p0,
        dt=dt,
        steps=steps,
        numerical_solution=numerical_solution,
        discretizations=("midpoint", "lobatto"),
        reference="Euler–Poisson equations about the tip by DOP853",
        parameters={"m": float(mass), "J": tuple(np.diag(j)), "l": float(length)},
    )


#: the spatial double pendulum's links: mass, principal inertia about the centre of mass,
#: joint-to-centre distance along −d₃, link length
LINKS = ((1.0, (0.1, 0.1, 0.02), 0.5, 1.0), (0.7, (0.05, 0.06, 0.02), 0.4, 0.8))
#: the revolute joint's axes as columns (body axes): its third axis is the links' d₁
HINGE_AXES = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def spatial_double_pendulum(
    rotvec0=(0.6, 0.2, 0.0),
    omega0=(0.3, -0.4, 1.0),
    hinge_rate: float = 2.0,
    gravity: float = 9.81,
    torn: bool = False,
    dt: float = 0.01,
    steps: int = 100,
) -> Problem:
    r"""Two links: the first hangs from the world origin by a spherical joint at its top;
    the second hangs from the first's bottom by a revolute joint about the first's body
    x-axis. Both start turned by ``rotvec0`` (hinge angle 0); ``omega0`` is the first
    link's *body* angular velocity, ``hinge_rate`` the hinge's. ``torn=True`` builds one
    subsystem per body and joint. Each link's reference point is its centre of mass.
    """
    g = np.array([0.0, 0.0, -float(gravity)])
    (m1, j1, a1, l1), (m2, j2, a2, _) = LINKS
    link1 = RigidBody(
        m1,
        j1,
        name="link1",
        gravity=g,
        frames={"top": (0.0, 0.0, a1), "bottom": ((0.0, 0.0, a1 - l1), HINGE_AXES)},
    )
    link2 = RigidBody(m2, j2, name="link2", gravity=g, frames={"top": ((0.0, 0.0, a2), HINGE_AXES)})
    r0 = _turned(rotvec0)
    w1 = r0 @ np.asarray(omega0, dtype=np.float64)
    w2 = w1 + float(hinge_rate) * r0 @ np.array([1.0, 0.0, 0.0])
    x1 = r0 @ np.array([0.0, 0.0, -a1])
    bottom = x1 + r0 @ np.array([0.0, 0.0, a1 - l1])
    x2 = bottom - r0 @ np.array([0.0, 0.0, a2])
    mb = Multibody("spatial_double_pendulum")
    mb.add(link1, position=x1, orientation=r0, velocity=np.cross(w1, x1), omega=w1)
    mb.add(
        link2,
        position=x2,
        orientation=r0,
        velocity=np.cross(w1, bottom) + np.cross(w2, x2 - bottom),
        omega=w2,
    )
    mb.joint("spherical", "link1.top", "world", name="shoulder")
    mb.joint("revolute", "link1.bottom", "link2.top", name="elbow")
    model = mb.build(torn=torn)
    return Problem(
        name="spatial-double-pendulum",
        description="Two links on a spherical and a revolute joint (director form)",
        system=model.system,
        q0=model.q0,
        p0=model.p0,
        dt=dt,
        steps=steps,
        discretizations=("midpoint", "lobatto"),
        reference="an external rigid-body library (tests)",
        parameters={"links": LINKS, "g": float(gravity), "torn": torn},
    )


__all__ = ["euler_solution", "free_rigid_body", "heavy_top", "spatial_double_pendulum"]
