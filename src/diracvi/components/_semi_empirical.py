r"""Level 3's drain current (the semi-empirical short-channel model, ngspice's ``mos3load``
at the nominal 27 °C) for an NMOS-oriented device in its forward mode (``V_DS ≥ 0``;
voltages times ``type``; source and drain swap for ``V_DS < 0`` in
:mod:`~diracvi.components._mos_part`).

With ``Φ`` = PHI, ``s = √(Φ − V_BS)`` for ``V_BS ≤ 0`` and ``√Φ/(1 + V_BS/(2Φ))`` above,
``φ_s = s²``, ``X_D = √α``, ``α = 2ε_Si/(q NSUB)`` (both 0 without NSUB), ``L``, ``W`` the
effective length and width (``L − 2LD + XL``, ``W − 2WD + XW``):

    F_s = 1 − (X_J/L)((c₀ + c₁ w + c₂ w² + LD/X_J) √(1 − (w/(1+w))²) − LD/X_J),
          w = X_D s/X_J,  (c₀, c₁, c₂) = (0.0631353, 0.8013292, −0.01110777)  (XJ, NSUB;
          else F_s = 1)                                                     (short channel)
    F_n = DELTA·π ε_Si/(2 C'_ox W)                                          (narrow width)
    F_b = γ F_s/(4 s) + F_n,   Q_b = γ F_s s + F_n φ_s                     (body effect)
    σ = ETA · 8.15·10⁻²² F/m/(C'_ox L³)                                     (static feedback)
    V_th = type·VTO − γ√Φ − σ V_DS + Q_b,   von = V_th  [+ V_T x_n with NFS:
    x_n = 1 + q NFS/C'_ox + Q_b/(2φ_s)]

Cut off (``I_D = 0``, ``V_DSAT = 0``) for ``V_GS ≤ von`` without NFS. Otherwise with
``V_x = max(V_GS, von)``, the mobility ``μ_s = U0/(1 + THETA (V_x − V_th))``,

    V_DSAT = (V_x − V_th)/(1 + F_b)                             without VMAX
           = a + V_c − √(a² + V_c²),  a = (V_x − V_th)/(1+F_b),  V_c = VMAX·L/μ_s   (VMAX)
    V_D = min(V_DS, V_DSAT)
    I₀ = KP (W/L) M/(1 + THETA(V_x − V_th)) · (V_x − V_th − (1+F_b) V_D/2) V_D
         · [1/(1 + V_D/V_c) with VMAX]

and the channel shortens by ``ΔL`` (``I_D = I₀/(1 − ΔL/L)``) where ngspice shortens it:

    ΔL = √(κα(V_DS − V_DSAT + V_DSAT/8))                V_DS > V_DSAT, no VMAX
       = √(κα V_DSAT/8) (V_DS/V_DSAT)⁴                  V_DS ≤ V_DSAT, no VMAX, NSUB
       = √(E_p² + κα(V_DS − V_DSAT)) − E_p               V_DS > V_DSAT, VMAX, NSUB
         E_p = ακ I₀/(2 L g_sat),  g_sat = max(I₀ (1 − f_d)/V_c, 10⁻¹² S),
         f_d = 1/(1 + V_D/V_c)
       = 0                                               otherwise,

``ΔL`` becoming ``L − L²/(4ΔL)`` above ``L/2`` (punch-through). Below ``von`` with NFS the
current is this at ``V_x = von`` times ``exp((V_GS − von)/(V_T x_n))``. ``von`` and
``V_DSAT`` are what Meyer's capacitances read, as ``mos3load`` passes them.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

from ._grove_frohman import _side

#: the fit of the depletion-layer corner in ngspice's short-channel factor
_C0, _C1, _C2 = 0.0631353, 0.8013292, -0.01110777


class Level3(NamedTuple):
    """Level 3's law constants (per device; lengths in m, ``u0`` in m²/V·s). The flags are
    ngspice's branches on the card: NFS ≠ 0, VMAX > 0, NSUB given (``α ≠ 0``), and
    ``short``: XJ ≠ 0 with NSUB (the short-channel factor). They are decided when the part
    is built, so that the numbers may be traced or array elements (:func:`law`: the
    part's :class:`~._mos_part.Law`)."""

    vbi: float  # type·(VTO + DELVTO) − γ√Φ
    beta: float  # KP·W·M/L (effective W, L)
    gamma: float
    phi: float
    narrow: float  # F_n = DELTA·π ε_Si/(2 C'ox W)
    sigma: float  # ETA·8.15e-22/(C'ox L³)
    alpha: float  # 2 ε_Si/(q NSUB), 0 without NSUB
    xj: float
    ld: float
    leff: float
    fast_states: float  # q·NFS/C'ox (V)
    theta: float
    kappa: float
    u0: float
    vmax: float
    vt: float  # kT/q at the device's temperature (V)
    has_nfs: bool
    has_vmax: bool
    has_alpha: bool
    short: bool


def _sqrt0(x):
    """``√x`` for ``x ≥ 0`` whose derivative stays finite (0) where ``x ≤ 0``: a branch
    that ``jnp.where`` discards must not put an infinite slope into the gradient."""
    pos = x > 0.0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, x, 1.0)), 0.0)


def _short_channel(p: Level3, s):
    """ngspice's ``fshort``: the share of the depletion charge the gate controls."""
    if not p.short:
        return 1.0 + 0.0 * s
    w = jnp.sqrt(p.alpha) * s / p.xj
    corner = _C0 + _C1 * w + _C2 * w * w + p.ld / p.xj
    c = w / (1.0 + w)
    return 1.0 - p.xj / p.leff * (corner * jnp.sqrt(1.0 - c * c) - p.ld / p.xj)


def _shortening(p: Level3, vds, vdsat, current, vdsx, vdsc):
    """``ΔL`` before the punch-through limit (module docstring)."""
    alpha, kappa = p.alpha, p.kappa
    saturated = vds > vdsat
    safe_sat = jnp.where(vdsat > 0.0, vdsat, 1.0)
    if not p.has_vmax:
        sat = _sqrt0(kappa * alpha * (vds - vdsat + vdsat / 8.0))
        if not p.has_alpha:
            return jnp.where(saturated, sat, 0.0)
        ratio = jnp.minimum(vds / safe_sat, 1.0)
        lin = _sqrt0(kappa * alpha * vdsat / 8.0) * ratio**4
        return jnp.where(saturated, sat, lin)
    if not p.has_alpha:
        return 0.0 * vds
    fdrain = 1.0 / (1.0 + vdsx / vdsc)
    safe_i = jnp.where(current > 0.0, current, 1.0)
    gdsat = jnp.maximum(safe_i * (1.0 - fdrain) / vdsc, 1e-12)
    emax = kappa * safe_i / (p.leff * gdsat)
    arga = 0.5 * emax * alpha
    argb = _sqrt0(arga * arga + kappa * alpha * jnp.maximum(vds - vdsat, 0.0))
    return jnp.where(saturated & (current > 0.0), argb - arga, 0.0)


def level3(p: Level3):
    """Level 3's forward law ``(V_GS, V_DS, V_BS) -> (I_D, von, V_DSAT)`` (module
    docstring); ``V_DSAT`` is 0 where ngspice leaves it so (cut off without NFS)."""
    vt = p.vt

    def forward(vgs, vds, vbs):
        s, _ = _side(p.phi, vbs)
        phibs = s * s
        gammas = p.gamma * _short_channel(p, s)
        fbody = 0.25 * gammas / s + p.narrow
        qb = gammas * s + p.narrow * phibs
        vth = p.vbi - p.sigma * vds + qb
        von = vth
        xn = 1.0
        if p.has_nfs:
            xn = 1.0 + p.fast_states + qb / (2.0 * phibs)
            von = vth + vt * xn
        vgsx = jnp.maximum(vgs, von)
        on = vgsx > vth  # false only when cut off without NFS (then V_GS ≤ von = V_th)
        over = jnp.where(on, vgsx - vth, 1.0)  # a positive stand-in where cut off
        onfg = 1.0 + p.theta * over
        vdsat = over / (1.0 + fbody)
        vdsc = 1.0
        if p.has_vmax:
            vdsc = p.leff * p.vmax / (p.u0 / onfg)
            vdsat = vdsat + vdsc - jnp.sqrt(vdsat * vdsat + vdsc * vdsc)
        vdsx = jnp.minimum(vds, vdsat)
        current = p.beta / onfg * (over - 0.5 * (1.0 + fbody) * vdsx) * vdsx
        if p.has_vmax:
            current = current / (1.0 + vdsx / vdsc)
        delxl = _shortening(p, vds, vdsat, current, vdsx, vdsc)
        half = 0.5 * p.leff
        delxl = jnp.where(
            delxl > half, p.leff - p.leff * p.leff / (4.0 * jnp.maximum(delxl, half)), delxl
        )
        current = current / (1.0 - delxl / p.leff)
        if p.has_nfs:
            current = current * jnp.exp(jnp.minimum(vgs - von, 0.0) / (vt * xn))
        current = jnp.where(on & (vds > 0.0), current, 0.0)
        return current, von, jnp.where(on, vdsat, 0.0)

    return forward


def law(**fields):
    """:func:`level3` of the :class:`Level3` of ``fields``: the maker of the part's
    :class:`~diracvi.components._mos_part.Law` (its numbers and its flags as keywords)."""
    return level3(Level3(**fields))
