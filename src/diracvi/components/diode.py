r"""The SPICE junction diode (ngspice's level 1) as a Lagrange–Dirac part.

A diode is *voltage-controlled*: its current is a function of its junction voltage, while
a force ``F(q, q̇)`` can only give a voltage as a function of current. The part therefore
carries, beside its branch charge ``q``, the flux linkage ``w = ∫ V_j dt`` of the junction,
with

    L(q, w, q̇, ẇ) = w q̇ + Φ(ẇ),        F = (−R_S q̇,  −i_D(ẇ)),

``Φ(V) = ∫₀^V Q_j(u) du`` the junction's charge co-energy. Its Euler–Lagrange equations are

    ẇ = (φ_p − φ_n) − R_S q̇ = V_j                  (the q-line: d/dt ∂L/∂q̇ = ẇ),
    q̇ = i_D(V_j) + d/dt Q_j(V_j)                    (the w-line: d/dt Φ′(ẇ) − q̇ = −i_D),

the series resistance, the static current and the junction charge exactly as SPICE's
diode (the internal node between ``R_S`` and the junction is the voltage ``φ_p − R_S i``,
so it needs no coordinate). The energy is ``E = Q_j V_j − Φ(V_j) = ∫₀^{Q_j} V dQ``, the
charge's stored energy — convex, because ``Q_j`` increases with ``V_j`` — and the power
balance is ``dE/dt = V i − R_S i² − i_D V_j`` (port power in, series and junction losses
out): the junction charge is a nonlinear capacitor held in the Lagrangian. Discretely the
charge is the momentum of ``w``, balanced exactly step by step; the energy balance is that
of any nonlinear capacitor under the rule (exact for a quadratic stored energy, to the
rule's order otherwise).

**Static current** (ngspice ``dioload.c``), ``nV_T = N kT/q``, ``I_S`` and ``I_BV`` scaled
by ``AREA`` as ngspice does for level 1 (``I_S·AREA``; ``I_BV`` not scaled)::

    V ≥ −3 nV_T        i = I_S (e^{V/nV_T} − 1)
    −BV' ≤ V < −3 nV_T   i = −I_S (1 + (3 nV_T/(e V))³)
    V < −BV'           i = −I_S e^{−(BV' + V)/(N_BV V_T)}         (only with BV)
    plus G_min V       (ngspice's GMIN, 1e-12 S, across the junction)

where ``BV'`` is ngspice's adjusted breakdown voltage: the ``x`` with
``I_S (e^{(BV−x)/(N_BV V_T)} − 1 + x/V_T) = I_BV`` (``I_BV`` raised to ``I_S BV/V_T`` if
smaller, then ``BV' = BV``). Above ``40 nV_T`` the exponential is continued by its tangent
(C¹) so that no iterate can overflow; that is thousands of amperes for ``I_S = 10⁻¹⁴``.

**Junction charge** ``Q_j = Q_dep + TT·i_D`` (``i_D`` without G_min), with the depletion
charge of ``C_J = CJO·AREA``, ``V_d = FC·VJ``::

    V < V_d    Q_dep = C_J VJ (1 − (1 − V/VJ)^{1−M}) / (1 − M)
    V ≥ V_d    Q_dep = C_J [F1 + (F3 (V − V_d) + M (V² − V_d²)/(2 VJ)) / F2]
    F1 = VJ (1 − (1−FC)^{1−M})/(1 − M),  F2 = (1−FC)^{1+M},  F3 = 1 − FC (1 + M)

(the linear extension of the capacitance above ``V_d``); ``Φ`` is its integral in closed
form.

**Temperature**: ``V_T = kT/q`` at the device's temperature (``thermal_voltage``; 27 °C
by default), and :func:`spice_diode` moves ``IS``, ``VJ``, ``CJO``, ``M``, ``BV``, ``RS``,
``TT`` to it as ngspice 39 does (:func:`diracvi.components._temperature.diode`).
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._diode_static import diffusion_coenergy, static_current
from ._junction import THERMAL_VOLTAGE, depletion_coenergy, exp_capped, exp_capped_integral
from ._part import Part, array_module, finite, positive, traced
from ._temperature import DIODE, DIODE_ALIASES, KELVIN, kelvin
from ._temperature import diode as diode_at

#: ngspice's diode model parameters that diracvi accepts (``.model NAME D(...)``):
#: name -> (default, unit, meaning). ``None``: not given (no breakdown; NBV = N).
#: KF, AF only act in noise analyses, so they are accepted and have no effect here; the
#: temperature parameters (EG, XTI, TNOM, TCV, TRS, …) are those of ``_temperature.DIODE``.
SPICE_PARAMETERS = {
    "is": (1e-14, "A", "saturation current"),
    "n": (1.0, "", "emission coefficient"),
    "rs": (0.0, "Ω", "ohmic (series) resistance"),
    "cjo": (0.0, "F", "zero-bias junction capacitance"),
    "vj": (1.0, "V", "junction potential"),
    "m": (0.5, "", "grading coefficient"),
    "fc": (0.5, "", "forward-bias depletion capacitance coefficient"),
    "tt": (0.0, "s", "transit time"),
    "bv": (None, "V", "reverse breakdown voltage"),
    "ibv": (1e-3, "A", "current at the breakdown voltage"),
    "nbv": (None, "", "breakdown emission coefficient (default N)"),
    "kf": (0.0, "", "flicker noise coefficient (noise only)"),
    "af": (1.0, "", "flicker noise exponent (noise only)"),
    "level": (1.0, "", "model level (only 1)"),
}
#: ngspice 39's optional terms (``dioload.c``; see :mod:`._diode_static`): ``None`` = not
#: given (the term is off). ``NR`` defaults to 1 in ngspice 39's code (its manual says 2).
SPICE_PARAMETERS.update(
    {
        "isr": (None, "A", "recombination saturation current"),
        "nr": (1.0, "", "recombination emission coefficient"),
        "ikf": (None, "A", "forward knee current (high injection)"),
        "ikr": (None, "A", "reverse knee current"),
        "jsw": (0.0, "A", "sidewall saturation current (× PJ)"),
        "ns": (None, "", "sidewall emission coefficient (not given: JSW joins IS)"),
        "cjsw": (0.0, "F", "sidewall junction capacitance (× PJ)"),
        "php": (1.0, "V", "sidewall junction potential"),
        "mjsw": (0.33, "", "sidewall grading coefficient"),
        "fcs": (0.5, "", "sidewall forward-bias depletion capacitance coefficient"),
        "area": (1.0, "", "area factor (the D line's AREA overrides it)"),
        "pj": (0.0, "", "perimeter factor (the D line's PJ overrides it)"),
    }
)
#: parameters with no effect in a transient/DC analysis: the safe-operating-area limits
#: (warnings only) and self-heating's (needs a thermal node, which the D line has not);
#: the temperature coefficients are read (:mod:`._temperature`)
SPICE_INERT = ("fv_max", "bv_max", "id_max", "te_max", "pd_max", "rth0", "cth0")
#: every model parameter name ngspice 39's diode knows (``dio.c``): a card's name outside
#: it is *ignored* by ngspice 39 ("unrecognized parameter - ignored", e.g. PSpice's IBVL,
#: NBVL, TBV1 and VJSW, which later ngspice releases alias): diracvi ignores it too, noted
NGSPICE39_NAMES = frozenset(
    "level is js jsw tnom tref rs trs trs1 trs2 n ns tt ttt1 ttt2 cjo cj0 cj vj pb m mj "
    "tm1 tm2 cjp cjsw php mjsw ikf ik ikr nbv area pj tlev tlevc eg xti cta ctc ctp tpb "
    "tvj tphp jtun jtunsw ntun xtitun keg kf af fc fcs bv ibv ib tcv isr nr fv_max bv_max "
    "id_max te_max pd_max rth0 cth0 lm lp wm wp xom xoi xm xp d".split()
)
#: other spellings ngspice accepts -> the name above
SPICE_PARAMETERS |= DIODE
SPICE_ALIASES = {
    "cj0": "cjo", "cj": "cjo", "pb": "vj", "mj": "m", "js": "is", "rs0": "rs",
    "ik": "ikf", "ib": "ibv", "cjp": "cjsw",
}  # fmt: skip
SPICE_ALIASES |= DIODE_ALIASES


def breakdown_knee(i_s, bv, ibv, nbv_vt, vt=THERMAL_VOLTAGE):
    """ngspice's adjusted breakdown voltage ``BV'`` (``diotemp.c``), see the module text."""
    xp = array_module(i_s, bv, ibv, nbv_vt)
    cbv = xp.maximum(ibv, i_s * bv / vt)
    x = bv - nbv_vt * xp.log(1.0 + cbv / i_s)
    for _ in range(60):  # a contraction: converged to round-off long before
        x = bv - nbv_vt * xp.log(cbv / i_s + 1.0 - x / vt)
    return xp.where(ibv < i_s * bv / vt, bv, x)


class _Junction:
    """The junction's static current, charge and charge co-energy at voltage ``V``."""

    def __init__(self, i_s, nvt, gmin, bv, nbv_vt, cj, vj, m, fc, tt):
        self.i_s, self.nvt, self.gmin = i_s, nvt, gmin
        self.bv, self.nbv_vt = bv, nbv_vt
        self.cj, self.vj, self.m, self.fc, self.tt = cj, vj, m, fc, tt

    # --- static current i_D (without G_min) and its integral
    def _regions(self, v):
        knee = -3.0 * self.nvt
        forward = v >= knee
        broken = (v < -self.bv) if self.bv is not None else jnp.zeros_like(v, dtype=bool)
        return knee, forward, broken

    def current(self, v):
        """``i_D(V)`` without G_min (the diffusion charge is ``TT`` times this)."""
        knee, forward, broken = self._regions(v)
        f = self.i_s * (exp_capped(v / self.nvt) - 1.0)
        vr = jnp.minimum(v, knee)
        arg = (3.0 * self.nvt / (math.e * vr)) ** 3
        r = -self.i_s * (1.0 + arg)
        out = jnp.where(forward, f, r)
        if self.bv is not None:
            b = -self.i_s * jnp.exp(-(self.bv + jnp.minimum(v, -self.bv)) / self.nbv_vt)
            out = jnp.where(broken, b, out)
        return out

    def current_integral(self, v):
        """``∫₀^V i_D(u) du`` (piecewise closed form, continuous)."""
        knee, forward, broken = self._regions(v)
        i_s, nvt = self.i_s, self.nvt

        def fwd(x):
            return i_s * (nvt * exp_capped_integral(x / nvt) - x)

        c = (3.0 * nvt / math.e) ** 3

        def rev(x):  # ∫_knee^x −I_S (1 + c/u³) du
            return -i_s * ((x - knee) - 0.5 * c * (1.0 / x**2 - 1.0 / knee**2))

        vr = jnp.minimum(v, knee)
        out = jnp.where(forward, fwd(jnp.maximum(v, knee)), fwd(knee) + rev(vr))
        if self.bv is not None:
            vb = jnp.minimum(v, -self.bv)
            at_bv = fwd(knee) + rev(jnp.minimum(-self.bv, knee))
            # ∫_{−BV'}^x −I_S e^{−(BV'+u)/nbv} du = I_S nbv (e^{−(BV'+x)/nbv} − 1)
            brk = at_bv + i_s * self.nbv_vt * (jnp.exp(-(self.bv + vb) / self.nbv_vt) - 1.0)
            out = jnp.where(broken, brk, out)
        return out

    # --- depletion charge and its integral
    def _depletion_integral(self, v):
        return depletion_coenergy(v, self.cj, self.vj, self.m, self.fc)

    def coenergy(self, v):
        """``Φ(V) = ∫₀^V Q_j``; ``Φ′ = Q_j`` (JAX differentiates it)."""
        out = 0.0 * v
        if not (isinstance(self.cj, float) and self.cj == 0.0):
            out = out + self._depletion_integral(v)
        if not (isinstance(self.tt, float) and self.tt == 0.0):
            out = out + self.tt * self.current_integral(v)
        return out


def _optional_terms(where, base, given):
    """``(JSW·PJ joined to I_S, the optional terms' tables or None)`` (see :func:`Diode`)."""
    vt = base["vt"]
    pj = finite(where, "perimeter", given["pj"])
    area = base["area"]
    jsw = finite(where, "sidewall_current", given["jsw"]) * pj
    cjsw = finite(where, "sidewall_capacitance", given["cjsw"]) * pj
    checks = (("perimeter", pj), ("sidewall_current", jsw), ("sidewall_capacitance", cjsw))
    for arg, value in checks:
        if not traced(value) and value < 0.0:
            raise ModelError(f"{where}: {arg}={value!r} must be ≥ 0 (ngspice's range).")
    prm = {"is": base["is_"], "nvt": base["nvt"], "nbv_vt": base["nbv_vt"], "tt": base["tt"]}
    if base["bv"] is not None:
        prm["bv"] = base["bv"]
    sidewall = given["ns"] is not None
    merged = 0.0
    if sidewall:
        prm["issw"] = jsw
        prm["nvtsw"] = positive(where, "sidewall_emission", given["ns"]) * vt
    else:
        merged = jsw
        prm["is"] = prm["is"] + jsw
    recombination = given["isr"] is not None
    if recombination:
        prm["isr"] = positive(where, "recombination_current", given["isr"]) * area
        prm["nrvt"] = positive(where, "recombination_emission", given["nr"]) * vt
        prm["vj"], prm["m"] = base["vj"], base["m"]
    knees = []
    for key, arg in (("ikf", "forward_knee"), ("ikr", "reverse_knee")):
        value = given[key]
        if value is not None and not traced(value):
            value = finite(where, arg, value)
            if value < 1e-28:  # ngspice: "IKF too small - model effect disabled"
                value = None
        if value is not None:
            prm[key] = value * area
        knees.append(value is not None)
    flags = (sidewall, recombination, *knees)
    has_cjsw = traced(cjsw) or cjsw != 0.0
    if not any(flags) and not has_cjsw:
        return merged, None
    depletion = None
    if has_cjsw:
        fcs = finite(where, "sidewall_coefficient", given["fcs"])
        mjsw = finite(where, "sidewall_grading", given["mjsw"])
        php = positive(where, "sidewall_potential", given["php"])
        for arg, value in (("sidewall_grading", mjsw), ("sidewall_coefficient", fcs)):
            if not traced(value) and not 0.0 <= value < 1.0:
                raise ModelError(f"{where}: {arg}={value!r} must be in [0, 1) (ngspice's range).")
        if not traced(fcs) and not traced(php) and fcs * php > 1.0:  # ngspice: PHP ≤ 1/FCS
            php = 1.0 / fcs
        depletion = (cjsw, php, mjsw, fcs)
    return merged, {"prm": prm, "flags": flags, "depletion": depletion}


class _Extended:
    """A :class:`_Junction` with ngspice's optional terms (:mod:`._diode_static`)."""

    def __init__(self, junction, extra):
        self.junction = junction  # its bottom depletion charge and, without terms, its current
        self.prm, self.flags, self.depletion = extra["prm"], extra["flags"], extra["depletion"]

    def current(self, v):
        """``i(V)`` without G_min (:func:`~._diode_static.static_current`)."""
        if not any(self.flags):
            return self.junction.current(v)
        return static_current(v, self.prm, self.flags)

    def coenergy(self, v):
        """``Φ(V) = ∫₀^V Q_j``: bottom and sidewall depletion, diffusion ``TT·i``."""
        j = self.junction
        out = 0.0 * v
        if not (isinstance(j.cj, float) and j.cj == 0.0):
            out = out + j._depletion_integral(v)
        if self.depletion is not None:
            out = out + depletion_coenergy(v, *self.depletion)
        if not (isinstance(j.tt, float) and j.tt == 0.0):
            if any(self.flags):
                out = out + diffusion_coenergy(v, self.prm, self.flags)
            else:
                out = out + j.tt * j.current_integral(v)
        return out


def shockley_current(v, saturation_current, emission, gmin):
    """``I_S (e^{V/(N V_T)} − 1) + G_min V`` with the linear continuation above 40 N V_T."""
    nvt = emission * THERMAL_VOLTAGE
    return saturation_current * (exp_capped(v / nvt) - 1.0) + gmin * v


def Diode(
    saturation_current=1e-14,
    emission=1.0,
    *,
    name: str,
    gmin=1e-12,
    series_resistance=0.0,
    junction_capacitance=0.0,
    junction_potential=1.0,
    grading=0.5,
    depletion_coefficient=0.5,
    transit_time=0.0,
    breakdown_voltage=None,
    breakdown_current=1e-3,
    breakdown_emission=None,
    area=1.0,
    v0=0.0,
    thermal_voltage=THERMAL_VOLTAGE,
    recombination_current=None,
    recombination_emission=1.0,
    forward_knee=None,
    reverse_knee=None,
    sidewall_current=0.0,
    sidewall_emission=None,
    sidewall_capacitance=0.0,
    sidewall_potential=1.0,
    sidewall_grading=0.33,
    sidewall_coefficient=0.5,
    perimeter=0.0,
) -> Part:
    r"""A junction diode from anode ``p`` to cathode ``n`` (SPICE's ``D``; see the module).

    Arguments are ngspice's model parameters in SI units: ``IS``, ``N``, ``GMIN``, ``RS``,
    ``CJO``, ``VJ``, ``M``, ``FC``, ``TT``, ``BV`` (``None``: no breakdown), ``IBV``,
    ``NBV`` (``None``: ``N``) and the instance's ``AREA``; ``v0`` is the initial junction
    voltage (SPICE's ``IC=``, used by the junction charge); ``thermal_voltage`` is
    ``kT/q`` at the device's temperature. Every value may be traced
    (``jax.grad`` flows to it). Coordinates ``(q, w)``: branch charge and flux linkage.

    ngspice's optional terms (:mod:`._diode_static`): ``ISR``, ``NR`` (recombination
    current; ``None``: none), ``IKF``, ``IKR`` (knee currents; ``None`` or below 10⁻²⁸:
    none), the sidewall ``JSW``, ``NS`` (``None``: ``JSW`` joins ``IS``), ``CJSW``, ``PHP``,
    ``MJSW``, ``FCS`` scaled by the instance's ``perimeter`` (``PJ``).
    """
    where = f"Diode {name!r}"
    area = positive(where, "area", area)
    i_s = positive(where, "saturation_current", saturation_current) * area
    n = positive(where, "emission", emission)
    g = positive(where, "gmin", gmin)
    rs = finite(where, "series_resistance", series_resistance)
    cj = finite(where, "junction_capacitance", junction_capacitance)
    vj = positive(where, "junction_potential", junction_potential)
    m = finite(where, "grading", grading)
    fc = finite(where, "depletion_coefficient", depletion_coefficient)
    tt = finite(where, "transit_time", transit_time)
    ibv = positive(where, "breakdown_current", breakdown_current)
    v0 = finite(where, "v0", v0)
    for arg, value, ok, need in (
        ("series_resistance", rs, lambda x: x >= 0, "≥ 0"),
        ("junction_capacitance", cj, lambda x: x >= 0, "≥ 0"),
        ("transit_time", tt, lambda x: x >= 0, "≥ 0"),
        ("grading", m, lambda x: 0 <= x < 1, "in [0, 1)"),
        ("depletion_coefficient", fc, lambda x: 0 <= x < 1, "in [0, 1)"),
    ):
        if not traced(value) and not ok(value):
            raise ModelError(f"{where}: {arg}={value!r} must be {need} (ngspice's range).")
    rs, cj = rs / area, cj * area  # ngspice's area scaling (level 1)
    if not traced(fc) and not traced(vj) and fc * vj > 1.0:  # ngspice limits VJ to 1/FC
        vj = 1.0 / fc
    vt = positive(where, "thermal_voltage", thermal_voltage)
    nvt = n * vt
    bv = None
    nbv_vt = nvt
    if breakdown_voltage is not None:
        bv = positive(where, "breakdown_voltage", breakdown_voltage)
        if breakdown_emission is not None:
            nbv_vt = positive(where, "breakdown_emission", breakdown_emission) * vt
        bv = breakdown_knee(i_s, bv, ibv, nbv_vt, vt)
    merged, extra = _optional_terms(
        where,
        dict(is_=i_s, nvt=nvt, vt=vt, bv=bv, nbv_vt=nbv_vt, area=area, vj=vj, m=m, fc=fc, tt=tt),
        dict(
            isr=recombination_current, nr=recombination_emission, ikf=forward_knee,
            ikr=reverse_knee, jsw=sidewall_current, ns=sidewall_emission,
            cjsw=sidewall_capacitance, php=sidewall_potential, mjsw=sidewall_grading,
            fcs=sidewall_coefficient, pj=perimeter,
        ),
    )  # fmt: skip
    # JSW·PJ without NS joins I_S (ngspice: csat + csatsw), after BV' and V_crit (I_S only)
    junction = _Junction(i_s + merged, nvt, g, bv, nbv_vt, cj, vj, m, fc, tt)
    if extra is not None:
        junction = _Extended(junction, extra)
    has_charge = extra is not None or not (
        isinstance(cj, float) and cj == 0.0 and isinstance(tt, float) and tt == 0.0
    )
    has_rs = not (isinstance(rs, float) and rs == 0.0)

    def lagrangian(q, v):
        out = q[1] * v[0]
        if has_charge:
            out = out + junction.coenergy(v[1])
        return out

    def force(q, v):
        series = -rs * v[0] if has_rs else 0.0 * v[0]
        return jnp.stack([series, -(junction.current(v[1]) + g * v[1])])

    xp = array_module(nvt, i_s, bv)
    vcrit = nvt * xp.log(nvt / (math.sqrt(2.0) * i_s))
    limits = xp.stack([xp.asarray(x, float) for x in (nvt, vcrit, np.inf if bv is None else bv)])
    limits = limits[None, :]
    return Part(
        ("q", "w"),
        lagrangian,
        force=force,
        name=name,
        pins=(("p", "q", 1), ("n", "q", -1)),
        initial_v=[0.0, v0],
        role="diode",
        junctions=("w",),
        junction_limits=limits,
    )


def spice_diode(
    model: dict, *, name: str, area=None, ic=0.0, gmin=1e-12, pj=None, m=1.0,
    temperature=27.0, tnom=27.0,
) -> Part:  # fmt: skip
    """A :func:`Diode` from ngspice model parameters (lower-case names of
    :data:`SPICE_PARAMETERS`, aliases allowed; missing ones take their defaults;
    :data:`SPICE_INERT` ones accepted, without effect in a transient) at the device's
    ``temperature`` (°C); ``tnom`` (°C) is the model's TNOM where it gives none (ngspice's
    ``.options tnom``). The instance's ``area`` and ``pj`` (``None``: the model's ``AREA``,
    ``PJ``) and multiplier ``m`` scale as ngspice 39's level 1: ``AREA·M`` multiplies
    ``IS``, ``ISR``, ``IKF``, ``IKR``, ``CJO`` and divides ``RS``; ``PJ·M`` multiplies
    ``JSW``, ``CJSW``; ``M`` multiplies ``IBV``."""
    values = {SPICE_ALIASES.get(k, k): v for k, v in model.items()}
    unknown = sorted(set(values) - set(SPICE_PARAMETERS) - set(SPICE_INERT))
    if unknown:
        raise ModelError(
            f"diode {name!r}: parameters {unknown} are not supported; supported: "
            f"{', '.join(k.upper() for k in SPICE_PARAMETERS)}."
        )
    p = {k: values.get(k, d[0]) for k, d in SPICE_PARAMETERS.items()}
    if float(p["level"]) != 1.0:
        raise ModelError(f"diode {name!r}: LEVEL={p['level']} is not supported (only level 1).")
    nominal = kelvin(tnom if p["tnom"] is None else p["tnom"])
    if kelvin(temperature) != nominal:
        # ngspice 39 scales these with temperature too (diotemp.c); diracvi does not yet
        scaled = [k.upper() for k in ("isr", "jsw", "cjsw") if values.get(k) not in (None, 0.0)]
        if scaled:
            raise ModelError(
                f"diode {name!r}: {', '.join(scaled)} at {temperature:g} °C (TNOM "
                f"{nominal - KELVIN:g} °C): their temperature dependence is not implemented; "
                "run at TNOM, or drop them"
            )
    # (the update also limits the grading coefficient to 0.9, as ngspice 39 does)
    p = diode_at(p, kelvin(temperature), nominal, name=name)
    mult = positive(f"diode {name!r}", "m", m)
    area = p["area"] if area is None else area
    pj = p["pj"] if pj is None else pj
    return Diode(
        p["is"],
        p["n"],
        name=name,
        gmin=gmin,
        series_resistance=p["rs"],
        junction_capacitance=p["cjo"],
        junction_potential=p["vj"],
        grading=p["m"],
        depletion_coefficient=p["fc"],
        transit_time=p["tt"],
        breakdown_voltage=p["bv"],
        breakdown_current=p["ibv"] * mult,
        breakdown_emission=p["nbv"],
        area=area * mult,
        v0=ic,
        thermal_voltage=p["vt"],
        recombination_current=p["isr"],
        recombination_emission=p["nr"],
        forward_knee=p["ikf"],
        reverse_knee=p["ikr"],
        sidewall_current=p["jsw"],
        sidewall_emission=p["ns"],
        sidewall_capacitance=p["cjsw"],
        sidewall_potential=p["php"],
        sidewall_grading=p["mjsw"],
        sidewall_coefficient=p["fcs"],
        perimeter=pj * mult,
    )
