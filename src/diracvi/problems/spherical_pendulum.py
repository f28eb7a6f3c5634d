r"""The spherical pendulum in Cartesian coordinates, with its reduced equations in angles.

``q = (x, y, z)``, unit mass on a rod of length ℓ: ``L = ½ |v|² − g z``, holonomic
``|q|² − ℓ² = 0``. In the polar angle θ (from the downward vertical) and the azimuth φ,
``q = ℓ (sin θ cos φ, sin θ sin φ, −cos θ)``, the angular momentum about the vertical
``L_z = ℓ² sin²θ φ̇`` is conserved and the motion reduces to (textbook; Goldstein §3)::

    θ̈ = L_z² cos θ / (ℓ⁴ sin³θ) − (g/ℓ) sin θ,        φ̇ = L_z / (ℓ² sin²θ),

which :func:`reduced_rhs` writes in NumPy for SciPy (no diracvi) — the reference of
``numerical_solution`` and of the work–precision benchmark.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model.system import LagrangeDiracSystem
from ._problem import Problem


def reduced_rhs(length: float, gravity: float, lz: float):
    """``f(t, y)`` of ``y = (θ, θ̇, φ)`` (see the module docstring)."""
    ell2 = length * length

    def rhs(t, y):
        th, thd = y[0], y[1]
        s, c = np.sin(th), np.cos(th)
        return [
            thd,
            lz * lz * c / (ell2 * ell2 * s**3) - (gravity / length) * s,
            lz / (ell2 * s * s),
        ]

    return rhs


def positions(length: float, y) -> np.ndarray:
    """``q = ℓ (sin θ cos φ, sin θ sin φ, −cos θ)`` from reduced states ``y`` (rows or one)."""
    y = np.asarray(y, dtype=np.float64)
    th, ph = y[..., 0], y[..., 2]
    return length * np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), -np.cos(th)], -1)


def spherical_pendulum(
    length: float = 1.0,
    gravity: float = 9.81,
    theta0: float = np.pi / 3,
    azimuth_rate: float = 2.0,
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    r"""The spherical pendulum (``diracvi run spherical-pendulum``): issue 31's long-run case.

    Starts at ``θ₀`` on the ``x``–``z`` plane with ``θ̇₀ = 0`` and ``φ̇₀`` = ``azimuth_rate``;
    ``p₀ = v₀`` (unit mass) is tangent to the sphere. Reference: :func:`reduced_rhs` by
    DOP853 at ``rtol = atol = 1e-12``, mapped by :func:`positions`.
    """
    ell, grav, th0, rate = float(length), float(gravity), float(theta0), float(azimuth_rate)
    system = LagrangeDiracSystem(
        ("x", "y", "z"),
        lambda q, v: 0.5 * v @ v - grav * q[2],
        holonomic=lambda q: jnp.atleast_1d(q @ q - ell**2),
        holonomic_names=("rod",),
        name="spherical_pendulum",
    )
    q0 = positions(ell, [th0, 0.0, 0.0])
    p0 = np.array([0.0, ell * np.sin(th0) * rate, 0.0])
    lz = ell**2 * np.sin(th0) ** 2 * rate
    rhs = reduced_rhs(ell, grav, lz)

    def numerical_solution(t):
        from .linkages import _dop853  # SciPy, imported only for the reference

        return positions(ell, _dop853(rhs, [th0, 0.0, 0.0], 0.0, t))

    return Problem(
        name="spherical-pendulum",
        description="Spherical pendulum in (x, y, z) with the rod |q|² = ℓ² (holonomic)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        numerical_solution=numerical_solution,
        reference="textbook (Goldstein §3); reduced (θ, φ) equations by DOP853",
        parameters={
            "l": ell,
            "g": grav,
            "theta0": th0,
            "azimuth_rate": rate,
            "Lz": lz,
            "reduced_rhs": rhs,
            "reduced_y0": np.array([th0, 0.0, 0.0]),
        },
    )
