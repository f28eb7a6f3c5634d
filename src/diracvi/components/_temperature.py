r"""ngspice 39's temperature updates of the semiconductor models, done once per device
before a run (ngspice's ``DIOtemp``, ``BJTtemp``, ``MOS1temp``), from the device's
temperature ``T`` and its model's nominal ``T_nom`` (kelvin).

Shared pieces (``q`` the electron charge, ``k`` Boltzmann's constant, ngspice's
``const.h``; ``T_ref = 300.15`` K):

    V_T(T) = k T / q,
    E_g(T) = 1.16 − 7.02·10⁻⁴ T² / (T + 1108)                      (silicon's gap, eV),
    p(T)   = −2 V_T(T) [1.5 ln(T/T_ref) + q (−E_g(T)/(2kT) + 1.1150877/(2k T_ref))],

and a junction potential and zero-bias depletion capacitance (grading ``M``) move as
(ngspice's ``TLEVC = 0``)

    φ₀ = (φ − p(T_nom)) / (T_nom/T_ref),   γ(φ) = (φ − φ₀)/φ₀,
    φ(T) = p(T) + (T/T_ref) φ₀,
    C(T) = C · [1 + M (4·10⁻⁴ (T − T_ref) − γ(φ(T)))] / [1 + M (4·10⁻⁴ (T_nom − T_ref) − γ(φ))].

At ``T = T_nom`` each update is the identity (up to round-off), so it is skipped there
and a nominal run is unchanged bit for bit. Every function works on NumPy floats or on
traced JAX values (:func:`~diracvi.components._part.array_module`), so a gradient flows
through the temperature update to the model parameters.
"""

from __future__ import annotations

from ..errors import ModelError
from ._part import array_module, traced

#: ngspice's const.h: electron charge (C), Boltzmann's constant (J/K), 0 °C (K)
CHARGE = 1.6021766208e-19
BOLTZMANN = 1.38064852e-23
KELVIN = 273.15
#: ngspice's REFTEMP, 27 °C in kelvin
REFERENCE = 300.15


def thermal_voltage(t):
    """``V_T = kT/q`` at ``t`` kelvin."""
    return BOLTZMANN * t / CHARGE


def _gap(t):
    return 1.16 - 7.02e-4 * t * t / (t + 1108.0)


def _pbfact(t, xp):
    arg = -_gap(t) / (2.0 * BOLTZMANN * t) + 1.1150877 / (BOLTZMANN * (2.0 * REFERENCE))
    return -2.0 * thermal_voltage(t) * (1.5 * xp.log(t / REFERENCE) + CHARGE * arg)


def junction(potential, capacitance, grading, t, tnom):
    """``(φ(T), C(T))`` of the module docstring for a junction of potential ``φ``,
    zero-bias capacitance ``C`` and grading ``M`` measured at ``tnom`` (kelvin)."""
    xp = array_module(potential, capacitance, grading, t, tnom)
    fact1, fact2 = tnom / REFERENCE, t / REFERENCE
    pbo = (potential - _pbfact(tnom, xp)) / fact1
    gmaold = (potential - pbo) / pbo
    pot = _pbfact(t, xp) + fact2 * pbo
    gmanew = (pot - pbo) / pbo
    cap = capacitance / (1.0 + grading * (4e-4 * (tnom - REFERENCE) - gmaold))
    return pot, cap * (1.0 + grading * (4e-4 * (t - REFERENCE) - gmanew))


def _poly(x, c1, c2, dt):
    """ngspice's quadratic temperature factor ``x (1 + c1 ΔT + c2 ΔT²)``."""
    return x * (1.0 + c1 * dt + c2 * dt * dt)


def _nominal(t, tnom) -> bool:
    return not traced(t) and not traced(tnom) and t == tnom


def kelvin(celsius):
    """°C → K."""
    return celsius + KELVIN


# ----------------------------------------------------------------------- diode
#: the diode's temperature parameters (ngspice 39 ``dio.c``, defaults of ``diosetup.c``):
#: name -> (default, unit, meaning)
DIODE = {
    "tnom": (None, "°C", "nominal temperature (default .options tnom, 27 °C)"),
    "eg": (1.11, "eV", "activation energy of IS"),
    "xti": (3.0, "", "saturation-current temperature exponent"),
    "tcv": (0.0, "V/K", "breakdown-voltage temperature coefficient"),
    "trs": (0.0, "1/K", "RS first-order temperature coefficient"),
    "trs2": (0.0, "1/K²", "RS second-order temperature coefficient"),
    "ttt1": (0.0, "1/K", "TT first-order temperature coefficient"),
    "ttt2": (0.0, "1/K²", "TT second-order temperature coefficient"),
    "tm1": (0.0, "1/K", "M first-order temperature coefficient"),
    "tm2": (0.0, "1/K²", "M second-order temperature coefficient"),
    "tlev": (0.0, "", "temperature equations of BV (only 0)"),
    "tlevc": (0.0, "", "temperature equations of VJ, CJO (only 0)"),
    "cta": (0.0, "1/K", "CJO temperature coefficient (TLEVC = 1 only)"),
    "ctp": (0.0, "1/K", "sidewall CJ temperature coefficient (TLEVC = 1 only)"),
    "tpb": (0.0, "V/K", "VJ temperature coefficient (TLEVC = 1 only)"),
    "tphp": (0.0, "V/K", "sidewall VJ temperature coefficient (TLEVC = 1 only)"),
}
DIODE_ALIASES = {"tref": "tnom", "trs1": "trs", "ctc": "cta", "tvj": "tpb"}
#: names ngspice 39 does not know (it warns "unrecognized parameter … ignored" and runs
#: without them; ngspice ≥ 40 reads TBV1 as TCV): read the same way, with a note
DIODE_IGNORED_BY_NGSPICE39 = ("tbv1", "tbv2")
#: ngspice 39 limits the temperature-adjusted grading coefficient to this (diotemp.c)
GRADING_LIMIT = 0.9


def _default_equations(p: dict, where: str) -> None:
    """Refuse ``TLEV``/``TLEVC`` other than ngspice's default 0 (the only equations here)."""
    for key in ("tlev", "tlevc"):
        if not traced(p[key]) and p[key] != 0:
            raise ModelError(
                f"{where}: {key.upper()}={p[key]:g} is not supported; only ngspice's default "
                f"{key.upper()}=0 (drop it)"
            )


def diode(p: dict, t, tnom, *, name: str) -> dict:
    r"""ngspice 39's diode temperature update (``diotemp.c``, ``TLEV = TLEVC = 0``) of
    the model values ``p`` (lower-case names, defaults filled) at ``t`` for a model
    measured at ``tnom`` (kelvin), ``ΔT = T − T_nom``:

        I_S(T) = I_S exp[(T/T_nom − 1) E_g/(N V_T(T)) + (X_TI/N) ln(T/T_nom)],
        M(T)   = min(M (1 + TM1 ΔT + TM2 ΔT²), 0.9),
        VJ(T), CJO(T) from the junction update (module docstring, with M(T)),
        BV(T)  = BV − TCV ΔT,
        R_S(T) = R_S (1 + TRS ΔT + TRS2 ΔT²),   TT(T) = TT (1 + TTT1 ΔT + TTT2 ΔT²),

    and the junction's thermal voltage becomes ``V_T(T)`` (returned as ``"vt"``); the
    breakdown knee ``BV'`` is then solved at ``V_T(T)`` too. Returns the updated copy.
    """
    _default_equations(p, f"diode {name!r}")
    out = dict(p)
    m = p["m"]
    if not traced(m) and m > GRADING_LIMIT:  # ngspice 39 limits M (with a warning)
        out["m"] = m = GRADING_LIMIT
    out["vt"] = thermal_voltage(t)
    if _nominal(t, tnom):
        return out
    xp = array_module(t, tnom, p["is"], p["n"], p["eg"], p["xti"])
    dt = t - tnom
    vt_n = p["n"] * thermal_voltage(t)
    out["is"] = p["is"] * xp.exp(
        (t / tnom - 1.0) * p["eg"] / vt_n + p["xti"] / p["n"] * xp.log(t / tnom)
    )
    m = _poly(p["m"], p["tm1"], p["tm2"], dt)
    out["m"] = xp.minimum(m, GRADING_LIMIT)
    out["vj"], out["cjo"] = junction(p["vj"], p["cjo"], out["m"], t, tnom)
    if p["bv"] is not None:
        out["bv"] = p["bv"] - p["tcv"] * dt
    out["rs"] = _poly(p["rs"], p["trs"], p["trs2"], dt)
    out["tt"] = _poly(p["tt"], p["ttt1"], p["ttt2"], dt)
    return out


# ------------------------------------------------------------------------- BJT
#: the BJT's temperature parameters read (ngspice 39 ``bjt.c``; ``None``: not given):
#: XTB, EG, XTI, the levels, and the quadratic coefficients ``TX1``, ``TX2`` of each
#: parameter ``X`` they scale (:data:`BJT_QUADRATIC`)
BJT = {"tnom": None, "xtb": 0.0, "eg": 1.11, "xti": 3.0, "tlev": 0.0, "tlevc": 0.0,
       "tbf1": None, "tbf2": None, "tbr1": None, "tbr2": None,
       **{f"t{x}{k}": 0.0 for x in ("vaf", "var", "ikf", "ikr", "rc", "re", "rb", "rm", "nf",
                                    "nr", "ne", "nc", "itf", "tf", "tr", "mje", "mjc", "mjs")
          for k in "12"}}  # fmt: skip
BJT_ALIASES = {"trb": "trb1", "trc": "trc1", "tre": "tre1"}
#: parameter -> the name stem of its coefficients: ``X(T) = X (1 + TX1 ΔT + TX2 ΔT²)``
BJT_QUADRATIC = {"vaf": "vaf", "var": "var", "ikf": "ikf", "ikr": "ikr", "rc": "rc",
                 "re": "re", "nf": "nf", "nr": "nr", "ne": "ne", "nc": "nc", "itf": "itf",
                 "tf": "tf", "tr": "tr", "mje": "mje", "mjc": "mjc", "mjs": "mjs"}  # fmt: skip
#: the emission coefficients: the part's ``V_T`` is 27 °C's, so a device at ``T``
#: carries ``N V_T(T)/V_T(27 °C)`` (the junction laws depend on ``N V_T`` only)
BJT_EMISSIONS = ("nf", "nr", "ne", "nc", "ns")
#: ngspice 39 limits a temperature-adjusted grading coefficient of the BJT to this
BJT_GRADING_LIMIT = 0.999


def bjt(p: dict, t, tnom, *, name: str) -> dict:
    r"""ngspice 39's BJT temperature update (``bjttemp.c``, ``TLEV = TLEVC = 0``) of the
    model values ``p`` at ``t`` for a model measured at ``tnom`` (kelvin),
    ``ΔT = T − T_nom``, ``L = (T/T_nom − 1) E_g/V_T(T) + X_TI ln(T/T_nom)``,
    ``b = (T/T_nom)^{X_TB}``:

        I_S(T)  = I_S e^L,
        B_F(T)  = B_F b   (B_F (1 + TBF1 ΔT + TBF2 ΔT²) when TBF1 or TBF2 is given; B_R alike),
        I_SE(T) = I_SE e^{L/N_E} / b,   I_SC(T) = I_SC e^{L/N_C} / b,
        X(T)    = X (1 + TX1 ΔT + TX2 ΔT²) for X in VAF, VAR, IKF, IKR, RC, RE, RB (TRB),
                  RBM (TRM), NF, NR, NE, NC, ITF, TF, TR, MJE, MJC, MJS (these ≤ 0.999),
        VJE, CJE, VJC, CJC, VJS, CJS from the junction update (module docstring, with
                  the adjusted gradings),

    then the emission coefficients times ``V_T(T)/V_T(27 °C)`` (:data:`BJT_EMISSIONS`).
    RB and RBM each by their own coefficients (TRB1/TRB2, TRM1/TRM2; RBM not given is RB
    at TNOM); ISS and IRB, which ngspice also scales, refused away from TNOM. Returns the
    updated copy.
    """
    _default_equations(p, f"BJT {name!r}")
    out = dict(p)
    if _nominal(t, tnom) and t == REFERENCE:
        return out
    xp = array_module(t, tnom, p["is"], p["eg"], p["xti"], p["xtb"])
    dt = t - tnom
    for x, stem in BJT_QUADRATIC.items():
        out[x] = _poly(p[x], p[f"t{stem}1"], p[f"t{stem}2"], dt)
    for x in ("mje", "mjc", "mjs"):
        out[x] = xp.minimum(out[x], BJT_GRADING_LIMIT)
    unscaled = [k.upper() for k in ("iss", "irb") if p.get(k) not in (None, 0.0)]
    if unscaled and not traced(dt) and dt != 0.0:
        raise ModelError(
            f"BJT {name!r}: {', '.join(unscaled)} at {t - KELVIN:g} °C (TNOM "
            f"{tnom - KELVIN:g} °C): their temperature dependence is not implemented; run "
            "at TNOM, or drop them"
        )
    # RB(T) and RBM(T) each by its own coefficients; RBM not given is RB at TNOM, so the
    # two may part with temperature: the bias-dependent base resistance (components/bjt.py)
    rbm = p["rb"] if p.get("rbm") is None else p["rbm"]
    out["rb"] = _poly(p["rb"], p["trb1"], p["trb2"], dt)
    out["rbm"] = _poly(rbm, p["trm1"], p["trm2"], dt)
    ratlog = xp.log(t / tnom)
    factlog = (t / tnom - 1.0) * p["eg"] / thermal_voltage(t) + p["xti"] * ratlog
    bfactor = xp.exp(ratlog * p["xtb"])
    out["is"] = p["is"] * xp.exp(factlog)
    for beta in ("bf", "br"):
        c1, c2 = p[f"t{beta}1"], p[f"t{beta}2"]
        given = c1 is not None or c2 is not None
        out[beta] = _poly(p[beta], c1 or 0.0, c2 or 0.0, dt) if given else p[beta] * bfactor
    out["ise"] = p["ise"] * xp.exp(factlog / p["ne"]) / bfactor
    out["isc"] = p["isc"] * xp.exp(factlog / p["nc"]) / bfactor
    for v, c, m in (("vje", "cje", "mje"), ("vjc", "cjc", "mjc"), ("vjs", "cjs", "mjs")):
        out[v], out[c] = junction(p[v], p[c], out[m], t, tnom)
    ratio = thermal_voltage(t) / thermal_voltage(REFERENCE)
    for n in BJT_EMISSIONS:
        out[n] = out[n] * ratio
    return out


# ------------------------------------------------------------------ MOSFET level 1
def mos1(v: dict, process: dict, sign, t, tnom) -> tuple[dict, dict, object]:
    r"""ngspice 39's level-1 MOSFET temperature update (``mos1temp.c``) of the card values
    ``v`` and the process values ``process`` (KP, PHI, GAMMA, VTO, derived at ``tnom``) at
    ``t`` (kelvin), ``r = T/T_nom``, ``type = sign`` (±1):

        KP(T)   = KP r^{−3/2},
        PHI(T)  = (T/T_ref) φ₀ + p(T),   φ₀ = (PHI − p(T_nom))/(T_nom/T_ref),
        VBI(T)  = VTO − type GAMMA √PHI + (E_g(T_nom) − E_g(T))/2 + type (PHI(T) − PHI)/2,
        VTO(T)  = VBI(T) + type GAMMA √PHI(T),
        IS(T), JS(T) = IS, JS · exp(−E_g(T)/V_T(T) + E_g(T_nom)/V_T(T_nom)),
        PB(T), and CBD, CBS, CJ (grading MJ), CJSW (grading MJSW, with PB's γ) by the
        junction update of the module docstring,

    returning ``(v, process, emission)``: the bulk junctions' ``V_T(T)/V_T(27 °C)`` (their
    law depends on ``V_T`` only through ``N V_T`` with ``N = 1``)."""
    if _nominal(t, tnom) and t == REFERENCE:
        return v, process, 1.0
    xp = array_module(t, tnom, v["pb"], process["phi"], process["kp"])
    v, process = dict(v), dict(process)
    ratio = t / tnom
    process["kp"] = process["kp"] / (ratio * xp.sqrt(ratio))
    phi, gamma = process["phi"], process["gamma"]
    phio = (phi - _pbfact(tnom, xp)) / (tnom / REFERENCE)
    tphi = (t / REFERENCE) * phio + _pbfact(t, xp)
    vbi = process["vto"] - sign * gamma * xp.sqrt(phi)
    vbi = vbi + 0.5 * (_gap(tnom) - _gap(t)) + sign * 0.5 * (tphi - phi)
    process["phi"], process["vto"] = tphi, vbi + sign * gamma * xp.sqrt(tphi)
    factor = xp.exp(-_gap(t) / thermal_voltage(t) + _gap(tnom) / thermal_voltage(tnom))
    v["is"], v["js"] = v["is"] * factor, v["js"] * factor
    pb = v["pb"]
    bottom = {k: v[k] for k in ("cbd", "cbs", "cj") if k in v}
    for k, c in bottom.items():
        v["pb"], v[k] = junction(pb, c, v["mj"], t, tnom)
    v["pb"], v["cjsw"] = junction(pb, v["cjsw"], v["mjsw"], t, tnom)
    return v, process, thermal_voltage(t) / thermal_voltage(REFERENCE)


# ------------------------------------------------------------------------- JFET
def jfet(v: dict, t, tnom) -> tuple[dict, float, object]:
    r"""ngspice 39's JFET temperature update (``jfettemp.c``) of the card values ``v`` (IS,
    VTO, BETA, B, PB, CGS, CGD and the coefficients EG, XTI, TCV, VTOTC, BEX, BETATCE; XTI,
    VTOTC and BETATCE present only where the card gives them) at ``t`` (kelvin), with
    ``ΔT = T − T_nom``, ``r = T/T_nom``:

        IS(T)   = IS exp((r − 1) EG / V_T(T)) · r^XTI        (the r^XTI only if XTI is given),
        VTO(T)  = VTO + VTOTC ΔT   (VTOTC given),   else VTO − TCV ΔT,
        BETA(T) = BETA 1.01^(BETATCE ΔT)   (BETATCE given),   else BETA r^BEX,
        PB, CGS, CGD by the junction update of the module docstring (grading ½),

    returning ``(v, bfac, emission)``: the doping tail's ``(1 − B)/(PB − VTO)`` at the
    card's values (``jfettemp`` computes it per model, before the update; ``None`` at
    ``T = T_nom = 27 °C``, where nothing is updated) and the gate junctions'
    ``V_T(T)/V_T(27 °C)``."""
    if _nominal(t, tnom) and t == REFERENCE:
        return v, None, 1.0
    if not traced(v["pb"]) and not traced(v["vto"]) and v["pb"] == v["vto"]:
        raise ModelError(
            f"PB = VTO = {v['pb']:g} V makes the doping tail's (1 − B)/(PB − VTO) 0/0 "
            "(ngspice's too); move PB or VTO."
        )
    bfac = (1.0 - v["b"]) / (v["pb"] - v["vto"])
    xp = array_module(t, tnom, v["is"], v["vto"], v["beta"], v["pb"])
    v = dict(v)
    ratio, dt, vt = t / tnom, t - tnom, thermal_voltage(t)
    scale = xp.exp((ratio - 1.0) * v["eg"] / vt)
    v["is"] = v["is"] * scale * (ratio ** v["xti"] if "xti" in v else 1.0)
    v["vto"] = v["vto"] + v["vtotc"] * dt if "vtotc" in v else v["vto"] - v["tcv"] * dt
    if "betatce" in v:
        v["beta"] = v["beta"] * 1.01 ** (v["betatce"] * dt)
    else:
        v["beta"] = v["beta"] * ratio ** v["bex"]
    pb = v["pb"]
    v["pb"], v["cgs"] = junction(pb, v["cgs"], 0.5, t, tnom)
    v["pb"], v["cgd"] = junction(pb, v["cgd"], 0.5, t, tnom)
    return v, bfac, thermal_voltage(t) / thermal_voltage(REFERENCE)


# ------------------------------------------------------------------------ VDMOS
def vdmos(v: dict, sign, t, tnom) -> dict:
    r"""ngspice 39's VDMOS temperature update (``vdmostemp.c``) of the card values ``v``
    (``sign`` = +1 NCHAN, −1 PCHAN; TEXP0 present only where the card gives it) at ``t``
    (kelvin), ``ΔT = T − T_nom``, ``r = T/T_nom``, ``P(c₁, c₂) = 1 + c₁ΔT + c₂ΔT²``:

        KP(T) = KP r^MU,   VTO(T) = VTO − type·TCVTH ΔT,
        KSUBTHRES(T) = KSUBTHRES P(TKSUBTHRES1, TKSUBTHRES2),
        RD(T) = RD r^TEXP0 (TEXP0 given), else RD P(TRD1, TRD2),
        RG(T) = RG P(TRG1, TRG2),   RS(T) = RS P(TRS1, TRS2),   RB(T) = RB P(TRB1, TRB2),
        the body diode's IS(T) = IS exp((r − 1) EG/(N V_T(T)) + (XTI/N) ln r),
        VJ, CJO by the junction update of the module docstring (grading M),

    and its ``V_T(T)`` (returned as ``"vt"``); EG below 0.1 eV is taken as 0.1, as
    ``vdmosset`` limits it."""
    out = dict(v)
    out["vt"] = thermal_voltage(t)
    if _nominal(t, tnom):
        return out
    xp = array_module(t, tnom, v["kp"], v["vto"], v["is"], v["n"])
    ratio, dt = t / tnom, t - tnom
    out["kp"] = v["kp"] * ratio ** v["mu"]
    out["vto"] = v["vto"] - sign * v["tcvth"] * dt
    out["ksubthres"] = _poly(v["ksubthres"], v["tksubthres1"], v["tksubthres2"], dt)
    if "texp0" in v:
        out["rd"] = v["rd"] * ratio ** v["texp0"]
    else:
        out["rd"] = _poly(v["rd"], v["trd1"], v["trd2"], dt)
    for r in ("rg", "rs", "rb"):
        out[r] = _poly(v[r], v[f"tr{r[1]}1"], v[f"tr{r[1]}2"], dt)
    eg = xp.maximum(v["eg"], 0.1) if traced(v["eg"]) else max(v["eg"], 0.1)
    vt_n = v["n"] * thermal_voltage(t)
    out["is"] = v["is"] * xp.exp((ratio - 1.0) * eg / vt_n + v["xti"] / v["n"] * xp.log(ratio))
    out["vj"], out["cjo"] = junction(v["vj"], v["cjo"], v["m"], t, tnom)
    return out
