r"""The positive root of Baum's quartic as ngspice's ``mos2load`` finds it, traceable by
JAX: level 2's velocity-saturated ``V_DSAT`` (:mod:`~diracvi.components._grove_frohman`).

``p(x) = x⁴ + a x³ + b x² + c x + d`` is written as a difference of squares (Ferrari),

    p(x) = (x² + a x/2 + y/2)² − (A x + B)²,   A² = a²/4 − b + y,   B² = y²/4 − d,

which holds when ``y`` is a root of the resolvent cubic
``y³ − b y² + (ac − 4d) y + (4bd − a²d − c²) = 0``; the candidate roots are those of
``x² + (a/2 ± A) x + y/2 ± B`` for the four sign pairs (the right pairing is among them),
and a candidate counts when it is real, positive and ``|p(x)| ≤ 10⁻⁶``. The smallest one
that counts is the answer; when none does, ngspice keeps Grove–Frohman's ``V_DSAT``.

**ngspice's resolvent root.** With the cubic depressed to ``t³ + r t + s = 0`` and
``D = s²/4 + r³/27``, ngspice takes ``y = 2 ρ cos(φ/3) − A/3`` with ``ρ = (s²/4 − D)^{1/6}``,
``φ = atan(−2√−D/s)`` when ``D < 0``, and ``y = |−s/2 + √D|^{1/3} + |−s/2 − √D|^{1/3} − A/3``
when ``D ≥ 0``. Both are roots of the cubic only for ``s < 0`` (``atan`` folds the angle
of ``s > 0`` by π; the moduli drop the cube roots' signs); otherwise the candidates are
not roots, fail the residual test, and ``V_DSAT`` stays Grove–Frohman's. This happens,
for instance, when a forward-biased bulk puts ``V_BS`` above ``Φ``; diracvi makes the
same choice so that its currents are ngspice's there too. A NaN candidate (a negative
``A²`` or ``B²``) does not count.

The value is ngspice's candidate itself; its derivative is the implicit function's,
``−(∂p/∂θ)/p′(x)``, carried by a zero-valued Newton correction.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

TOLERANCE = 1e-6
#: the signs of A, of B and of the quadratic's root for the eight candidates
_SIGNS = (
    np.array([1.0, 1.0, -1.0, -1.0, 1.0, 1.0, -1.0, -1.0]),
    np.array([1.0, 1.0, 1.0, 1.0, -1.0, -1.0, -1.0, -1.0]),
    np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0]),
)


def _poly(x, a, b, c, d):
    return (((x + a) * x + b) * x + c) * x + d


def _dpoly(x, a, b, c):
    return ((4.0 * x + 3.0 * a) * x + 2.0 * b) * x + c


def _sqrt(x):
    """``√x``, NaN for ``x < 0`` (as C's), with no NaN derivative leaking elsewhere."""
    return jnp.where(x >= 0.0, jnp.sqrt(jnp.maximum(x, 0.0)), jnp.nan)


def _resolvent_root(a, b, c, d):
    """ngspice's root ``y`` of the resolvent cubic (module docstring)."""
    ca, cb, cc = -b, a * c - 4.0 * d, -d * (a * a - 4.0 * b) - c * c
    r = cb - ca * ca / 3.0
    s = 2.0 * ca**3 / 27.0 - ca * cb / 3.0 + cc
    disc = s * s / 4.0 + r**3 / 27.0
    root = jnp.sqrt(jnp.abs(disc))
    rho = jnp.exp(jnp.log(jnp.sqrt(s * s / 4.0 + jnp.abs(disc))) / 3.0)
    angle = jnp.arctan(-2.0 * root / s)  # s = 0: ±inf, as C's atan(−inf) = −π/2
    trig = 2.0 * rho * jnp.cos(angle / 3.0)
    cardano = jnp.cbrt(jnp.abs(-s / 2.0 + root)) + jnp.cbrt(jnp.abs(-s / 2.0 - root))
    return jnp.where(disc < 0.0, trig, cardano) - ca / 3.0


def baum_root(a, b, c, d):
    """``(x, found)``: the smallest positive candidate root of ``x⁴ + a x³ + b x² + c x + d``
    that passes ngspice's test (module docstring), and whether there is one (``x`` is 1
    where not). Arguments may be traced arrays of one shape."""
    args = [jnp.asarray(z, dtype=jnp.float64) for z in (a, b, c, d)]
    frozen = [jax.lax.stop_gradient(z) for z in args]
    y = _resolvent_root(*frozen)
    fa, fb, fc, fd = (z[..., None] for z in frozen)  # the candidates on a last axis
    y = y[..., None]
    big, small = _sqrt(fa * fa / 4.0 - fb + y), _sqrt(y * y / 4.0 - fd)
    lin = fa / 2.0 + _SIGNS[0] * big  # the eight (A, B, ±) sign choices at once
    const = y / 2.0 + _SIGNS[1] * small
    disc = lin * lin / 4.0 - const
    x = -lin / 2.0 + _SIGNS[2] * jnp.sqrt(jnp.maximum(disc, 0.0))
    ok = (disc >= 0.0) & (x > 0.0) & (jnp.abs(_poly(x, fa, fb, fc, fd)) <= TOLERANCE)
    ok = ok & jnp.isfinite(x)
    found = jnp.any(ok, axis=-1)
    x = jnp.where(found, jnp.min(jnp.where(ok, x, jnp.inf), axis=-1), 1.0)
    slope = _dpoly(x, *args[:3])
    flat = jnp.abs(slope) < 1e-300
    step = -jnp.where(flat, 0.0, _poly(x, *args) / jnp.where(flat, 1.0, slope))
    return x + (step - jax.lax.stop_gradient(step)), found
