r"""Mechanical parts, translational (positions ``x``) and rotational (angles ``θ``).

Each flange is a coordinate; flanges at one mechanical node are joined by
:func:`diracvi.connect` (equal velocities; the multiplier is the force or torque the
joint transmits). The equations are the Euler–Lagrange equations of

    Mass / Inertia          L = ½ m ẋ²                          (flange)
    Spring / TorsionSpring  L = −½ k (x_b − x_a − ℓ₀)²           (flanges a, b)
    Damper / Rot.Damper     F = c (ẋ_b − ẋ_a) (1, −1)            (flanges a, b)
    Fixed                   ẋ = 0                              (flange)
    ForceSource / Torque    F = f(t) on the flange
    Pendulum                L = ½ (J + m ℓ²) θ̇² + m g ℓ cos θ    (flange; θ from the
                            downward vertical)
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._part import ROTATIONAL, TRANSLATIONAL, Part, finite, positive
from .waveforms import as_waveform


def _inertial(kind, value, name, label):
    m = positive(f"{label} {name!r}", "mass" if kind == TRANSLATIONAL else "inertia", value)
    return Part(
        ("x",),
        lambda q, v: 0.5 * m * v[0] ** 2 + 0.0 * q[0],
        name=name,
        flanges=(("flange", "x", kind),),
    )


def _spring(kind, stiffness, rest, name, label):
    k = positive(f"{label} {name!r}", "stiffness", stiffness)
    rest = finite(f"{label} {name!r}", "rest_length", rest)
    return Part(
        ("a", "b"),
        lambda q, v: -0.5 * k * (q[1] - q[0] - rest) ** 2 + 0.0 * v[0],
        name=name,
        flanges=(("a", "a", kind), ("b", "b", kind)),
    )


def _damper(kind, damping, name, label):
    c = positive(f"{label} {name!r}", "damping", damping)

    def force(q, v):
        f = c * (v[1] - v[0])
        return jnp.stack([f, -f])

    return Part(
        ("a", "b"),
        lambda q, v: 0.0 * v[0],
        force=force,
        name=name,
        flanges=(("a", "a", kind), ("b", "b", kind)),
    )


def _source(kind, value, name, label):
    wave = as_waveform(value, f"{label} {name!r}")
    return Part(
        ("x",),
        lambda q, v: 0.0 * v[0],
        force=lambda q, v, t: jnp.atleast_1d(wave(t)) + 0.0 * v,
        name=name,
        flanges=(("flange", "x", kind),),
    )


def Mass(mass, *, name: str) -> Part:
    """A point mass ``L = ½ m ẋ²`` on the translational flange ``flange``."""
    return _inertial(TRANSLATIONAL, mass, name, "Mass")


def Inertia(inertia, *, name: str) -> Part:
    """A rotor ``L = ½ J θ̇²`` on the rotational flange ``flange``."""
    return _inertial(ROTATIONAL, inertia, name, "Inertia")


def Spring(stiffness, rest_length=0.0, *, name: str) -> Part:
    """A linear spring ``L = −½ k (x_b − x_a − ℓ₀)²`` between flanges ``a`` and ``b``."""
    return _spring(TRANSLATIONAL, stiffness, rest_length, name, "Spring")


def TorsionSpring(stiffness, rest_angle=0.0, *, name: str) -> Part:
    """A torsion spring ``L = −½ k (θ_b − θ_a − θ₀)²`` between flanges ``a`` and ``b``."""
    return _spring(ROTATIONAL, stiffness, rest_angle, name, "TorsionSpring")


def Damper(damping, *, name: str) -> Part:
    """A viscous damper ``F = c (ẋ_b − ẋ_a)·(1, −1)`` between ``a`` and ``b`` (removes
    energy at the rate ``c (ẋ_b − ẋ_a)²``)."""
    return _damper(TRANSLATIONAL, damping, name, "Damper")


def RotationalDamper(damping, *, name: str) -> Part:
    """A rotational damper, torque ``c (θ̇_b − θ̇_a)`` on ``a`` and its opposite on ``b``."""
    return _damper(ROTATIONAL, damping, name, "RotationalDamper")


def ForceSource(value, *, name: str) -> Part:
    """A prescribed force ``f(t)`` on the translational flange (number, waveform or ``f(t)``)."""
    return _source(TRANSLATIONAL, value, name, "ForceSource")


def TorqueSource(value, *, name: str) -> Part:
    """A prescribed torque ``τ(t)`` on the rotational flange."""
    return _source(ROTATIONAL, value, name, "TorqueSource")


def Fixed(*, name: str, rotational: bool = False) -> Part:
    """A flange held still: the one-form ``dx`` (``ẋ = 0``); its multiplier is the
    reaction. Its position is the one its mechanical node starts at."""
    kind = ROTATIONAL if rotational else TRANSLATIONAL
    return Part(
        ("x",),
        lambda q, v: 0.0 * v[0],
        constraints=np.array([[1.0]]),
        constraint_names=("fixed",),
        name=name,
        flanges=(("flange", "x", kind),),
    )


def Pendulum(mass, length, gravity=9.81, inertia=0.0, *, name: str) -> Part:
    r"""A rigid pendulum on a rotational flange: ``L = ½ (J + m ℓ²) θ̇² + m g ℓ cos θ``."""
    where = f"Pendulum {name!r}"
    m, ell = positive(where, "mass", mass), positive(where, "length", length)
    g, j = finite(where, "gravity", gravity), finite(where, "inertia", inertia)
    if j < 0.0:
        raise ModelError(f"{where}: inertia={inertia!r} must be ≥ 0.")
    total = j + m * ell**2
    return Part(
        ("x",),
        lambda q, v: 0.5 * total * v[0] ** 2 + m * g * ell * jnp.cos(q[0]),
        name=name,
        flanges=(("flange", "x", ROTATIONAL),),
    )
