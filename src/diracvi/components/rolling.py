r"""Rolling without slipping of a disk or a ball on a plane: a nonholonomic joint.

A body frame ``a`` marks the centre ``r_a`` and, for a disk, the disk's axis ``â = e₃``
(world axes ``E_a = R A``); the plane is a world frame ``b``: a point ``r_b`` on it and its
normal ``n = f₃``. The contact point lies at ``r_a + s`` below the centre,

    disk of radius ρ:   s = −ρ u/|u|,  u = n − (n·â) â     (the rim's lowest point)
    ball of radius ρ:   s = −ρ n,

and the contact conditions are

    holonomic (touching):    n·(r_a − r_b) − ρ |u| = 0   (ball: n·(r_a − r_b) − ρ = 0)
    upright disk (optional): n·â = 0
    rolling (nonholonomic):  fᵢ·(ẋ + Σⱼ Xⱼ ḋⱼ) = 0,  i = 1, 2,   X = Rᵀ(r_a + s − x)

— the velocity of the *material* point at the contact (body coordinates ``X``, frozen at
``q``) has no component in the plane. Those two rows are one-forms ``A(q) v = 0`` on the
body's director coordinates: a row ``(fᵢ, X₁ fᵢ, X₂ fᵢ, X₃ fᵢ)``. Their normal
component is the time derivative of the touching row (the contact point is the lowest
point of the rim), so it is not repeated. The reaction forces do no work: the energy of
a rolling body is conserved (to the scheme's order: the rolling rows hold at the
midpoint, not exactly along the step). ``|u| = √(1 − (n·â)²)`` vanishes when the disk
lies flat: the contact point is then undefined, and the model holds for a disk that is
not flat.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..errors import ModelError

SHAPES = ("disk", "ball")


def contact_offset(shape: str, radius: float, ea, eb):
    """``s``: the world vector from the centre to the contact point."""
    n = eb[:, 2]
    if shape == "ball":
        return -radius * n
    a = ea[:, 2]
    u = n - (n @ a) * a
    return -radius * u / jnp.sqrt(u @ u)


def contact_rows(shape: str, radius: float, upright: bool):
    """``rows(r_a, E_a, r_b, E_b)``: the holonomic rows (touching; upright) and their names."""

    def rows(ra, ea, rb, eb):
        n = eb[:, 2]
        height = n @ (ra - rb)
        if shape == "ball":
            return jnp.atleast_1d(height - radius)
        tilt = n @ ea[:, 2]
        touch = height - radius * jnp.sqrt(1.0 - tilt**2)
        return jnp.stack([touch, tilt]) if upright else jnp.atleast_1d(touch)

    names = ("touch", "upright") if upright else ("touch",)
    return rows, names


def rolling_forms(shape: str, radius: float, point, axes, q, eb):
    r"""The two rolling one-forms (2, 12) on a body's ``q = (x, d₁, d₂, d₃)``: rows
    ``(fᵢ, X₁ fᵢ, X₂ fᵢ, X₃ fᵢ)`` with ``X`` the contact point in body coordinates."""
    rot = q[3:12].reshape(3, 3).T
    ea = rot @ jnp.asarray(axes)
    offset = contact_offset(shape, radius, ea, eb)
    local = jnp.asarray(point) + rot.T @ offset  # X = frame point + Rᵀ s
    tangents = eb[:, 0:2].T  # (2, 3)
    lever = jnp.concatenate([jnp.ones(1), local])  # (1, X₁, X₂, X₃)
    return (lever[None, :, None] * tangents[:, None, :]).reshape(2, 12)


def check_contact(where: str, shape: str, radius, upright: bool) -> float:
    """The contact's parameters, or a :class:`ModelError` naming the bad one."""
    if shape not in SHAPES:
        raise ModelError(f"{where}: shape={shape!r} is not one of {SHAPES}.")
    try:
        rho = float(radius)
    except (TypeError, ValueError):
        rho = float("nan")
    if not rho > 0.0 or rho == float("inf"):
        raise ModelError(f"{where}: radius={radius!r} must be a finite number > 0.")
    if upright and shape != "disk":
        raise ModelError(f"{where}: upright=True is for a disk (a ball has no axis).")
    return rho


__all__ = ["SHAPES", "check_contact", "contact_offset", "contact_rows", "rolling_forms"]
