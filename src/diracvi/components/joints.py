r"""Joints between two frames as holonomic constraints, polynomial in the directors.

A frame ``F`` on a body is a point ``X`` and three orthonormal axes ``A = [a₁ a₂ a₃]``
(body coordinates); in the world it is at ``r = x + R X`` with axes ``E = R A`` — both
*linear* in the body's ``q = (x, d₁, d₂, d₃)``. A world frame is a constant ``(r, E)``.
With ``Δ = r_b − r_a`` and ``eᵢ``, ``fᵢ`` the axes of frames a and b, the joints are

    spherical     Δ = 0                                               3 rows
    revolute      Δ = 0,  e₃·f₁ = e₃·f₂ = 0       (turns about e₃ = f₃)  5 rows
    universal     Δ = 0,  e₁·f₂ = 0               (about e₁ and f₂)     4 rows
    cylindrical   e₃·f₁ = e₃·f₂ = 0,  Δ·e₁ = Δ·e₂ = 0  (along/about e₃)  4 rows
    prismatic     cylindrical and e₁·f₂ = 0       (slides along e₃)     5 rows
    fixed         Δ = 0,  e₃·f₁ = e₃·f₂ = e₁·f₂ = 0                      6 rows

each row a polynomial of degree ≤ 2 in the coordinates, exact at every step end. The
axis rows fix the relative rotation near the frames' initial alignment (they also vanish
at a few isolated turned-over configurations, far from a continuous motion's reach).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError


def _delta(ra, rb):
    return rb - ra


def spherical(ra, ea, rb, eb):
    """``r_b − r_a`` (3)."""
    return _delta(ra, rb)


def revolute(ra, ea, rb, eb):
    """``r_b − r_a``, ``e₃·f₁``, ``e₃·f₂`` (5): rotation about the common third axis."""
    return jnp.concatenate([_delta(ra, rb), jnp.stack([ea[:, 2] @ eb[:, 0], ea[:, 2] @ eb[:, 1]])])


def universal(ra, ea, rb, eb):
    """``r_b − r_a``, ``e₁·f₂`` (4): rotation about a's first and b's second axis."""
    return jnp.concatenate([_delta(ra, rb), jnp.atleast_1d(ea[:, 0] @ eb[:, 1])])


def cylindrical(ra, ea, rb, eb):
    """``e₃·f₁``, ``e₃·f₂``, ``Δ·e₁``, ``Δ·e₂`` (4): slides along and turns about e₃."""
    d = _delta(ra, rb)
    return jnp.stack([ea[:, 2] @ eb[:, 0], ea[:, 2] @ eb[:, 1], d @ ea[:, 0], d @ ea[:, 1]])


def prismatic(ra, ea, rb, eb):
    """The cylindrical rows and ``e₁·f₂`` (5): slides along e₃ without turning."""
    return jnp.concatenate([cylindrical(ra, ea, rb, eb), jnp.atleast_1d(ea[:, 0] @ eb[:, 1])])


def fixed(ra, ea, rb, eb):
    """``r_b − r_a``, ``e₃·f₁``, ``e₃·f₂``, ``e₁·f₂`` (6): no relative motion."""
    return jnp.concatenate(
        [_delta(ra, rb), jnp.stack([ea[:, 2] @ eb[:, 0], ea[:, 2] @ eb[:, 1], ea[:, 0] @ eb[:, 1]])]
    )


#: joint kind → (row function, row names)
JOINTS = {
    "spherical": (spherical, ("dx", "dy", "dz")),
    "revolute": (revolute, ("dx", "dy", "dz", "e3.f1", "e3.f2")),
    "universal": (universal, ("dx", "dy", "dz", "e1.f2")),
    "cylindrical": (cylindrical, ("e3.f1", "e3.f2", "d.e1", "d.e2")),
    "prismatic": (prismatic, ("e3.f1", "e3.f2", "d.e1", "d.e2", "e1.f2")),
    "fixed": (fixed, ("dx", "dy", "dz", "e3.f1", "e3.f2", "e1.f2")),
}


def revolute_angle(ea, eb):
    r"""The turn ``θ`` of frame b about the common axis ``e₃ = f₃`` of a revolute joint:
    ``f₁ = cos θ e₁ + sin θ e₂``, so ``θ = atan2(e₂·f₁, e₁·f₁)`` — from the two frames'
    world axes (…, 3, 3) alone (the URDF joint angle, in (−π, π]; unwrap a time series)."""
    ea, eb = np.asarray(ea), np.asarray(eb)
    f1 = eb[..., :, 0]
    return np.arctan2(np.sum(ea[..., :, 1] * f1, -1), np.sum(ea[..., :, 0] * f1, -1))


def slide(ra, ea, rb):
    """The slide ``(r_b − r_a)·e₃`` of a prismatic or cylindrical joint (…,)."""
    return np.sum((np.asarray(rb) - np.asarray(ra)) * np.asarray(ea)[..., :, 2], -1)


def joint_rows(kind: str):
    """``(rows(r_a, E_a, r_b, E_b), names)`` of the joint ``kind``, or a clear error."""
    try:
        return JOINTS[kind]
    except KeyError:
        raise ModelError(
            f"joint kind={kind!r} is unknown; the joints are {sorted(JOINTS)}."
        ) from None


__all__ = [
    "JOINTS",
    "cylindrical",
    "fixed",
    "joint_rows",
    "prismatic",
    "revolute",
    "revolute_angle",
    "slide",
    "spherical",
    "universal",
]
