r"""A rigid body in three dimensions in the director (rotation-free) form.

The body's configuration is ``q = (x, d₁, d₂, d₃) ∈ R¹²``: the position ``x`` of its
reference point and the three body-fixed unit vectors ``dᵢ`` (the columns of its
rotation ``R = [d₁ d₂ d₃]``). A material point with body coordinates ``X`` is at
``x + Σ Xᵢ dᵢ`` — *linear* in ``q``, so the kinetic energy is quadratic with a constant
mass matrix (Betsch & Steinmann 2001)::

    T = ½ Σ_ab M̄_ab ẏ_a·ẏ_b,   y = (x, d₁, d₂, d₃),
    M̄ = [[m, m cᵀ], [m c, E]],  E = E_c + m c cᵀ,  E_c = ½ tr(J) I − J,

with ``c`` the centre of mass and ``J`` the inertia tensor about it, both in body
coordinates; ``E_c = ∫ ρ X Xᵀ`` is the "Euler tensor" (the second moment of mass). Gravity
is ``V = −m g·(x + Σ cᵢ dᵢ)``. The six orthonormality conditions

    g = (d₁·d₁ − 1, d₂·d₂ − 1, d₃·d₃ − 1, d₁·d₂, d₁·d₃, d₂·d₃) = 0

are holonomic rows, which every step enforces at its end (``g(q_{k+1}) = 0``), so ``R``
stays orthonormal to round-off with no parametrisation of rotations (no singular Euler
angles, no quaternion norm drift). The equations are the Euler–Lagrange equations of the
constrained ``L = T − V``; their reduction is Euler's ``J Ω̇ + Ω × J Ω = τ``.

Applied loads are generalized forces (covectors on ``q``) with the right virtual work:
a force ``f`` at the body point ``X`` is ``(f, X₁ f, X₂ f, X₃ f)``; a torque ``τ`` (world
axes) is ``(0, ½ τ × d₁, ½ τ × d₂, ½ τ × d₃)``, since ``Σ dᵢ × (½ τ × dᵢ) = τ`` when the
``dᵢ`` are orthonormal.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._gram import gram_rows
from ._part import Part, positive

#: the body's twelve coordinates: its reference point, then the directors' components
COORDS = ("x", "y", "z", *(f"d{i}{a}" for i in (1, 2, 3) for a in "xyz"))
#: names of the six orthonormality rows
ORTHONORMALITY = ("d1.d1", "d2.d2", "d3.d3", "d1.d2", "d1.d3", "d2.d3")


def vector(where: str, arg: str, value, shape=(3,)) -> np.ndarray:
    """``value`` as a finite float array of ``shape``, else a :class:`ModelError`."""
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ModelError(
            f"{where}: {arg}={value!r} is not numeric; pass {shape} numbers."
        ) from None
    if out.shape != shape or not np.all(np.isfinite(out)):
        raise ModelError(f"{where}: {arg}={value!r} must be finite numbers of shape {shape}.")
    return out


def rotation(where: str, arg: str, value, tol: float = 1e-10) -> np.ndarray:
    """``value`` as a proper rotation matrix (columns orthonormal, det +1), checked."""
    r = vector(where, arg, value, (3, 3))
    err = np.max(np.abs(r.T @ r - np.eye(3)))
    if err > tol or np.linalg.det(r) < 0.0:
        raise ModelError(
            f"{where}: {arg} is not a rotation (max |RᵀR − I| = {err:.2e}, det = "
            f"{np.linalg.det(r):.3f}); pass a 3×3 matrix with orthonormal columns and det +1."
        )
    return r


def directors(q):
    """The rotation ``R = [d₁ d₂ d₃]`` (columns) of a body's coordinates ``q`` (12,)."""
    return q[3:12].reshape(3, 3).T


def orthonormality(q):
    """The six rows ``dᵢ·dⱼ − δᵢⱼ`` (i ≤ j) of one body's coordinates, in ORTHONORMALITY's
    order (`_gram.GRAM_PAIRS`), each to ``O(ε²)`` (:mod:`._gram`: the plainly rounded
    rows bias the angular momentum of a long run); their derivative is the plain one."""
    return gram_rows(q[3:12].reshape(3, 3))


def point(q, local):
    """World position ``x + Σ Xᵢ dᵢ`` of the body point ``X = local`` (body coordinates)."""
    return q[0:3] + directors(q) @ local


def axis(q, local):
    """World direction ``Σ aᵢ dᵢ`` of the body-fixed vector ``a = local``."""
    return directors(q) @ local


def angular_velocity(q, v):
    r"""World angular velocity ``ω = ½ Σ dᵢ × ḋᵢ`` (exact when ``ḋᵢ = ω × dᵢ``)."""
    d = np.asarray(q)[..., 3:12].reshape(*np.shape(q)[:-1], 3, 3)
    dv = np.asarray(v)[..., 3:12].reshape(*np.shape(v)[:-1], 3, 3)
    return 0.5 * np.cross(d, dv).sum(axis=-2)


def angular_momentum(q, p):
    r"""Angular momentum about the world origin ``x × p_x + Σ dᵢ × p_{dᵢ}`` — the
    momentum map of rotations acting on all four vectors of ``q`` (conserved by a free
    body and by each step of a symmetric rule)."""
    y = np.asarray(q).reshape(*np.shape(q)[:-1], 4, 3)
    py = np.asarray(p).reshape(*np.shape(p)[:-1], 4, 3)
    return np.cross(y, py).sum(axis=-2)


class Inertial(eqx.Module):
    r"""The constant 4×4 director mass matrix ``M̄`` and the gravity covector of a body:
    ``L(q, v) = ½ tr(Wᵀ M̄ W) + (m (1, c))·Y g``, ``Y = q`` and ``W = v`` as 4×3."""

    # tuples, not arrays: static fields are hashed with the system's structure
    mbar: tuple = eqx.field(static=True)
    weights: tuple = eqx.field(static=True)  # m (1, c₁, c₂, c₃)
    gravity: tuple = eqx.field(static=True)

    def __init__(self, mbar, weights, gravity):
        self.mbar = _floats(mbar)
        self.weights = _floats(weights)
        self.gravity = _floats(gravity)

    def __call__(self, q, v):
        y, w = q.reshape(4, 3), v.reshape(4, 3)
        kinetic = 0.5 * jnp.sum(w * (jnp.asarray(self.mbar) @ w))
        return kinetic + jnp.asarray(self.weights) @ y @ jnp.asarray(self.gravity)


def director_mass(where: str, mass, inertia, com) -> np.ndarray:
    """``M̄ = [[m, m cᵀ], [m c, E_c + m c cᵀ]]`` with ``E_c = ½ tr(J) I − J``, after
    checking that ``J`` is a physical inertia tensor (symmetric, with strictly positive
    ``E_c``: the triangle inequalities ``Jᵢ < Jⱼ + Jₖ`` of its principal moments)."""
    m = positive(where, "mass", mass)
    if np.shape(inertia) == (3,):  # principal moments
        inertia = np.diag(vector(where, "inertia", inertia))
    j = vector(where, "inertia", inertia, (3, 3))
    if np.max(np.abs(j - j.T)) > 1e-12 * max(1.0, np.max(np.abs(j))):
        raise ModelError(f"{where}: inertia={j.tolist()} is not symmetric; pass J = Jᵀ.")
    euler = 0.5 * np.trace(j) * np.eye(3) - j
    low = np.linalg.eigvalsh(euler)[0]
    if low <= 0.0:
        raise ModelError(
            f"{where}: inertia={j.tolist()} is not the inertia tensor of a body with volume "
            f"(its Euler tensor ½ tr(J) I − J has eigenvalue {low:.3g} ≤ 0: the principal "
            "moments must satisfy Jᵢ < Jⱼ + Jₖ). A slender rod needs a small nonzero "
            "moment about its axis."
        )
    c = vector(where, "com", com)
    mbar = np.zeros((4, 4))
    mbar[0, 0] = m
    mbar[0, 1:] = mbar[1:, 0] = m * c
    mbar[1:, 1:] = euler + m * np.outer(c, c)
    return mbar


class Loads(eqx.Module):
    r"""Applied force ``f(t)`` at a body point ``X`` and torque ``τ(t)`` (world axes) as
    the covector ``(f, X₁ f, X₂ f, X₃ f) + (0, ½ τ × d₁, ½ τ × d₂, ½ τ × d₃)``."""

    force: object = eqx.field(static=True)
    torque: object = eqx.field(static=True)
    at: tuple = eqx.field(static=True)

    def __call__(self, q, v, t):
        d = q[3:12].reshape(3, 3)
        zero = 0.0 * v[0:3]
        f = zero if self.force is None else jnp.asarray(self.force(t)) + zero
        tau = zero if self.torque is None else jnp.asarray(self.torque(t)) + zero
        rows = jnp.asarray(self.at)[:, None] * f[None, :] + 0.5 * jnp.cross(tau[None, :], d)
        return jnp.concatenate([f, rows.reshape(9)])


def _load(where: str, arg: str, value):
    """A constant 3-vector, or a callable ``t -> (3,)`` (checked at t = 0)."""
    if value is None:
        return None
    if callable(value):
        out = np.asarray(value(0.0), dtype=np.float64)
        if out.shape != (3,):
            raise ModelError(f"{where}: {arg}(t) returned shape {out.shape}; it must be (3,).")
        return value
    const = vector(where, arg, value)
    return _Constant(_floats(const))


class _Constant(eqx.Module):
    value: tuple = eqx.field(static=True)

    def __call__(self, t):
        return jnp.asarray(self.value) + 0.0 * t


class RigidBody(Part):
    r"""A rigid body ``q = (x, d₁, d₂, d₃)`` with its orthonormality as holonomic rows.

    ``L = ½ tr(Ẏᵀ M̄ Ẏ) + m g·(x + Σ cᵢ dᵢ)`` (see the module docstring for ``M̄``).

    Args:
        mass: ``m > 0``.
        inertia: the inertia tensor about the centre of mass in body axes: a 3×3
            symmetric matrix, or its three principal moments.
        name: the body's name.
        com: the centre of mass ``c`` in body coordinates (default the reference point).
        frames: ``{name: point}`` or ``{name: (point, R)}``: body-fixed frames, the
            ports joints attach to (``point`` in body coordinates, ``R`` the frame's axes
            as columns in body axes; default ``I``). ``"origin"`` is always there.
        gravity: the gravitational acceleration vector (world axes), default none.
        force: an applied force (world axes), constant ``(3,)`` or ``f(t) -> (3,)``.
        force_at: the body point (body coordinates) the force acts at; default ``com``.
        torque: an applied torque (world axes), constant or ``τ(t) -> (3,)``.
    """

    inertial: Inertial
    loads: Loads | None
    _mbar: tuple = eqx.field(static=True)
    _gravity: tuple = eqx.field(static=True)
    body_frames: tuple = eqx.field(static=True)

    def __init__(
        self,
        mass,
        inertia,
        *,
        name: str,
        com=(0.0, 0.0, 0.0),
        frames=None,
        gravity=(0.0, 0.0, 0.0),
        force=None,
        force_at=None,
        torque=None,
    ):
        where = f"RigidBody {name!r}"
        mbar = director_mass(where, mass, inertia, com)
        c = mbar[0, 1:] / mbar[0, 0]
        grav = vector(where, "gravity", gravity)
        lagrangian = Inertial(mbar, mbar[0, 0] * np.concatenate([[1.0], c]), grav)
        f, tau = _load(where, "force", force), _load(where, "torque", torque)
        at = c if force_at is None else vector(where, "force_at", force_at)
        loads = None if f is None and tau is None else Loads(f, tau, _floats(at))
        super().__init__(
            COORDS,
            lagrangian,
            force=loads,
            holonomic=orthonormality,
            holonomic_names=ORTHONORMALITY,
            name=name,
            role="rigid body",
            parameters={"mass": float(mbar[0, 0])},
        )
        self.inertial, self.loads = lagrangian, loads
        self._mbar, self._gravity = _floats(mbar), _floats(grav)
        self.body_frames = _frames(where, frames)

    @property
    def mbar(self) -> np.ndarray:
        """The 4×4 director mass matrix ``M̄``."""
        return np.array(self._mbar)

    @property
    def gravity(self) -> np.ndarray:
        """The gravitational acceleration acting on the body (world axes)."""
        return np.array(self._gravity)

    def frame(self, name: str):
        """``(point, R)`` of the body frame ``name`` (body coordinates)."""
        for key, pt, rot in self.body_frames:
            if key == name:
                return np.asarray(pt), np.asarray(rot)
        raise ModelError(
            f"RigidBody {self.name!r} has no frame {name!r}; its frames are "
            f"{[k for k, _, _ in self.body_frames]} (add one with frames={{name: point}})."
        )

    def state(self, position=(0.0, 0.0, 0.0), orientation=None, velocity=None, omega=None):
        r"""Consistent ``(q, v)`` of the body: reference point at ``position``, rotation
        ``orientation`` (default ``I``), reference-point velocity ``velocity`` and world
        angular velocity ``omega`` (``ḋᵢ = ω × dᵢ``)."""
        where = f"RigidBody {self.name!r}"
        x = vector(where, "position", position)
        r = np.eye(3) if orientation is None else rotation(where, "orientation", orientation)
        xd = np.zeros(3) if velocity is None else vector(where, "velocity", velocity)
        w = np.zeros(3) if omega is None else vector(where, "omega", omega)
        q = np.concatenate([x, r.T.reshape(9)])
        v = np.concatenate([xd, np.cross(w, r.T).reshape(9)])
        return q, v

    def momenta(self, v):
        """``p = (M̄ ⊗ I₃) v`` (the Legendre transform; constant mass matrix)."""
        return (self.mbar @ np.asarray(v, dtype=np.float64).reshape(4, 3)).reshape(12)


def _floats(array) -> tuple:
    """A float array as nested tuples of Python floats (hashable, and no array in a
    static field)."""
    return tuple(np.asarray(array, dtype=np.float64).tolist())


def _frames(where: str, frames) -> tuple:
    out = [("origin", (0.0, 0.0, 0.0), _floats(np.eye(3)))]
    for key, spec in dict(frames or {}).items():
        if key == "origin":
            raise ModelError(f"{where}: the frame name 'origin' is reserved (the reference point).")
        if isinstance(spec, tuple) and len(spec) == 2 and np.shape(spec[1]) == (3, 3):
            pt, rot = (
                vector(where, f"frames[{key!r}]", spec[0]),
                rotation(where, f"frames[{key!r}] axes", spec[1]),
            )
        else:
            pt, rot = vector(where, f"frames[{key!r}]", spec), np.eye(3)
        out.append((str(key), _floats(pt), _floats(rot)))
    return tuple(out)


__all__ = [
    "COORDS",
    "ORTHONORMALITY",
    "RigidBody",
    "angular_momentum",
    "angular_velocity",
    "axis",
    "directors",
    "orthonormality",
    "point",
]
