r"""ngspice's VDMOS (vertical power MOSFET, SPICE ``M`` with a ``VDMOS`` card): its channel
and its nonlinear gate–drain capacitance as Lagrange–Dirac parts.

**Channel** (ngspice's ``vdmosload`` at the nominal temperature; voltages multiplied by
``type`` = +1 for ``NCHAN``, −1 for ``PCHAN``; source and drain swap roles for
``V_DS < 0`` as in level 1). The overdrive is a softplus of ``V_GS − VTO`` (ngspice's weak
inversion, slope ``KSUBTHRES``, offset ``SUBSHIFT``), then level 1's square law with
``β = KP`` (no W/L: a VDMOS card describes a whole device):

    V_ov = K ln(1 + exp((V_GS − VTO − SUBSHIFT)/K)),   K = KSUBTHRES
    I_D  = β′ V_ov²/2                 V_ov ≤ V_m   (saturation)
         = β′ V_m (V_ov − V_m/2)       otherwise    (linear),   V_m = MTRIODE·V_DS
    β′   = KP (1 + LAMBDA·v_ds) / (1 + THETA·v_gs)

where ``V_GS``, ``V_DS`` are the oriented ones (``V_GD``, ``−V_DS`` in the inverse mode)
but ngspice's channel-length modulation and mobility degradation read the device's own
``v_ds``, ``v_gs`` in either mode (``t0 = 1 + lambda*vds``, ``t1 = 1 + theta*vgs``), so
``β′`` is not symmetric under the swap: the law recovers them from the oriented triple,
since the bulk is tied to the source (``V_BS = 0``, and the inverse mode's ``V_BD`` is
``−V_DS``): ``v_ds = V_DS − 2 V_B``, ``v_gs = V_GS − V_B``.

The body has no terminal (the bulk pin of the shared part is tied to the source) and no
body effect. :func:`VDMOS` builds this on the shared MOSFET part
(:func:`~diracvi.components._mos_part.build`) with its constant ``CGS`` as the gate–source
overlap capacitor and ``RD``/``RS`` as its series resistances.

**Gate–drain capacitance** (ngspice's ``DevCapVDMOS``, after LTspice): with
``s = (C_max − C_min)/(1 + π/2)`` and ``y = C_max − s``,

    C_GD(V) = s tanh(a V) + y   (V > 0),     s atan(a V) + y   (V ≤ 0),    V = type·V_GD

rising from ``C_min`` (``V → −∞``) to ``C_max`` (``V → +∞``), C¹ at 0. It enters through a
charge port (:class:`~diracvi.components._charge_port.ChargePortPart`) on a gate–drain
branch in flux form (``L = w q̇``): its charge

    Q(V) = ∫₀^V C = y V + (s/a) ln cosh(a V)                     (V > 0)
                  = y V + s (V atan(a V) − ln(1 + a²V²)/(2a))    (V ≤ 0)

is a function of ``ẇ = V_GD`` alone, so the port's current ``dQ/dt`` is ngspice's
``C_GD(V) dV/dt`` (ngspice integrates the trapezoidal mean of ``C`` over a step, which
agrees to the step's second order).
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..errors import ModelError
from ._charge_port import ChargePortPart
from ._mos_part import KINDS, build, channel_current, device, law, polarity
from ._part import finite, positive

__all__ = ["VDMOS", "GateDrainCapacitance", "gate_drain_capacitance", "gate_drain_charge"]


def _shape(cgdmin, cgdmax):
    s = (cgdmax - cgdmin) / (1.0 + 0.5 * math.pi)
    return s, cgdmax - s


def gate_drain_capacitance(v, cgdmin, cgdmax, a):
    """``C_GD(V)`` of the module docstring (``V = type·V_GD``)."""
    s, y = _shape(cgdmin, cgdmax)
    return jnp.where(v > 0.0, s * jnp.tanh(a * v) + y, s * jnp.arctan(a * v) + y)


def _log_cosh(x):
    # ln cosh x = |x| + ln(1 + e^{−2|x|}) − ln 2, finite for any x
    ax = jnp.abs(x)
    return ax + jnp.log1p(jnp.exp(-2.0 * ax)) - math.log(2.0)


def gate_drain_charge(v, cgdmin, cgdmax, a):
    """``Q(V) = ∫₀^V C_GD`` of the module docstring: the charge whose derivative is
    :func:`gate_drain_capacitance`."""
    s, y = _shape(cgdmin, cgdmax)
    above = s * _log_cosh(a * v) / a
    below = s * (v * jnp.arctan(a * v) - jnp.log1p((a * v) ** 2) / (2.0 * a))
    return y * v + jnp.where(v > 0.0, above, below)


def GateDrainCapacitance(kind, cgdmin, cgdmax, a, *, name: str, v0=0.0) -> ChargePortPart:
    r"""The VDMOS gate–drain capacitance from pin ``p`` (gate) to pin ``n`` (drain): a
    branch ``(q, w)`` with ``L = w q̇`` and the charge port ``Q = type·Q(type·ẇ)`` on the
    ``w``-line (module docstring), so that the branch current is ``dQ/dt``. ``v0`` is the
    initial ``V_GD``."""
    where = f"VDMOS gate–drain capacitance {name!r}"
    sign = polarity(where, kind)
    cmin, cmax = finite(where, "cgdmin", cgdmin), finite(where, "cgdmax", cgdmax)
    a = positive(where, "a", a)
    if cmin < 0.0 or cmax < cmin:
        raise ModelError(f"{where}: need 0 ≤ cgdmin ≤ cgdmax (got {cmin:g}, {cmax:g}).")

    def lagrangian(q, v):
        return q[1] * v[0]

    def charge(q, v):
        return jnp.stack([0.0 * v[0], sign * gate_drain_charge(sign * v[1], cmin, cmax, a)])

    return ChargePortPart(
        ("q", "w"),
        lagrangian,
        name=name,
        pins=(("p", "q", 1), ("n", "q", -1)),
        initial_v=[0.0, finite(where, "v0", v0)],
        role="capacitor",
        charge=charge,
        parameters={"cgdmin": cmin, "cgdmax": cmax, "a": a},
    )


def vdmos_law(vto, kp, ksubthres, subshift, lambda_=0.0, theta=0.0, mtriode=1.0):
    """The channel's forward law ``(V_GS, V_DS, V_B) -> (I_D, von, vdsat)`` of the module
    docstring (NMOS-oriented, ``V_DS ≥ 0``; ``vto`` is ``type·VTO``; ``V_B`` the oriented
    bulk voltage, 0 forward and ``V_BD`` inverse, read only to undo the orientation for
    ``LAMBDA`` and ``THETA``)."""

    def forward(vgs, vds, vbs):
        # softplus written as K·logaddexp(0, x): no overflow for large overdrives
        vov = ksubthres * jnp.logaddexp(0.0, (vgs - vto - subshift) / ksubthres)
        # ngspice's β′ at the device's own v_ds, v_gs (module docstring)
        beta = kp * (1.0 + lambda_ * (vds - 2.0 * vbs)) / (1.0 + theta * (vgs - vbs))
        saturation = 0.5 * beta * vov * vov
        vm = mtriode * vds  # ngspice's vdss: the triode region's V_DS scaled by MTRIODE
        linear = beta * vm * (vov - 0.5 * vm)
        i = jnp.where(vov <= vm, saturation, linear)
        return i, vto + 0.0 * vgs, jnp.maximum(vgs - vto, 0.0)

    return forward


def drain_current(
    vgs,
    vds,
    *,
    kind,
    vto=0.0,
    kp=1.0,
    ksubthres=0.1,
    subshift=0.0,
    lambda_=0.0,
    theta=0.0,
    mtriode=1.0,
):
    """The channel current into the drain for true (signed) ``V_GS``, ``V_DS``."""
    sign = KINDS[kind]
    law = vdmos_law(sign * vto, kp, ksubthres, subshift, lambda_, theta, mtriode)
    return channel_current(vgs, vds, 0.0 * vgs, sign, law)


def VDMOS(
    kind="nmos",
    vto=0.0,
    kp=1.0,
    *,
    ksubthres=0.1,
    subshift=0.0,
    lambda_=0.0,
    theta=0.0,
    mtriode=1.0,
    cgs=0.0,
    rd=0.0,
    rs=0.0,
    gmin=1e-12,
    v0=(0.0, 0.0),
    name: str,
):
    r"""The VDMOS channel with pins ``d g s b`` (``b`` to be tied to ``s``): the law of the
    module docstring (ngspice's defaults ``VTO = 0``, ``KP = 1`` A/V², ``KSUBTHRES = 0.1``
    V, ``SUBSHIFT = 0``, ``LAMBDA = THETA = 0``, ``MTRIODE = 1``), the constant
    gate–source capacitance ``cgs`` and the drain and source resistances ``rd``, ``rs``
    (0: none; ``lambda_``/``theta`` need ``rs = 0``). The gate–drain capacitance
    (:func:`GateDrainCapacitance`), the gate resistance and the body diode are separate
    parts beside it. ``v0 = (V_GS, V_GD)``: initial gate voltages."""
    # the shared part's bulk junctions get I_S = 0 (a VDMOS has no bulk terminal; its
    # body diode is a separate part): only their G_min remains, as in level 1
    vgs, vgd = v0
    dev = device("VDMOS", kind, 1.0, 1.0, name,
                 dict(is_=0.0, cgso=cgs, rd=rd, rs=rs, gmin=gmin, v0=(vgs, vgd, vgs)))  # fmt: skip
    where = dev.where
    vto, kp = finite(where, "vto", vto), finite(where, "kp", kp)
    ksub = positive(where, "ksubthres", ksubthres)
    lam, th = finite(where, "lambda_", lambda_), finite(where, "theta", theta)
    if (lam != 0.0 or th != 0.0) and rs != 0.0:
        # the law reads V_BS = 0 (module docstring): the bulk must be the channel's source
        raise ModelError(
            f"{where}: lambda_/theta need rs=0 here (the law reads the bulk as the "
            "channel's own source); put RS in series as a Resistor, as the netlist does."
        )
    mtr = positive(where, "mtriode", mtriode)
    # the law as data (its numbers a vector): devices of other values share one program
    forward = law(
        vdmos_law, vto=KINDS[kind] * vto, kp=kp, ksubthres=ksub,
        subshift=finite(where, "subshift", subshift), lambda_=lam, theta=th, mtriode=mtr,
    )  # fmt: skip
    params = dict(vto=vto, kp=kp, ksubthres=ksub, mtriode=mtr)
    return build(dev, forward, 0.6, params | {"lambda": lam, "theta": th})
