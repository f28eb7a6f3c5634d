r"""pn-junction currents as ngspice's level-1 devices compute them, overflow-safe.

``I(V) = I_S (e^{V/(N V_T)} − 1)`` for ``V ≥ −3 N V_T``; below, ngspice's BJT continues
with ``−I_S (1 + (3 N V_T / (e V))³)`` (C¹, tends to ``−I_S``) and its MOSFET bulk
junctions with the constant ``−I_S``. Above ``V = 40 N V_T`` the exponential is continued
by its tangent (C¹) so that a Newton iterate cannot overflow; currents there exceed
``I_S e^{40}`` (2·10¹⁷ ``I_S``), far outside any solution the models are used for.

Shared by the diode (:mod:`~diracvi.components.diode`) and the transistor models
(:mod:`~diracvi.components.bjt`, :mod:`~diracvi.components.mosfet`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

#: kT/q at ngspice's nominal 27 °C (CONSTboltz, CHARGE of ngspice's const.h)
THERMAL_VOLTAGE = 1.38064852e-23 * 300.15 / 1.6021766208e-19

_LIMIT = 40.0
_E = 2.718281828459045


def exp_capped(x):
    """``e^x``, continued by its tangent above ``x = 40``."""
    capped = jnp.minimum(x, _LIMIT)
    return jnp.exp(capped) * (1.0 + (x - capped))


def exp_capped_integral(x):
    """``∫₀^x`` of :func:`exp_capped` (the tangent continuation integrated too)."""
    capped = jnp.minimum(x, _LIMIT)
    over = x - capped
    return jnp.exp(capped) * (1.0 + over + 0.5 * over * over) - 1.0


def pn_current(v, saturation_current, emission=1.0, reverse="cubic"):
    r"""``I_S (e^{V/(N V_T)} − 1)`` with ngspice's reverse branch below ``−3 N V_T``:
    ``reverse="cubic"`` (BJT: ``−I_S (1 + (3 N V_T/(e V))³)``) or ``"constant"``
    (MOSFET bulk junctions: ``−I_S``)."""
    nvt = emission * THERMAL_VOLTAGE
    forward = saturation_current * (exp_capped(v / nvt) - 1.0)
    low = v < -3.0 * nvt
    if reverse == "constant":
        back = -saturation_current + 0.0 * v
    else:
        safe = jnp.where(low, v, -3.0 * nvt)  # no division by 0 on the unused branch
        arg = 3.0 * nvt / (safe * _E)
        back = -saturation_current * (1.0 + arg * arg * arg)
    return jnp.where(low, back, forward)


def depletion_charge(v, cj, vj, m, fc):
    r"""ngspice's depletion charge ``Q(V)`` of a junction (``dQ/dV = C_J (1 − V/V_J)^{−M}``
    below ``FC·V_J``, continued linearly in ``C`` above), ``Q(0) = 0``."""
    a = fc * vj
    below = jnp.minimum(v, a)
    # 1 − (1 − x)^{1−M} as −expm1((1−M) log1p(−x)): no cancellation at small V (the
    # plain form loses eps/x of its value: 10⁻⁶ at V = 10⁻¹⁰, more than Newton may leave)
    q_low = -cj * vj * jnp.expm1((1.0 - m) * jnp.log1p(-below / vj)) / (1.0 - m)
    f2 = (1.0 - fc) ** (1.0 + m)
    f3 = 1.0 - fc * (1.0 + m)
    d = jnp.maximum(v - a, 0.0)
    return q_low + cj / f2 * (f3 * d + m / (2.0 * vj) * d * (d + 2.0 * a))


@jax.custom_jvp
def depletion_coenergy(v, cj, vj, m, fc):
    r"""``C*(V) = ∫₀^V Q(u) du`` of :func:`depletion_charge`: the term of the flux-form
    Lagrangian ``L = w q̇ + C*(ẇ)`` whose momentum ``∂L/∂ẇ = Q(ẇ)`` is the junction
    charge, so that the ``w``-line reads ``q̇ = i_dc + dQ/dt``.

    Its derivative in ``V`` is :func:`depletion_charge` itself (a custom JVP): JAX's
    derivative of the closed form below is ``C_J V_J (1 − (1 − V/V_J)^{1−M})/(1 − M)``,
    whose cancellation at small ``V`` leaves an absolute error ``≈ eps·C_J·V_J`` in the
    charge — far above a first step's charge ``C_J V`` from a zero state, so Newton
    could not converge there (a sine source's first steps, ``V ≈ 10⁻¹⁰``)."""
    return _depletion_coenergy(v, cj, vj, m, fc)


@depletion_coenergy.defjvp
def _depletion_coenergy_jvp(primals, tangents):
    v, cj, vj, m, fc = primals
    dv = tangents[0]
    out = _depletion_coenergy(*primals)
    # the parameters' tangents from the closed form (no cancellation issue there)
    _, dparams = jax.jvp(
        lambda *params: _depletion_coenergy(v, *params), primals[1:], tuple(tangents[1:])
    )
    return out, depletion_charge(v, cj, vj, m, fc) * dv + dparams


def _depletion_coenergy(v, cj, vj, m, fc):
    a = fc * vj
    below = jnp.minimum(v, a)
    grow = jnp.expm1((2.0 - m) * jnp.log1p(-below / vj))  # (1 − V/V_J)^{2−M} − 1
    e_low = cj * vj / (1.0 - m) * (below + vj / (2.0 - m) * grow)
    q_a = cj * vj * (1.0 - (1.0 - fc) ** (1.0 - m)) / (1.0 - m)
    f2 = (1.0 - fc) ** (1.0 + m)
    f3 = 1.0 - fc * (1.0 + m)
    d = jnp.maximum(v - a, 0.0)
    # ∫₀^d [f3 x + m/(2 vj) x (x + 2a)] dx
    upper = q_a * d + cj / f2 * (0.5 * f3 * d * d + m / (2.0 * vj) * (d**3 / 3.0 + a * d * d))
    return e_low + upper


def diffusion_coenergy(v, transit_time, saturation_current, emission=1.0):
    r"""``C*(V) = ∫₀^V τ I_S (e^{u/(N V_T)} − 1) du`` (the exponential continued by its
    tangent above 40, as :func:`exp_capped`): the co-energy of the diffusion charge
    ``τ I(V)``. (ngspice's reverse branch below ``−3 N V_T`` is not reproduced here: the
    charge differs there by less than ``τ I_S``.)"""
    nvt = emission * THERMAL_VOLTAGE
    return transit_time * saturation_current * (nvt * exp_capped_integral(v / nvt) - v)
