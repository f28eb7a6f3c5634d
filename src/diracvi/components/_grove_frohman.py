r"""Level 2's drain current (Grove–Frohman with Baum's velocity saturation, ngspice's
``mos2load`` at the nominal 27 °C) for an NMOS-oriented device in its forward mode
(``V_DS ≥ 0``; voltages times ``type``; source and drain swap for ``V_DS < 0`` in
:mod:`~diracvi.components._mos_part`).

With ``Φ`` = PHI, ``s(v) = √(Φ − v)`` for ``v ≤ 0`` and ``√Φ/(1 + v/(2Φ))`` above:

    s = s(V_BS),  b = s(V_BS − V_DS)                                  (source, drain side)
    F = DELTA·π ε_Si/(4 C'_ox W),  η = 1 + F                          (narrow width)
    V_bin = type·VTO − γ√Φ + F (Φ − V_BS)
    γ_sd = γ (1 − X_J/(2L) (√(1 + 2 X_D s/X_J) − 1 + √(1 + 2 X_D b/X_J) − 1))   (XJ > 0)
    von = V_bin + γ_sd s   [+ V_T x_n with NFS:  x_n = 1 + q NFS/C'_ox + F − ∂(γ_sd s)/∂V_BS]

``X_D = √(2 ε_Si/(q NSUB))`` (0 without NSUB). The mobility factor is
``f_u = (U_c/(V_GS − von))^UEXP`` above ``U_c = UCRIT·ε_Si/C'_ox`` (1 below), the
saturation voltage Grove–Frohman's, with ``γ_d = γ_sd/η``, ``V_x = V_GS`` (``max(V_GS,
von)`` with NFS):

    V_DSAT = (V_x − V_bin)/η + γ_d² (1 − √(1 + 4((V_x − V_bin)/η + Φ − V_BS)/γ_d²))/2  (≥ 0)

or, with VMAX, the smallest positive root ``x`` of Baum's quartic
``x⁴ + ⁴⁄₃γ_d x³ − 2(v₁+ξ) x² − 2γ_d ξ x + 2v₁(v₂+ξ) − v₂² − ⁴⁄₃γ_d s³ = 0``
(``v₁ = (V_x − V_bin)/η + Φ − V_BS``, ``v₂ = Φ − V_BS``, ``ξ = VMAX·L/μ_eff``,
``μ_eff = U0·f_u``) as ``V_DSAT = x² − v₂``, the root ngspice finds (:mod:`._quartic`).
The channel shortens by ``ΔL/L = λ V_DS`` with LAMBDA, or (NSUB given, LAMBDA not > 0) by

    ΔL/L = X_D/L · √(a + √(1 + a²)),  a = (V_DS − V_DSAT)/4              (no VMAX)
    ΔL/L = X_D'/L · (√(ξ_L² + max(V_DS − V_DSAT, 0)) − ξ_L),
           X_D' = X_D/√NEFF,  ξ_L = VMAX X_D'/(2 μ_eff)                   (VMAX)

limited at punch-through (``L(1 − ΔL/L) < X_W = X_D√PB``, or 0.25 µm without NSUB:
``L_eff = X_W/(1 + (ΔL − (L − X_D√PB))/X_W)``). With ``β₁ = KP (W/L) f_u/(1 − ΔL/L)``
and ``B(v) = s(V_BS − v)³ − s³`` (the 2/3-power bulk charge):

    I_D = β₁ ((V_GS − V_bin − η V_DS/2) V_DS − γ_sd B(V_DS)/1.5)       V_DS ≤ V_DSAT
        = β₁ ((V_GS − V_bin − η V_DSAT/2) V_DSAT − γ_sd B(V_DSAT)/1.5)  V_DS > V_DSAT

where ``V_GS > von`` (NFS) or ``V_GS > V_bin`` (no NFS); below ``von`` with NFS it is the
same expression at ``V_GS = von``, ``V_D = min(V_DS, V_DSAT)``, times
``exp((V_GS − von)/(V_T x_n))``; 0 otherwise and for ``V_DS ≤ 10⁻¹⁰`` V.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from ._quartic import baum_root


class Level2(NamedTuple):
    """Level 2's law constants (per device; lengths in m, ``u0`` in m²/V·s). The flags
    are ngspice's branches on the card: NFS ≠ 0, VMAX > 0, NSUB given, XJ > 0, and
    ``lambda_set`` LAMBDA > 0 (``None``: a traced LAMBDA, which decides in the program).
    They are decided when the part is built, so that the numbers may be traced or array
    elements (:func:`law`: the part's :class:`~._mos_part.Law`)."""

    vbi: float  # type·VTO − γ√Φ
    beta: float  # KP·W·M/L_eff
    gamma: float
    phi: float
    factor: float  # DELTA·π ε_Si/(4 C'ox W)
    xd: float  # √(2 ε_Si/(q NSUB)), 0 without NSUB
    xj: float
    leff: float
    lambda_: float
    fast_states: float  # q·NFS/C'ox (V)
    ucrit: float  # UCRIT·ε_Si/C'ox (V)
    uexp: float
    u0: float
    vmax: float
    neff: float
    pb: float
    vt: float  # kT/q at the device's temperature (V)
    has_nfs: bool
    has_vmax: bool
    has_nsub: bool
    has_xj: bool
    lambda_set: bool | None


def _side(phi, v):
    """``(s(v), ds/dv)``: ``√(Φ − v)`` for ``v ≤ 0``, ``√Φ/(1 + v/(2Φ))`` above."""
    below = jnp.sqrt(phi - jnp.minimum(v, 0.0))
    above = jnp.sqrt(phi) / (1.0 + 0.5 * jnp.maximum(v, 0.0) / phi)
    s = jnp.where(v <= 0.0, below, above)
    return s, jnp.where(v <= 0.0, -0.5 / below, -0.5 * above * above / (phi * jnp.sqrt(phi)))


def _short_channel_gamma(p: Level2, s, ds, b, db):
    """``γ_sd`` and ``∂γ_sd/∂V_BS`` (junction depth XJ sharing the depletion charge)."""
    if not p.has_xj:
        return p.gamma + 0.0 * s, 0.0 * s
    arg_s = jnp.sqrt(1.0 + 2.0 * p.xd * s / p.xj)
    arg_d = jnp.sqrt(1.0 + 2.0 * p.xd * b / p.xj)
    gamma_sd = p.gamma * (1.0 - 0.5 * p.xj / p.leff * (arg_s - 1.0 + arg_d - 1.0))
    dgamma = -p.gamma * 0.5 * p.xd / p.leff * (ds / arg_s + db / arg_d)
    return gamma_sd, dgamma


def _grove_frohman_vdsat(over, v2, gammad):
    """Grove–Frohman's ``V_DSAT`` from ``over = (V_x − V_bin)/η`` and ``v2 = Φ − V_BS``."""
    argv = over + v2
    positive = gammad > 0.0
    g2 = jnp.where(positive, gammad * gammad, 1.0)
    root = jnp.sqrt(1.0 + 4.0 * jnp.maximum(argv, 0.0) / g2)
    with_body = jnp.where(argv <= 0.0, 0.0, jnp.maximum(over + g2 * (1.0 - root) / 2.0, 0.0))
    return jnp.where(positive, with_body, jnp.maximum(over, 0.0))


def _baum_vdsat(p: Level2, over, v2, gammad, s, ueff, fallback):
    """Baum's velocity-saturated ``V_DSAT`` (module docstring), ``fallback`` where the
    quartic has no positive root."""
    v1 = over + v2
    xv = p.vmax * p.leff / ueff
    a1 = gammad / 0.75
    b1 = -2.0 * (v1 + xv)
    c1 = -2.0 * gammad * xv
    d1 = 2.0 * v1 * (v2 + xv) - v2 * v2 - 4.0 / 3.0 * gammad * s * s * s
    x, found = baum_root(a1, b1, c1, d1)
    return jnp.where(found, x * x - v2, fallback)


def _shortening(p: Level2, vds, vdsat, ueff):
    """``ΔL/L``, the channel shortening ``λ V_DS`` (module docstring)."""
    computed = p.has_nsub and p.lambda_set is not True
    given = p.lambda_ * vds
    if not computed:
        return given
    if not p.has_vmax:
        a = (vds - vdsat) / 4.0
        out = p.xd / p.leff * jnp.sqrt(a + jnp.sqrt(1.0 + a * a))
    else:
        xdv = p.xd / jnp.sqrt(p.neff)
        xlv = p.vmax * xdv / (2.0 * ueff)
        out = xdv / p.leff * (jnp.sqrt(xlv * xlv + jnp.maximum(vds - vdsat, 0.0)) - xlv)
    if p.lambda_set is not None:
        return out
    return jnp.where(p.lambda_ > 0.0, given, out)  # a traced LAMBDA decides as ngspice


def _length_factor(p: Level2, shortening):
    """``1 − ΔL/L``, limited at punch-through as ``mos2load``."""
    xwb = p.xd * jnp.sqrt(p.pb)
    xld = p.leff - xwb
    if not p.has_nsub:
        xwb = 0.25e-6
    clfact = 1.0 - shortening
    punched = p.leff * clfact < xwb
    limited = xwb / (1.0 + (shortening * p.leff - xld) / xwb) / p.leff
    return jnp.where(punched, limited, clfact)


def level2(p: Level2):
    """Level 2's forward law ``(V_GS, V_DS, V_BS) -> (I_D, von, V_DSAT)`` (module
    docstring); ``V_DSAT`` is 0 where ngspice leaves it so (cut off without NFS)."""
    vt = p.vt
    eta = 1.0 + p.factor

    def forward(vgs, vds, vbs):
        v2 = p.phi - vbs
        s, ds = _side(p.phi, vbs)
        b, db = _side(p.phi, vbs - vds)
        vbin = p.vbi + p.factor * v2
        gamma_sd, dgamma = _short_channel_gamma(p, s, ds, b, db)
        von = vbin + gamma_sd * s
        xn = 1.0
        if p.has_nfs:
            xn = 1.0 + p.fast_states + p.factor - (gamma_sd * ds + dgamma * s)
            von = von + vt * xn
            vgsx = jnp.maximum(vgs, von)
        else:
            vgsx = vgs
        # mobility: (U_c/V_GST)^UEXP above U_c — continuous, so no branch
        ufact = jnp.exp(p.uexp * jnp.log(p.ucrit / jnp.maximum(vgs - von, p.ucrit)))
        ueff = p.u0 * ufact
        gammad = gamma_sd / eta
        over = (vgsx - vbin) / eta
        vdsat = _grove_frohman_vdsat(over, v2, gammad)
        if p.has_vmax:
            vdsat = _baum_vdsat(p, over, v2, gammad, s, ueff, vdsat)
        bs, _ = _side(p.phi, vbs - vdsat)
        sarg3 = s * s * s
        body, bodys = b * b * b - sarg3, bs * bs * bs - sarg3
        beta1 = p.beta * ufact / _length_factor(p, _shortening(p, vds, vdsat, ueff))

        def charge(vg, vd, bulk):  # β₁((V_G − V_bin − η V_D/2) V_D − γ_sd B/1.5)
            return beta1 * ((vg - vbin - 0.5 * eta * vd) * vd - gamma_sd * bulk / 1.5)

        linear = vds <= vdsat
        strong = jnp.where(linear, charge(vgs, vds, body), charge(vgs, vdsat, bodys))
        if p.has_nfs:
            vdson = jnp.minimum(vdsat, vds)
            below = charge(von, vdson, jnp.where(linear, body, bodys))
            weak = jnp.where(vdsat <= 0.0, 0.0, below * jnp.exp((vgs - von) / (vt * xn)))
            current = jnp.where(vgs > von, strong, weak)
        else:
            current = jnp.where(vgs > vbin, strong, 0.0)
            vdsat = jnp.where(vgs > vbin, vdsat, 0.0)  # mos2load's cutoff skips it
        current = jnp.where(vds <= 1e-10, 0.0, current)
        return current, von, vdsat

    return forward


def law(**fields):
    """:func:`level2` of the :class:`Level2` of ``fields``: the maker of the part's
    :class:`~diracvi.components._mos_part.Law` (its numbers and its flags as keywords)."""
    return level2(Level2(**fields))
