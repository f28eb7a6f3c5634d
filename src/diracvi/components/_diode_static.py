r"""ngspice 39's level-1 diode current with its optional terms (``dioload.c``), and the
co-energy of its diffusion charge where no closed form exists.

With ``V_T = kT/q``, ``nV_T = N V_T``, ``I_S`` the area's saturation current (the sidewall's
``JSW·PJ`` added to it when ``NS`` is not given) and ``BV'`` the adjusted breakdown voltage
(:func:`~diracvi.components.diode.breakdown_knee`), the junction current is

    i_b(V) = I_S (e^{V/nV_T} − 1) + I_SR (e^{V/(N_R V_T)} − 1) g(V)   V ≥ −3 nV_T
           = −I_S (1 + (3 nV_T/(e V))³)                                 −BV' ≤ V < −3 nV_T
           = −I_S e^{−(BV' + V)/(N_BV V_T)}                              V < −BV'
    g(V)   = ((1 − V/VJ)² + 0.005)^{M/2}                                (the recombination
                                                                         current's generation
                                                                         factor; only with ISR)
    i_sw(V): the same three branches with ``JSW·PJ``, ``N_S V_T`` (only when NS is given)
    i = i_b + i_sw, then the knees (ngspice's high-injection roll-off, only when given):
    i ← i / (1 + √(i/I_KF))      if V ≥ −3 nV_T and i > 10⁻¹⁸ A
    i ← i / (1 + √(i/(−I_KR)))   if V < −3 nV_T and i < −10⁻¹⁸ A

(``I_SR``, ``I_KF``, ``I_KR`` scaled by the area). ngspice 39 adds the recombination term in
the forward branch only, so the current jumps by ``≈ I_SR g`` at ``V = −3 nV_T``; later
releases (46) carry it into the reverse branches — this is 39's. Every exponential is
continued by its tangent above 40 (:func:`~._junction.exp_capped`).

The diffusion charge is ``TT·i(V)`` (ngspice's ``diffcharge = TT·cd``; without ``G_min``
here, a charge ``TT·G_min·V`` below 10⁻²⁰ C). Its co-energy ``Φ(V) = TT ∫₀^V i(u) du`` has no
closed form once ``g`` or a knee enters, so :func:`diffusion_coenergy` defines
``Φ′ = TT·i`` exactly (a custom JVP: the charge, hence the circuit's equations, are exact)
and evaluates ``Φ`` itself — which only the energy reports — by Gauss–Legendre quadrature
on the pieces between the current's breakpoints (its value is then exact to round-off for
the exponential pieces and to ``≈ 10⁻⁸`` relative near ``V = VJ``, where ``g`` bends).

The sidewall depletion charge (``CJSW·PJ``, ``PHP``, ``MJSW``, ``FCS``) is ngspice's
form with the sidewall's own ``F1 = PHP (1 − (1−FCS)^{1−MJSW})/(1 − MJSW)``
(:func:`~._junction.depletion_coenergy`). ngspice (39 and its newest source) starts the
linear extension above ``FCS·PHP`` from the *bottom* junction's ``F1`` (``dioload.c``:
``czeroSW*here->DIOtF1``), so its charge jumps there by ``CJSW·PJ (F1_bottom −
F1_sidewall)`` — an impulse of current no implicit step can cross when a resistor feeds
the junction (every step failed at the crossing when diracvi reproduced it). diracvi keeps
the continuous charge; above ``FCS·PHP`` it differs from ngspice's by that constant and
has the same capacitance (``tests/test_diode_params.py`` checks both).
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

from ._junction import exp_capped

_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)
_PANELS = 8  # Gauss–Legendre panels per piece (≤ 5 e-folds of e^{V/nV_T} each)
_TINY = 1.0e-18  # ngspice's threshold for the knees (A)


def _branches(v, i_s, nvt, bv, nbv_vt):
    """The three-branch junction current of ``I_S``, ``nV_T`` (``bv`` ``None``: none)."""
    knee = -3.0 * nvt
    forward = i_s * (exp_capped(v / nvt) - 1.0)
    vr = jnp.minimum(v, knee)
    arg = 3.0 * nvt / (math.e * vr)
    out = jnp.where(v >= knee, forward, -i_s * (1.0 + arg * arg * arg))
    if bv is not None:
        brk = -i_s * jnp.exp(-(bv + jnp.minimum(v, -bv)) / nbv_vt)
        out = jnp.where(v < -bv, brk, out)
    return out


def static_current(v, prm, flags):
    """``i(V)`` of the module text (without ``G_min``). ``prm``: ``is nvt bv nbv_vt`` and,
    as ``flags = (sidewall, recombination, ikf, ikr)`` say, ``issw nvtsw``, ``isr nrvt vj
    m``, ``ikf``, ``ikr``; ``bv`` absent: no breakdown."""
    sidewall, recombination, ikf, ikr = flags
    bv = prm.get("bv")
    nvt = prm["nvt"]
    forward = v >= -3.0 * nvt
    i = _branches(v, prm["is"], nvt, bv, prm["nbv_vt"])
    if recombination:
        x = 1.0 - v / prm["vj"]
        g = (x * x + 0.005) ** (0.5 * prm["m"])
        rec = prm["isr"] * (exp_capped(v / prm["nrvt"]) - 1.0) * g
        i = i + jnp.where(forward, rec, 0.0)
    if sidewall:
        i = i + _branches(v, prm["issw"], prm["nvtsw"], bv, prm["nbv_vt"])
    if ikf:
        big = forward & (i > _TINY)
        safe = jnp.where(big, i, 1.0)
        i = jnp.where(big, safe / (1.0 + jnp.sqrt(safe / prm["ikf"])), i)
    if ikr:
        big = ~forward & (i < -_TINY)
        safe = jnp.where(big, i, -1.0)
        i = jnp.where(big, safe / (1.0 + jnp.sqrt(-safe / prm["ikr"])), i)
    return i


def _breakpoints(prm, flags):
    """Voltages where ``i`` or a derivative jumps (region edges, the exponentials' caps)."""
    sidewall, recombination, _, _ = flags
    out = [-3.0 * prm["nvt"], 40.0 * prm["nvt"]]
    if "bv" in prm:
        out.append(-prm["bv"])
    if sidewall:
        out += [-3.0 * prm["nvtsw"], 40.0 * prm["nvtsw"]]
    if recombination:
        out += [40.0 * prm["nrvt"], prm["vj"]]
    return out


def _quadrature(v, prm, flags):
    """``TT ∫₀^V i(u) du`` by Gauss–Legendre on the pieces between the breakpoints."""
    lo, hi = jnp.minimum(v, 0.0), jnp.maximum(v, 0.0)
    cuts = [jnp.clip(jnp.asarray(b, dtype=float), lo, hi) for b in _breakpoints(prm, flags)]
    pts = jnp.sort(jnp.stack([lo, hi, *cuts]))
    a, b = pts[:-1], pts[1:]
    frac = jnp.linspace(0.0, 1.0, _PANELS + 1)[None, :]
    linear = a[:, None] + (b - a)[:, None] * frac
    # a piece away from 0 gets geometric panels: the reverse branch's (3nV_T/(eV))³ falls
    # by 10³ between −3nV_T and −10 nV_T, where uniform panels would lose 10⁻⁶ of it
    same = a * b > 0.0
    ratio = jnp.where(same, b / jnp.where(same, a, 1.0), 1.0)
    geometric = a[:, None] * ratio[:, None] ** frac
    edges = jnp.where(same[:, None], geometric, linear)
    mid = 0.5 * (edges[:, 1:] + edges[:, :-1])
    half = 0.5 * (edges[:, 1:] - edges[:, :-1])
    x = mid[..., None] + half[..., None] * _GL_X
    total = jnp.sum(half[..., None] * _GL_W * static_current(x, prm, flags))
    return prm["tt"] * jnp.where(v >= 0.0, total, -total)


@functools.partial(jax.custom_jvp, nondiff_argnums=(2,))
def diffusion_coenergy(v, prm, flags):
    r"""``Φ(V) = TT ∫₀^V i(u) du`` with ``∂Φ/∂V = TT·i(V)`` exact (see the module text)."""
    return _quadrature(v, prm, flags)


@diffusion_coenergy.defjvp
def _diffusion_coenergy_jvp(flags, primals, tangents):
    v, prm = primals
    dv, dprm = tangents
    # the parameters' tangents through the quadrature (its error is the value's)
    out, dparams = jax.jvp(lambda p: _quadrature(v, p, flags), (prm,), (dprm,))
    return out, prm["tt"] * static_current(v, prm, flags) * dv + dparams
