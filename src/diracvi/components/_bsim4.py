r"""BSIM4 (ngspice's ``bsim4v7``, run for a card's VERSION 4.7, and ``bsim4v5``, run for
4.0–4.5) at the model's TNOM and its default modes (bsim4v5's gate tunnelling, igcMod and
igbMod 1, in :func:`tunnelling`): the card's parameters and their
size-dependent values (``b4v7set.c``, ``b4v7temp.c``), the drain current, the substrate
current and GIDL/GISL of an NMOS-oriented device in its mode (``V_DS ≥ 0``; source and
drain swapped for ``V_DS < 0``), and the intrinsic charges of capMod 2, the
charge-thickness model (``b4v7ld.c``). Written from the equations (BSIM4.7 manual);
ngspice's derivative bookkeeping is JAX's autodiff here.

**Size dependence** (``T/TNOM = 1``): every binnable ``P = P₀ + P_L/L_eff + P_W/W_eff +
P_P/(L_eff W_eff)`` (BINUNIT = 1: µm), ``L_eff = L + XL − 2dL``, ``W_eff = W + XW − 2dW``
(and their C–V and junction forms with DLC, DWC, DWJ). ``Φ = V_tm ln(NDEP/n_i) + PHIN +
0.4``, ``X_dep0 = √(2ε_Si Φ/(q NDEP))``, ``V_bi = V_tm ln(NSD·NDEP/n_i²)``, K1, K2 from
GAMMA1, GAMMA2 (as BSIM3), ``θ_0 = e^{x}/((e^{x} − 1)² + 2e^{x}MIN_EXP)`` at ``x =
DSUB L/l_t0`` (the 4.x short-channel form), ``R_ds0 = RDSW/(W_eff,CJ·10⁶)^{WR}``.

**Drain current** (``V_bseff`` floored at ``V_bsc`` and capped at 0.95Φ):

    V_th = V_th0 + (K1ox√Φ_s − K1√Φ)√(1 + LPEB/L) − K2ox V_bseff − ΔV_th(L) − ΔV_th(W)
           + (K3 + K3B V_bseff) TOXE Φ/(W_eff + W0) + K1ox(√(1 + LPE0/L) − 1)√Φ
           − (ETA0 + ETAB V_bseff) θ_DIBL V_DS − n V_t ln(L/(L + DVTP0(1 + e^{−DVTP1 V_DS})))
           − DVTP2f tanh(DVTP4 V_DS)
    V_gsteff = n V_t ln(1 + e^{m*V_gst/nV_t}) / (m* + n C_oxe/C_dep0 e^{(VOFF' − (1−m*)V_gst)/nV_t})
    I_ds = I_dl (1 + ΔV/V_ADIBL)(1 + ΔV/V_ADITS)(1 + ln(V_A/V_Asat)/C_clm)(1 + ΔV/V_ASCBE) V_dseff,
    I_dl = μ_eff C_oxeff (W/L) V_gsteff (1 − A_bulk V_dseff/2(V_gsteff + 2V_t))
           / ((1 + V_dseff/E_sat L)(1 + R_ds g_che))

with ``ΔV = V_DS − V_dseff``, mobMod 0/1/2's ``μ_eff`` (with UD's Coulomb term),
``C_oxeff`` the charge-centroid oxide capacitance (ADOS, BDOS, TOXP), and ngspice's guards
on each denominator kept as written.

**Charges** (capMod 2): the accumulation, depletion and inversion charges with the
centroid ``C_oxeff`` of each (``Δφ_s`` by MOIN), partitioned by XPART.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from ..errors import ModelError
from ._bsim3 import inversion_charges, saturation_voltage

KBOQ = 8.617087e-5
EPS0 = 8.85418e-12
EPSSI = 1.03594e-10
CHARGE_Q = 1.60219e-19
#: const.h's CHARGE, which BSIM4v7polyDepletion reads (b4v7ld.c's own Charge_q elsewhere)
CHARGE = 1.6021766208e-19
PI = 3.141592654
MAX_EXP = 5.834617425e14
MIN_EXP = 1.713908431e-15
EXP_THRESHOLD = 34.0
DELTA_1 = 0.02
DELTA_3 = 0.02
DELTA_4 = 0.02
CELSIUS = 273.15

#: the binnable parameters read here (each also with an L, W and P prefix), with
#: ngspice's defaults (``None``: derived in :func:`size_dependent` when not given)
BINNED = {
    "cdsc": 2.4e-4, "cdscb": 0.0, "cdscd": 0.0, "cit": 0.0, "nfactor": 1.0, "xj": 0.15e-6,
    "vsat": 8.0e4, "a0": 1.0, "ags": 0.0, "a1": 0.0, "a2": 1.0, "keta": -0.047,
    "nsub": 6.0e16, "ndep": 1.7e17, "nsd": 1.0e20, "phin": 0.0, "ngate": 0.0,
    "gamma1": None, "gamma2": None, "vbx": None, "vbm": -3.0, "xt": 1.55e-7, "vfb": None,
    "k1": None, "k2": None, "k3": 80.0, "k3b": 0.0, "w0": 2.5e-6, "lpe0": 1.74e-7,
    "lpeb": 0.0, "dvtp0": 0.0, "dvtp1": 0.0, "dvtp2": 0.0, "dvtp3": 0.0, "dvtp4": 0.0,
    "dvtp5": 0.0, "dvt0": 2.2, "dvt1": 0.53, "dvt2": -0.032, "dvt0w": 0.0, "dvt1w": 5.3e6,
    "dvt2w": -0.032, "drout": 0.56, "dsub": None, "vth0": None, "ua": None, "ub": 1.0e-19,
    "uc": None, "ud": 0.0, "up": 0.0, "lp": 1.0e-8, "eu": None, "u0": None,
    "voff": -0.08, "minv": 0.0, "minvcv": 0.0, "fprout": 0.0, "pdits": 0.0,
    "pditsd": 0.0, "delta": 0.01, "rdsw": 200.0, "prwg": 1.0, "prwb": 0.0, "eta0": 0.08,
    "etab": -0.07, "pclm": 1.3, "pdiblc1": 0.39, "pdiblc2": 0.0086, "pdiblcb": 0.0,
    "pscbe1": 4.24e8, "pscbe2": 1.0e-5, "pvag": 0.0, "wr": 1.0, "dwg": 0.0, "dwb": 0.0,
    "b0": 0.0, "b1": 0.0, "alpha0": 0.0, "alpha1": 0.0, "beta0": 0.0, "agidl": 0.0,
    "bgidl": 2.3e9, "cgidl": 0.5, "egidl": 0.8, "agisl": None, "bgisl": None,
    "cgisl": None, "egisl": None, "cgsl": 0.0, "cgdl": 0.0, "ckappas": 0.6,
    "ckappad": None, "cf": None, "clc": 0.1e-6, "cle": 0.6, "acde": 1.0, "moin": 15.0,
    "noff": 1.0, "voffcv": 0.0,
    # gate tunnelling (igcMod/igbMod 1, b4v5set.c's defaults; None: by type)
    "aigc": None, "bigc": None, "cigc": None, "aigsd": None, "bigsd": None, "cigsd": None,
    "aigbacc": 1.36e-2, "bigbacc": 1.71e-3, "cigbacc": 0.075, "aigbinv": 1.11e-2,
    "bigbinv": 9.49e-4, "cigbinv": 0.006, "nigc": 1.0, "nigbacc": 1.0, "nigbinv": 3.0,
    "ntox": 1.0, "eigbinv": 1.1, "pigcd": 1.0, "poxedge": 1.0, "vfbsdoff": 0.0,
}  # fmt: skip
#: ``b4v5set.c``'s type-dependent defaults of the gate-to-channel and edge tunnelling
#: parameters: ``(NMOS, PMOS)``
TUNNEL_DEFAULTS = {"aigc": (1.36e-2, 9.80e-3), "bigc": (1.71e-3, 7.59e-4),
                   "cigc": (0.075, 0.03), "aigsd": (1.36e-2, 9.80e-3),
                   "bigsd": (1.71e-3, 7.59e-4), "cigsd": (0.075, 0.03)}  # fmt: skip
#: the model parameters read here that are not binned (``None``: derived)
MODEL = {
    "mobmod": 0.0, "binunit": 1.0, "capmod": 2.0, "toxe": 30.0e-10, "toxp": None,
    "toxm": None, "dtox": 0.0, "epsrox": 3.9, "tnom": None, "cgso": None, "cgdo": None,
    "cgbo": None, "xpart": 0.0, "rsh": 0.0, "lint": 0.0, "ll": 0.0, "llc": None,
    "lln": 1.0, "lw": 0.0, "lwc": None, "lwn": 1.0, "lwl": 0.0, "lwlc": None, "wint": 0.0,
    "wl": 0.0, "wlc": None, "wln": 1.0, "ww": 0.0, "wwc": None, "wwn": 1.0, "wwl": 0.0,
    "wwlc": None, "xl": 0.0, "xw": 0.0, "dwc": None, "dlc": None, "dwj": None,
    "lmin": 0.0, "lmax": 1.0, "wmin": 0.0, "wmax": 1.0, "voffl": 0.0, "ados": 1.0,
    "bdos": 1.0, "pditsl": 0.0, "rdswmin": 0.0, "dmcg": 0.0, "dmci": None, "dmdg": 0.0,
    "dmcgt": 0.0,
    # gate tunnelling, the gate electrode (rgateMod 1) and the body network (rbodyMod 1)
    "toxref": 30.0e-10, "dlcig": None, "rshg": 0.1, "xgw": 0.0, "xgl": 0.0, "ngcon": 1.0,
    "gbmin": 1.0e-12, "rbdb": 50.0, "rbsb": 50.0, "rbpb": 50.0, "rbps": 50.0, "rbpd": 50.0,
    # junctions (diomod 1): source, and the drain's defaulting to the source's
    "jss": 1.0e-4, "jsws": 0.0, "jswgs": 0.0, "njs": 1.0, "ijthsfwd": 0.1,
    "cjs": 5.0e-4, "cjsws": 5.0e-10, "cjswgs": None, "pbs": 1.0, "pbsws": 1.0,
    "pbswgs": None, "mjs": 0.5, "mjsws": 0.33, "mjswgs": None,
    "jsd": None, "jswd": None, "jswgd": None, "njd": None, "ijthdfwd": None,
    "cjd": None, "cjswd": None, "cjswgd": None, "pbd": None, "pbswd": None,
    "pbswgd": None, "mjd": None, "mjswd": None, "mjswgd": None,
}  # fmt: skip
#: the modes and the values built (any other refused by name)
MODES = {
    "mobmod": ((0.0, 1.0, 2.0), "mobMod 0, 1 and 2 (mobMod 3, the high-k model, is not built)"),
    "capmod": ((2.0,), "capMod 2, the charge-thickness model (capMod 0 and 1 are not built)"),
    "rdsmod": ((0.0,), "rdsMod 0 (internal bias-dependent R_ds; rdsMod 1's external "
               "source/drain resistors are not built)"),
    "igcmod": ((0.0, 1.0), "igcMod 0 and 1 (igcMod 2's V_th-referred current is not built)"),
    "igbmod": ((0.0, 1.0), "igbMod 0 and 1"),
    "rbodymod": ((0.0, 1.0), "rbodyMod 0 and 1 (rbodyMod 2's scalable network is not built)"),
    "rgatemod": ((0.0, 1.0), "rgateMod 0 and 1 (rgateMod 2 and 3, the bias-dependent "
                 "intrinsic-input resistance, are not built)"),
    "trnqsmod": ((0.0,), "trnqsMod 0 (the transient non-quasi-static charge is not built)"),
    "acnqsmod": ((0.0,), "acnqsMod 0 (the AC non-quasi-static model is not built)"),
    "geomod": ((0.0,), "geoMod 0 (isolated source and drain)"),
    "rgeomod": ((0.0,), "rgeoMod 0 (no diffusion resistance from the layout)"),
    "permod": ((1.0,), "perMod 1 (PS/PD include the gate edge)"),
    "tempmod": ((0.0,), "tempMod 0"),
    "diomod": ((1.0,), "dioMod 1 (resistance-free diode, no breakdown)"),
    "gidlmod": ((0.0,), "gidlMod 0 (the 4.7 GIDL/GISL model, gidlMod 1, is not built)"),
    "mtrlmod": ((0.0,), "mtrlMod 0 (the high-k material parameters are not built)"),
    "cvchargemod": ((0.0,), "cvchargeMod 0"),
    "wpemod": ((0.0,), "wpeMod 0 (the well proximity effect is not built)"),
}  # fmt: skip
#: parameters that have no effect at the default modes and T = TNOM (the temperature
#: coefficients, the noise and the refused modes' parameters): read and left aside
INERT = frozenset("""
ute ucste kt1 kt1l kt2 ua1 ub1 uc1 ud1 at prt tvoff tnfactor teta0 tvoffcv tvfbsdoff
xti xtis xtid tpb tpbsw tpbswg tcj tcjsw tcjswg tnjts tnjtssw tnjtsswg tnjtsd
tnjtsswd tnjtsswgd tku0 kvsat tbgasub tbgbsub bg0sub tempeot
noia noib noic em ef af kf ntnoi lintnoi tnoia tnoib rnoia rnoib tnoimod fnoimod
aigs bigs cigs aigd bigd cigd dlcigd xrcrg1 xrcrg2 rbps0
rbpd0 rbpbx0 rbpby0 rbsbx0 rbsby0 rbdbx0 rbdby0 rbpsl rbpsw rbpsnf rbpdl rbpdw rbpdnf
rbpbxl rbpbxw rbpbxnf rbpbyl rbpbyw rbpbynf rbsdbxl rbsdbxw rbsdbxnf rbsdbyl rbsdbyw
rbsdbynf rdw rsw rdwmin rswmin vfbcv bvs bvd xjbvs xjbvd ijthsrev ijthdrev
vgs_max vgd_max vgb_max vds_max vbs_max vbd_max vgsr_max vgdr_max vgbr_max vbsr_max
vbdr_max paramchk noimod
""".split())  # fmt: skip
#: binnable parameters that are inert (their L/W/P forms too)
INERT_BINNED = frozenset("""
at kt1 kt1l kt2 ua1 ub1 uc1 ud1 ute prt tvoff tnfactor teta0 tvoffcv tvfbsdoff ucste
aigs bigs cigs aigd bigd cigd xrcrg1 xrcrg2 rdw rsw vfbcv
""".split())  # fmt: skip
#: every name of a card accepted (but LEVEL, VERSION and the mode selectors)
NAMES = (
    frozenset(MODEL)
    | frozenset(BINNED)
    | {p + k for k in BINNED for p in "lwp"}
    | INERT
    | INERT_BINNED
    | {p + k for k in INERT_BINNED for p in "lwp"}
    | frozenset(MODES)
)
#: a parameter's built defaults that the card must keep (a value ≠ the default is refused)
FIXED = {
    "lambda": (0.0, "lambda (velocity overshoot) is not built"),
    "vtl": (None, "vtl (the source-end velocity limit) is not built"),
    "jtss": (0.0, "jtss (trap-assisted tunnelling) is not built"),
    "jtsd": (0.0, "jtsd (trap-assisted tunnelling) is not built"),
    "jtssws": (0.0, "jtssws (trap-assisted tunnelling) is not built"),
    "jtsswd": (0.0, "jtsswd (trap-assisted tunnelling) is not built"),
    "jtsswgs": (0.0, "jtsswgs (trap-assisted tunnelling) is not built"),
    "jtsswgd": (0.0, "jtsswgd (trap-assisted tunnelling) is not built"),
}


#: bsim4v7's parameters that ngspice's bsim4v5 (VERSION 4.0–4.5) does not have: it
#: ignores them ("unrecognized parameter"), and so does diracvi, with a note
ONLY_47 = frozenset(
    {"dvtp2", "dvtp3", "dvtp4", "dvtp5", "ados", "bdos", "agisl", "bgisl", "cgisl", "egisl",
     "minvcv", "voffcvl", "gidlmod", "mtrlmod", "cvchargemod", "ucs", "ucste", "tnfactor",
     "teta0", "tvoffcv"}
    | {p + k for k in ("dvtp2", "dvtp3", "dvtp4", "dvtp5", "agisl", "bgisl", "cgisl",
                       "egisl", "minvcv", "ucs", "ucste", "tnfactor", "teta0", "tvoffcv")
       for p in "lwp"}
)  # fmt: skip


def version_code(version) -> int:
    """The ngspice model a BSIM4 VERSION runs (``inpdomod.c``): 47 (4.7: ``bsim4v7``) or
    45 (4.0–4.5: ``bsim4v5``); 4.6 and 4.8 (``bsim4v6``, ``bsim4``) are not built."""
    text = "4.8.3" if version is None else (f"{version:g}" if isinstance(version, float)
                                           else str(version))  # fmt: skip
    if text.startswith("4.7"):
        return 47
    if text[:3] in ("4.0", "4.1", "4.2", "4.3", "4.4", "4.5"):
        return 45
    raise ModelError(
        f"BSIM4 VERSION={text} is not supported: diracvi has ngspice's bsim4v7 (4.7) and "
        "bsim4v5 (4.0–4.5); ngspice runs 4.6 and 4.8 (its default) with other models."
    )


def _theta(x):
    """``e^{x}/((e^{x} − 1)² + 2 e^{x} MIN_EXP)``, ``1/(MAX_EXP − 2)`` at ``x ≥ 34``."""
    xs = jnp.minimum(x, EXP_THRESHOLD - 1.0)
    t1 = jnp.exp(xs)
    t2 = jnp.expm1(xs)
    val = t1 / (t2 * t2 + 2.0 * t1 * MIN_EXP)
    return jnp.where(x < EXP_THRESHOLD, val, 1.0 / (MAX_EXP - 2.0))


def _dexp(a):
    """ngspice's ``DEXP``: ``e^a``, continued linearly above 34, MIN_EXP below −34."""
    return jnp.where(
        a > EXP_THRESHOLD,
        MAX_EXP * (1.0 + a - EXP_THRESHOLD),
        jnp.where(a < -EXP_THRESHOLD, MIN_EXP, jnp.exp(jnp.clip(a, -EXP_THRESHOLD, EXP_THRESHOLD))),
    )


def _sqrt(x):
    return jnp.sqrt(jnp.maximum(x, 1e-300))


def _zero_at_vds0(x, vds):
    """``x`` with ngspice's ``V_dseff = 0`` at ``V_DS = 0`` exactly: the value 0 there, its
    derivative kept (b4v7ld.c zeroes the value and leaves ``∂V_dseff/∂V_DS``, so that the
    conductance at ``V_DS = 0`` is the one on either side, not 0)."""
    return jnp.where(vds == 0.0, x - jax.lax.stop_gradient(x), x)


def _float(x) -> bool:
    return isinstance(x, float)


def model_values(card: dict, sign: float) -> dict:
    """The model (non-binned) parameters with ngspice's derived defaults (``b4v7set.c``,
    the start of ``b4v7temp.c``)."""
    m = {k: card.get(k, v) for k, v in MODEL.items()}
    toxe_given, toxp_given = "toxe" in card, "toxp" in card
    if toxe_given and not toxp_given:
        m["toxp"] = m["toxe"] - m["dtox"]
    elif toxp_given and not toxe_given:
        m["toxe"] = m["toxp"] + m["dtox"]
    elif not toxp_given:
        m["toxp"] = m["toxe"]
    if m["toxm"] is None:
        m["toxm"] = m["toxe"]
    for base, derived in (
        ("llc", "ll"),
        ("lwc", "lw"),
        ("lwlc", "lwl"),
        ("wlc", "wl"),
        ("wwc", "ww"),
        ("wwlc", "wwl"),
        ("dwc", "wint"),
        ("dlc", "lint"),
    ):
        if m[base] is None:
            m[base] = m[derived]  # fmt: skip
    if m["dwj"] is None:
        m["dwj"] = m["dwc"]
    if m["dlcig"] is None:
        m["dlcig"] = m["lint"]
    if m["dmci"] is None:
        m["dmci"] = m["dmcg"]
    for k, src in (("cjswgs", "cjsws"), ("pbswgs", "pbsws"), ("mjswgs", "mjsws")):
        if m[k] is None:
            m[k] = m[src]
    for d, s in (("jsd", "jss"), ("jswd", "jsws"), ("jswgd", "jswgs"), ("njd", "njs"),
                 ("ijthdfwd", "ijthsfwd"), ("cjd", "cjs"), ("cjswd", "cjsws"),
                 ("cjswgd", "cjswgs"), ("pbd", "pbs"), ("pbswd", "pbsws"),
                 ("pbswgd", "pbswgs"), ("mjd", "mjs"), ("mjswd", "mjsws"),
                 ("mjswgd", "mjswgs")):  # fmt: skip
        if m[d] is None:
            m[d] = m[s]
    for k in ("pbs", "pbsws", "pbswgs", "pbd", "pbswd", "pbswgd"):  # b4v7temp.c's floor
        m[k] = max(m[k], 0.1)
    for k in ("ijthsfwd", "ijthdfwd"):
        m[k] = max(m[k], 0.0)
    for k in ("cjsws", "cjswd"):
        m[k] = max(m[k], 0.0)
    m["mobmod"] = float(card.get("mobmod", 0.0))
    return m


def size_dependent(card: dict, sign: float, l: float, w: float, delvto=0.0, mulu0=1.0,  # noqa: E741
                   revision=47):  # fmt: skip
    r"""The size-dependent parameters of a device of drawn ``l`` × ``w`` (m; NF = 1)
    from the card's **given** values ``card``, ``sign`` = type, at TNOM (module
    docstring; ``b4v7temp.c``). Returns a dict of floats or traced values."""
    m = model_values(card, sign)
    toxe, toxp, epsrox = m["toxe"], m["toxp"], m["epsrox"]
    coxe = epsrox * EPS0 / toxe
    coxp = epsrox * EPS0 / toxp
    epssub = EPSSI
    mob = int(m["mobmod"])
    base = {}
    for k, d in BINNED.items():
        if k in card:
            base[k] = card[k]
        elif k == "dsub":
            base[k] = card.get("drout", BINNED["drout"])
        elif k == "vth0":
            base[k] = 0.7 * sign
        elif k == "ua":
            base[k] = 1.0e-15 if mob == 2 else 1.0e-9
        elif k == "uc":
            base[k] = -0.0465 if mob == 1 else -0.0465e-9
        elif k in TUNNEL_DEFAULTS:
            base[k] = TUNNEL_DEFAULTS[k][0 if sign > 0 else 1]
        elif k == "ud" and revision == 45:
            base[k] = 1.0e14  # b4v5set.c's default (b4v7set.c's is 0)
        elif k == "eu":
            base[k] = 1.67 if sign > 0 else 1.0
        elif k == "u0":
            base[k] = 0.067 if sign > 0 else 0.025
        elif k == "cf":
            base[k] = 2.0 * epsrox * EPS0 / PI * math.log(1.0 + 0.4e-6 / toxe)
        elif k == "ckappad":
            base[k] = card.get("ckappas", BINNED["ckappas"])
        elif k in ("agisl", "bgisl", "cgisl", "egisl") and revision == 45:
            base[k] = 0.0  # bsim4v5's GISL reads AGIDL … EGIDL (set below)
        elif k in ("agisl", "bgisl", "cgisl", "egisl"):
            gidl = "agidl bgidl cgidl egidl".split()["agisl bgisl cgisl egisl".split().index(k)]
            base[k] = card[gidl] if gidl in card else ({"agisl": 0.0, "bgisl": 2.3e9,
                                                       "cgisl": 0.5, "egisl": 0.8}[k])  # fmt: skip
        else:
            base[k] = 0.0 if d is None else d
    # b4v7mpar.c reads NDEP above 1e20 and NSD, NGATE above 1.000001e24 (their L, W, P
    # terms above 1e23) as m⁻³
    for k, (top, binned_top) in (("ndep", (1.0e20, 1.0e20)), ("nsd", (1.000001e24, 1.0e23)),
                                 ("ngate", (1.000001e24, 1.0e23))):  # fmt: skip
        for pre in ("", "l", "w", "p"):
            x = card.get(pre + k)
            if _float(x) and x > (binned_top if pre else top):
                card = card | {pre + k: x * 1e-6}
                if not pre:
                    base[k] = x * 1e-6
    lnew, wnew = l + m["xl"], w + m["xw"]
    t0, t1 = lnew ** m["lln"], wnew ** m["lwn"]
    dl = m["lint"] + m["ll"] / t0 + m["lw"] / t1 + m["lwl"] / (t0 * t1)
    dlc = m["dlc"] + m["llc"] / t0 + m["lwc"] / t1 + m["lwlc"] / (t0 * t1)
    t2, t3 = lnew ** m["wln"], wnew ** m["wwn"]
    tmp = m["wl"] / t2 + m["ww"] / t3 + m["wwl"] / (t2 * t3)
    dw = m["wint"] + tmp
    tmpc = m["wlc"] / t2 + m["wwc"] / t3 + m["wwlc"] / (t2 * t3)
    dwc = m["dwc"] + tmpc
    dwj = m["dwj"] + tmpc
    leff, weff = lnew - 2.0 * dl, wnew - 2.0 * dw
    leffcv, weffcv, weffcj = lnew - 2.0 * dlc, wnew - 2.0 * dwc, wnew - 2.0 * dwj
    for what, x in (("L_eff", leff), ("W_eff", weff), ("L_eff,CV", leffcv),
                    ("W_eff,CV", weffcv), ("W_eff,CJ", weffcj)):  # fmt: skip
        if _float(x) and x <= 0.0:
            raise ModelError(
                f"BSIM4: the effective channel {what} = {x:g} m must be > 0 (l={l:g}, w={w:g};"
                " LINT/WINT/DLC/DWC/DWJ and their L/W terms shorten it)."
            )
    unit = 1.0e-6 if m["binunit"] == 1.0 else 1.0
    inv_l, inv_w, inv_lw = unit / leff, unit / weff, unit * unit / (leff * weff)
    p = {k: base[k] + card.get("l" + k, 0.0) * inv_l + card.get("w" + k, 0.0) * inv_w
         + card.get("p" + k, 0.0) * inv_lw for k in BINNED}  # fmt: skip
    if revision == 45:  # no separate GISL parameters, no DITS shift, no ADOS/BDOS
        for k in ("agisl", "bgisl", "cgisl", "egisl"):
            p[k] = p["agidl bgidl cgidl egidl".split()["agisl bgisl cgisl egisl".split().index(k)]]
        for k in ("dvtp2", "dvtp3", "dvtp4", "dvtp5"):
            p[k] = 0.0
        m["ados"] = m["bdos"] = 1.0
    p.update(leff=leff, weff=weff, leffcv=leffcv, weffcv=weffcv, weffcj=weffcj, coxe=coxe,
             coxp=coxp, toxe=toxe, toxp=toxp, toxm=m["toxm"], sign=sign)  # fmt: skip
    tnom = CELSIUS + card["tnom"] if "tnom" in card else 300.15
    vtm0 = KBOQ * tnom
    eg0 = 1.16 - 7.02e-4 * tnom * tnom / (tnom + 1108.0)
    ni = (
        1.45e10
        * (tnom / 300.15)
        * math.sqrt(tnom / 300.15)
        * math.exp(21.5565981 - eg0 / (2.0 * vtm0))
    )
    p["vtm"] = vtm0
    p["factor1"] = math.sqrt(epssub / (epsrox * EPS0) * toxe)
    p["abulkcvfactor"] = 1.0 + (p["clc"] / leffcv) ** p["cle"]
    p["vsattemp"] = p["vsat"]
    pow_weff_wr = (weffcj * 1.0e6) ** p["wr"]
    p["rds0"] = p["rdsw"] / pow_weff_wr
    p["rdswmin"] = m["rdswmin"] / pow_weff_wr
    u0 = p["u0"]
    u0 = jnp.where(u0 > 1.0, u0 / 1.0e4, u0) if not _float(u0) else (u0 / 1.0e4 if u0 > 1.0 else u0)
    p["u0temp"] = u0 * (1.0 - p["up"] * jnp.exp(-leff / p["lp"])) * mulu0
    p["eu"] = jnp.maximum(p["eu"], 0.0)
    p["cgdo_eff"] = None
    if "ndep" not in card and "gamma1" in card:
        p["ndep"] = 3.01248e22 * (p["gamma1"] * coxe) ** 2
    ndep = p["ndep"]
    phi = vtm0 * jnp.log(ndep / ni) + p["phin"] + 0.4
    p["phi"] = phi
    p["sqrtphi"] = jnp.sqrt(phi)
    xdep0 = jnp.sqrt(2.0 * epssub / (CHARGE_Q * ndep * 1.0e6)) * p["sqrtphi"]
    p["xdep0"] = xdep0
    # bsim4v5: √(3 XJ TOXE); bsim4v7 scales it by 3.9/EPSROX
    p["litl"] = jnp.sqrt((3.0 if revision == 45 else 3.0 * 3.9 / epsrox) * p["xj"] * toxe)
    p["vbi"] = vtm0 * jnp.log(p["nsd"] * ndep / (ni * ni))
    p["cdep0"] = jnp.sqrt(CHARGE_Q * epssub * ndep * 1.0e6 / 2.0 / phi)
    p["mstar"] = 0.5 + jnp.arctan(p["minv"]) / PI
    p["voffcbn"] = p["voff"] + m["voffl"] / leff
    p["ldeb"] = jnp.sqrt(epssub * vtm0 / (CHARGE_Q * ndep * 1.0e6)) / 3.0
    p["acde"] = p["acde"] * (ndep / 2.0e16) ** -0.25
    if "k1" in card or "k2" in card:
        if "k1" not in card:
            p["k1"] = 0.53
        if "k2" not in card:
            p["k2"] = -0.0186
    else:
        vbx = p["vbx"] if "vbx" in card else phi - 7.7348e-4 * ndep * p["xt"] ** 2
        vbx = -jnp.abs(vbx)
        p["vbm"] = -jnp.abs(p["vbm"])
        g1 = p["gamma1"] if "gamma1" in card else 5.753e-12 * jnp.sqrt(ndep) / coxe
        g2 = p["gamma2"] if "gamma2" in card else 5.753e-12 * jnp.sqrt(p["nsub"]) / coxe
        t1 = jnp.sqrt(phi - vbx) - p["sqrtphi"]
        t2 = jnp.sqrt(phi * (phi - p["vbm"])) - phi
        p["k2"] = (g1 - g2) * t1 / (2.0 * t2 + p["vbm"])
        p["k1"] = g2 - 2.0 * p["k2"] * jnp.sqrt(phi - p["vbm"])
    k1, k2 = p["k1"], p["k2"]
    if "vfb" not in card:
        p["vfb"] = (sign * p["vth0"] - phi - k1 * p["sqrtphi"]) if "vth0" in card else -1.0
    if "vth0" not in card:
        p["vth0"] = sign * (p["vfb"] + phi + k1 * p["sqrtphi"])
    p["k1ox"] = k1 * toxe / m["toxm"]
    tmp = jnp.sqrt(epssub / (epsrox * EPS0) * toxe * xdep0)
    p["theta0vb0"] = _theta(p["dsub"] * leff / tmp)
    p["thetarout"] = p["pdiblc1"] * _theta(p["drout"] * leff / tmp) + p["pdiblc2"]
    tmp2 = p["factor1"] * jnp.sqrt(xdep0)
    v0 = p["vbi"] - phi
    t8 = p["dvt0w"] * _theta(p["dvt1w"] * weff * leff / tmp2) * v0
    t9 = p["dvt0"] * _theta(p["dvt1"] * leff / tmp2) * v0
    t4 = toxe * phi / (weff + p["w0"])
    t5 = p["k1ox"] * (jnp.sqrt(1.0 + p["lpe0"] / leff) - 1.0) * p["sqrtphi"]
    vfbzbfactor = -t8 - t9 + p["k3"] * t4 + t5 - phi - k1 * p["sqrtphi"]
    # 4.7's DITS (b4v7temp.c): DVTP2f = DVTP5 + DVTP2 e^{−DVTP3 ln L}
    p["dvtp2factor"] = p["dvtp5"] + p["dvtp2"] * _dexp(-p["dvtp3"] * jnp.log(leff))
    # the instance's values (b4v7temp.c, no stress or well-proximity effect)
    vth0 = p["vth0"] + delvto
    vfb = p["vfb"] + sign * delvto
    p["vth0"], p["vfb"] = vth0, vfb
    t3 = sign * vth0 - vfb - phi
    p["vtfbphi1"] = jnp.maximum(2.0 * t3 if sign > 0 else 2.5 * t3, 0.0)
    p["vtfbphi2"] = jnp.maximum(4.0 * t3, 0.0)
    vbsc = jnp.where(
        k2 < 0.0,
        jnp.clip(0.9 * (phi - (0.5 * k1 / jnp.where(k2 < 0.0, k2, -1.0)) ** 2), -30.0, -3.0),
        -30.0,
    )
    p["vbsc"] = jnp.minimum(vbsc, p["vbm"])
    p["k2ox"] = k2 * toxe / m["toxm"]
    p["vfbzb"] = vfbzbfactor + sign * vth0
    # the overlaps (b4v7temp.c)
    cgdo, cgso, cgbo = (card.get(k) for k in ("cgdo", "cgso", "cgbo"))
    dlc_card = card.get("dlc")
    if cgdo is None:
        cgdo = (dlc_card * coxe - p["cgdl"] if dlc_card is not None and dlc_card > 0.0
                else 0.6 * m_xj(card) * coxe)  # fmt: skip
    if cgso is None:
        cgso = (dlc_card * coxe - p["cgsl"] if dlc_card is not None and dlc_card > 0.0
                else 0.6 * m_xj(card) * coxe)  # fmt: skip
    if cgbo is None:
        cgbo = 2.0 * m["dwc"] * coxe
    p["cgdo_eff"] = (cgdo + p["cf"]) * weffcv
    p["cgso_eff"] = (cgso + p["cf"]) * weffcv
    p["cgbo_eff"] = cgbo * leffcv
    p.update(_tunnelling_values(p, m, sign, vtm0))
    p["model"] = m
    p["revision"] = revision
    return p


def _tunnelling_values(p: dict, m: dict, sign: float, vtm0: float) -> dict:
    r"""The gate tunnelling's size-dependent prefactors (``b4v5temp.c``): ``A = A₀ W_eff
    L_eff R_tox``, ``B = −B₀ TOXE`` (``A₀, B₀`` = 4.97232e-7, 7.45669e11 for NMOS and
    3.42537e-7, 1.16645e12 for PMOS), ``R_tox = (TOXREF/TOXE)^NTOX / TOXE²``, the edge's
    ``A_edge = A₀ W_eff DLCIG R_tox,edge`` and ``B_edge = −B₀ TOXE POXEDGE`` with
    ``R_tox,edge = (TOXREF/(TOXE POXEDGE))^NTOX / (TOXE POXEDGE)²``, and the source/drain
    flat band ``V_fbsd = V_tm ln(NGATE/NSD)`` (0 for NGATE ≤ 0)."""
    toxe, ntox, pox = p["toxe"], p["ntox"], p["poxedge"]
    a0, b0 = (4.97232e-7, 7.45669e11) if sign > 0 else (3.42537e-7, 1.16645e12)
    ratio = jnp.exp(ntox * jnp.log(m["toxref"] / toxe)) / toxe / toxe
    edge = jnp.exp(ntox * jnp.log(m["toxref"] / (toxe * pox))) / toxe / toxe / pox / pox
    ngate = p["ngate"]
    vfbsd = jnp.where(ngate > 0.0, vtm0 * jnp.log(jnp.where(ngate > 0.0, ngate, 1.0) / p["nsd"]),
                      0.0)  # fmt: skip
    return {"toxratio": ratio, "aechvb": a0 * p["weff"] * p["leff"] * ratio,
            "bechvb": -b0 * toxe, "aechvbedge": a0 * p["weff"] * m["dlcig"] * edge,
            "bechvbedge": -b0 * toxe * pox, "vfbsd": vfbsd}  # fmt: skip


def m_xj(card):
    """The model-level XJ (b4v7temp.c's CGSO/CGDO default reads the card's XJ, unbinned)."""
    return card.get("xj", BINNED["xj"])


def branches(p: dict) -> tuple:
    """The forms :func:`evaluate` takes, decided once from known values: ``simple``
    (``V_dsat`` without R_ds and λ), ``a1`` (λ's form), ``poly`` (poly depletion),
    ``pocket`` (DVTP0 > 0), ``dits2`` (DVTP4 and DVTP2f ≠ 0), the terms that are off
    (``no_clm``, ``no_dibl``, ``no_dits``, ``no_scbe``, ``no_isub``, ``fprout``,
    ``no_gidl``, ``no_gisl``) and the charges' K1ox forms."""
    a1, a2, k1ox = p["a1"], p["a2"], p["k1ox"]
    lam = "zero" if _float(a1) and a1 == 0.0 else ("positive" if _float(a1) and a1 > 0.0
                                                  else "general")  # fmt: skip
    rds_zero = (
        _float(p["rds0"]) and p["rds0"] == 0.0 and _float(p["rdswmin"]) and p["rdswmin"] == 0.0
    )
    tmp = p["alpha0"] + p["alpha1"] * p["leff"]

    def known(x, test):
        return bool(_float(x) and test(x))

    gidl_off = not all(_float(p[k]) for k in ("agidl", "bgidl", "cgidl")) or (
        p["agidl"] <= 0.0 or p["bgidl"] <= 0.0 or p["cgidl"] <= 0.0)  # fmt: skip
    gisl_off = not all(_float(p[k]) for k in ("agisl", "bgisl", "cgisl")) or (
        p["agisl"] <= 0.0 or p["bgisl"] <= 0.0 or p["cgisl"] <= 0.0)  # fmt: skip
    return (
        ("simple", bool(rds_zero and lam == "zero" and known(a2, lambda x: x == 1.0))),
        ("a1", lam),
        ("rds_zero", bool(rds_zero)),
        ("poly", not _float(p["ngate"]) or 1.0e18 < p["ngate"] < 1.0e25),
        ("pocket", not _float(p["dvtp0"]) or p["dvtp0"] > 0.0),
        ("dits2", not (known(p["dvtp4"], lambda x: x == 0.0)
                       or known(p["dvtp2factor"], lambda x: x == 0.0))),
        ("no_clm", known(p["pclm"], lambda x: x <= MIN_EXP)),
        ("no_dibl", known(p["thetarout"], lambda x: x <= MIN_EXP)),
        ("no_dits", known(p["pdits"], lambda x: x <= MIN_EXP)),
        ("no_scbe", known(p["pscbe2"], lambda x: x <= 0.0)
         or (p["revision"] == 47 and known(p["pscbe1"], lambda x: x < 0.0))),
        ("no_isub", known(tmp, lambda x: x <= 0.0) or known(p["beta0"], lambda x: x <= 0.0)),
        ("fprout", not known(p["fprout"], lambda x: x <= 0.0)),
        ("no_gidl", bool(gidl_off and all(_float(p[k]) for k in ("agidl", "bgidl", "cgidl")))),
        ("no_gisl", bool(gisl_off and all(_float(p[k]) for k in ("agisl", "bgisl", "cgisl")))),
        ("k1ox_zero", known(k1ox, lambda x: x == 0.0)),
        ("k1ox_nonpositive", known(k1ox, lambda x: x <= 0.0)),
    )  # fmt: skip


def _poly(p, vgs):
    """The poly-gate depletion's ``V_gs,eff`` (``BSIM4v7polyDepletion``)."""
    phi_g = p["vfb"] + p["phi"]
    t1 = 1.0e6 * CHARGE * EPSSI * p["ngate"] / (p["coxe"] * p["coxe"])
    t8 = jnp.maximum(vgs - phi_g, 0.0)
    t4 = jnp.sqrt(1.0 + 2.0 * t8 / t1)
    t2 = 2.0 * t8 / (t4 + 1.0)
    t3 = 0.5 * t2 * t2 / t1
    t7 = 1.12 - t3 - 0.05
    t6 = jnp.sqrt(t7 * t7 + 0.224)
    t5 = 1.12 - 0.5 * (t7 + t6)
    return jnp.where(vgs > phi_g, vgs - t5, vgs)


def evaluate(p: dict, vgs, vds, vbs, *, mobmod=0, xpart=0.0, charges_only=False, extras=None):
    r"""``(I_ds, I_sub, (Q_g, Q_b, Q_d))`` of the NMOS-oriented mode (``V_DS ≥ 0``; the
    module docstring's current, ALPHA0/ALPHA1/BETA0's substrate current and capMod 2's
    intrinsic charges; ``None`` for the charges with XPART < 0). ``charges_only``: the
    charges alone (the currents ``None``). ``extras``, a dict, receives ``V_gs,eff``,
    ``V_bseff``, ``V_gsteff`` and ``V_dseff``, which :func:`tunnelling` reads."""
    if charges_only and xpart < 0.0:
        return None, None, None
    form = dict(p["branches"]) if "branches" in p else dict(branches(p))
    vtm = p["vtm"]
    coxe, toxe = p["coxe"], p["toxe"]
    leff = p["leff"]
    phi, sqrtphi = p["phi"], p["sqrtphi"]
    vbsc = p["vbsc"]
    # V_bseff: floored smoothly at V_bsc, then capped at 0.95Φ
    t0 = vbs - vbsc - 0.001
    t1 = jnp.sqrt(t0 * t0 - 0.004 * vbsc)
    vbseff = jnp.where(t0 >= 0.0, vbsc + 0.5 * (t0 + t1),
                       vbsc * (1.0 - 0.002 / jnp.where(t0 >= 0.0, 1.0, t1 - t0)))  # fmt: skip
    t9 = 0.95 * phi
    t0 = t9 - vbseff - 0.001
    t1 = jnp.sqrt(t0 * t0 + 0.004 * t9)
    vbseff = t9 - 0.5 * (t0 + t1)
    phis = phi - vbseff
    sqrtphis = jnp.sqrt(phis)
    xdep = p["xdep0"] * sqrtphis / sqrtphi
    # threshold
    t3 = jnp.sqrt(xdep)
    v0 = p["vbi"] - phi

    def _dvt2(dvt2):
        t = dvt2 * vbseff
        return jnp.where(t >= -0.5, 1.0 + t, (1.0 + 3.0 * t) / (3.0 + 8.0 * jnp.minimum(t, -0.5)))

    lt1 = p["factor1"] * t3 * _dvt2(p["dvt2"])
    ltw = p["factor1"] * t3 * _dvt2(p["dvt2w"])
    theta0 = _theta(p["dvt1"] * leff / lt1)
    delt_vth = p["dvt0"] * theta0 * v0
    t2w = p["dvt0w"] * _theta(p["dvt1w"] * p["weff"] * leff / ltw) * v0
    t1 = p["k1ox"] * (jnp.sqrt(1.0 + p["lpe0"] / leff) - 1.0) * sqrtphi
    vth_narrow = toxe * phi / (p["weff"] + p["w0"])
    t3e = p["eta0"] + p["etab"] * vbseff
    t3e = jnp.where(t3e < 1.0e-4, (2.0e-4 - t3e) / (3.0 - 2.0e4 * jnp.minimum(t3e, 1e-4)), t3e)
    dibl = t3e * p["theta0vb0"] * vds
    lpe_vb = jnp.sqrt(1.0 + p["lpeb"] / leff)
    vth = (p["sign"] * p["vth0"] + (p["k1ox"] * sqrtphis - p["k1"] * sqrtphi) * lpe_vb
           - p["k2ox"] * vbseff - delt_vth - t2w + (p["k3"] + p["k3b"] * vbseff) * vth_narrow
           + t1 - dibl)  # fmt: skip
    # subthreshold swing
    tmp1 = EPSSI / xdep
    cdsc = p["cdsc"] + p["cdscb"] * vbseff + p["cdscd"] * vds
    tmp4 = (p["nfactor"] * tmp1 + cdsc * theta0 + p["cit"]) / coxe
    n = jnp.where(
        tmp4 >= -0.5, 1.0 + tmp4, (1.0 + 3.0 * tmp4) / (3.0 + 8.0 * jnp.minimum(tmp4, -0.5))
    )
    if form["pocket"]:  # the pocket implant's V_th shift
        t0 = -p["dvtp1"] * vds
        t2 = jnp.where(t0 < -EXP_THRESHOLD, MIN_EXP, jnp.exp(jnp.maximum(t0, -EXP_THRESHOLD)))
        t3p = leff + p["dvtp0"] * (1.0 + t2)
        vth = vth - jnp.where(p["dvtp0"] > 0.0, n * vtm * jnp.log(leff / t3p), 0.0)
    if form["dits2"]:  # 4.7's DITS shift
        t0 = _dexp(2.0 * p["dvtp4"] * vds)
        vth = vth - p["dvtp2factor"] * (t0 - 1.0) / (t0 + 1.0)
    vgs_eff = _poly(p, vgs) if form["poly"] else vgs
    vgst = vgs_eff - vth
    # V_gsteff
    t0 = n * vtm
    mstar = p["mstar"]
    t1 = mstar * vgst
    t2 = t1 / t0
    t10 = jnp.where(
        t2 > EXP_THRESHOLD, t1,
        jnp.where(t2 < -EXP_THRESHOLD, t0 * math.log(1.0 + MIN_EXP),
                  t0 * jnp.log1p(jnp.exp(jnp.clip(t2, -EXP_THRESHOLD, EXP_THRESHOLD)))),
    )  # fmt: skip
    t1 = p["voffcbn"] - (1.0 - mstar) * vgst
    t2 = t1 / t0
    e2 = jnp.where(t2 < -EXP_THRESHOLD, MIN_EXP,
                   jnp.where(t2 > EXP_THRESHOLD, MAX_EXP,
                             jnp.exp(jnp.clip(t2, -EXP_THRESHOLD, EXP_THRESHOLD))))  # fmt: skip
    vgsteff = t10 / (mstar + n * coxe / p["cdep0"] * e2)
    # A_bulk
    t9 = 0.5 * p["k1ox"] * lpe_vb / sqrtphis
    t1a = t9 + p["k2ox"] - p["k3b"] * vth_narrow
    t9 = jnp.sqrt(p["xj"] * xdep)
    t5 = leff / (leff + 2.0 * t9)
    t2 = p["a0"] * t5 + p["b0"] / (p["weff"] + p["b1"])
    abulk0 = 1.0 + t1a * t2
    abulk = abulk0 - t1a * p["ags"] * p["a0"] * t5**3 * vgsteff

    def _floor01(a):
        return jnp.where(a < 0.1, (0.2 - a) / (3.0 - 20.0 * jnp.minimum(a, 0.1)), a)

    abulk0, abulk = _floor01(abulk0), _floor01(abulk)
    t2k = p["keta"] * vbseff
    kf = jnp.where(
        t2k >= -0.9, 1.0 / (1.0 + t2k), (17.0 + 20.0 * t2k) / (0.8 + jnp.minimum(t2k, -0.9))
    )
    abulk, abulk0 = abulk * kf, abulk0 * kf
    if charges_only:
        return None, None, _charges(p, form, xpart, vgs_eff, vbseff, vth, n, vgst, abulk0, vds)
    # effective width and R_ds
    t9 = sqrtphis - sqrtphi
    weff = p["weff"] - 2.0 * (p["dwg"] * vgsteff + p["dwb"] * t9)
    weff = jnp.where(
        weff < 2.0e-8, 2.0e-8 * (4.0e-8 - weff) / (6.0e-8 - 2.0 * jnp.minimum(weff, 2e-8)), weff
    )
    t2r = 1.0 / (1.0 + p["prwg"] * vgsteff) + p["prwb"] * t9
    rds = p["rdswmin"] + (t2r + jnp.sqrt(t2r * t2r + 0.01)) * p["rds0"] * 0.5
    if form["rds_zero"]:
        rds = 0.0 * vgsteff
    # mobility
    if p["revision"] == 45:  # bsim4v5's Coulomb term: UD/(T₀/TOXE)² V_th²
        t0u = (vgsteff + p["vtfbphi1"]) / toxe**2 if mobmod == 2 else (vgsteff + 2.0 * vth) / toxe
        t6 = p["ud"] / (t0u * t0u) * vth * vth
    else:
        t12 = jnp.sqrt(vth * vth + 0.0001)
        t10m = toxe / (vgsteff + 2.0 * t12)
        t6 = p["ud"] * t10m * t10m * vth * vth
    if mobmod == 0:
        t3m = (vgsteff + 2.0 * vth) / toxe
        t5m = t3m * (p["ua"] + p["uc"] * vbseff + p["ub"] * t3m) + t6
    elif mobmod == 1:
        t3m = (vgsteff + 2.0 * vth) / toxe
        t5m = t3m * (p["ua"] + p["ub"] * t3m) * (1.0 + p["uc"] * vbseff) + t6
    else:
        t0m = (vgsteff + p["vtfbphi1"]) / toxe
        t5m = jnp.exp(p["eu"] * jnp.log(t0m)) * (p["ua"] + p["uc"] * vbseff) + t6
    denomi = jnp.where(t5m >= -0.8, 1.0 + t5m, (0.6 + t5m) / (7.0 + 10.0 * jnp.minimum(t5m, -0.8)))
    ueff = p["u0temp"] / denomi
    # V_dsat
    wvcox = weff * p["vsattemp"] * coxe
    wvcoxrds = wvcox * rds
    esat = 2.0 * p["vsattemp"] / ueff
    esatl = esat * leff
    lam, vgst2vtm, vdsat = saturation_voltage(p, form, vgsteff, vtm, abulk, esatl, wvcoxrds)
    # V_dseff
    delta = p["delta"]
    t1d = vdsat - vds - delta
    t2d = jnp.sqrt(t1d * t1d + 4.0 * delta * vdsat)
    below = vdsat * (1.0 - 2.0 * delta / jnp.where(t1d >= 0.0, 1.0, t2d - t1d))
    vdseff = jnp.where(t1d >= 0.0, vdsat - 0.5 * (t1d + t2d), below)
    vdseff = _zero_at_vds0(vdseff, vds)
    vdseff = jnp.minimum(vdseff, vds)
    if extras is not None:
        extras.update(vgs_eff=vgs_eff, vbseff=vbseff, vgsteff=vgsteff, vdseff=vdseff)
    diffvds = vds - vdseff
    # V_Asat
    tmp4 = 1.0 - 0.5 * abulk * vdsat / vgst2vtm
    t0s = esatl + vdsat + 2.0 * wvcoxrds * vgsteff * tmp4
    t1s = 2.0 / lam - 1.0 + wvcoxrds * abulk
    vasat = t0s / t1s
    # I_dl with the centroid's C_oxeff
    t0c = (vgsteff + p["vtfbphi2"]) / (2.0e8 * p["toxp"])
    tcen = p["model"]["ados"] * 1.9e-9 / (1.0 + jnp.exp(p["model"]["bdos"] * 0.7 * jnp.log(t0c)))
    coxeff = EPSSI * p["coxp"] / (EPSSI + p["coxp"] * tcen)
    beta = ueff * coxeff * weff / leff
    fgche1 = vgsteff * (1.0 - 0.5 * vdseff * abulk / vgst2vtm)
    fgche2 = 1.0 + vdseff / esatl
    gche = beta * fgche1 / fgche2
    idl = gche / (1.0 + gche * rds)
    fp = 1.0 / (1.0 + p["fprout"] * jnp.sqrt(leff) / vgst2vtm) if form["fprout"] else 1.0
    t9p = p["pvag"] / esatl * vgsteff
    pvag = jnp.where(t9p > -0.9, 1.0 + t9p, (0.8 + t9p) / (17.0 + 20.0 * jnp.minimum(t9p, -0.9)))
    # V_ACLM
    clm_on = diffvds > 1.0e-10
    cclm = jnp.where(
        clm_on,
        fp * pvag * (1.0 + rds * idl) * (leff + vdsat / esat) / (p["pclm"] * p["litl"]),
        MAX_EXP,
    )
    vaclm = jnp.where(clm_on, cclm * diffvds, MAX_EXP)
    if form["no_clm"]:
        cclm = vaclm = MAX_EXP + 0.0 * vds
    # V_ADIBL
    t8 = abulk * vdsat
    vadibl = (vgst2vtm - vgst2vtm * t8 / (vgst2vtm + t8)) / p["thetarout"]
    t7 = p["pdiblcb"] * vbseff
    vadibl = vadibl * jnp.where(t7 >= -0.9, 1.0 / (1.0 + t7),
                                (17.0 + 20.0 * t7) / (0.8 + jnp.minimum(t7, -0.9)))  # fmt: skip
    vadibl = vadibl * pvag
    if form["no_dibl"]:
        vadibl = MAX_EXP + 0.0 * vds
    va = vasat + vaclm
    # V_ADITS
    if form["no_dits"]:
        vadits = MAX_EXP + 0.0 * vds
    else:
        t0 = p["pditsd"] * vds
        t1 = jnp.where(t0 > EXP_THRESHOLD, MAX_EXP, jnp.exp(jnp.minimum(t0, EXP_THRESHOLD)))
        vadits = (1.0 + (1.0 + p["model"]["pditsl"] * leff) * t1) / p["pdits"] * fp
    # V_ASCBE
    if form["no_scbe"]:
        vascbe = MAX_EXP + 0.0 * vds
    else:
        pl = p["pscbe1"] * p["litl"]
        big = diffvds > pl / EXP_THRESHOLD
        arg = pl / jnp.where(big, diffvds, 1.0)
        vascbe = jnp.where(big, leff * jnp.exp(jnp.minimum(arg, EXP_THRESHOLD)) / p["pscbe2"],
                           MAX_EXP * leff / p["pscbe2"])  # fmt: skip
    idsa = idl * (1.0 + diffvds / vadibl)
    idsa = idsa * (1.0 + diffvds / vadits)
    idsa = idsa * (1.0 + jnp.log(va / vasat) / cclm)
    # substrate current
    if form["no_isub"]:
        isub = 0.0 * idsa
    else:
        t2s = (p["alpha0"] + p["alpha1"] * leff) / leff
        big = diffvds > p["beta0"] / EXP_THRESHOLD
        dv = jnp.where(big, diffvds, 1.0)
        t1s = jnp.where(big, t2s * diffvds * jnp.exp(-p["beta0"] / dv), t2s * MIN_EXP * diffvds)
        isub = t1s * idsa * vdseff
    ids = idsa * (1.0 + diffvds / vascbe) * vdseff
    if xpart < 0.0:
        return ids, isub, None
    return ids, isub, _charges(p, form, xpart, vgs_eff, vbseff, vth, n, vgst, abulk0, vds)


def _exp_limited(x):
    """ngspice's guarded ``e^x`` of the tunnelling: MAX_EXP above 34, MIN_EXP below −34."""
    inside = jnp.exp(jnp.clip(x, -EXP_THRESHOLD, EXP_THRESHOLD))
    return jnp.where(x > EXP_THRESHOLD, MAX_EXP, jnp.where(x < -EXP_THRESHOLD, MIN_EXP, inside))


def _softplus(x, scale):
    """``scale·ln(1 + e^{x/scale})``: ``x`` above 34·scale, ``scale·ln(1 + MIN_EXP)``
    below −34·scale (ngspice's ``V_aux``)."""
    r = x / scale
    inside = scale * jnp.log1p(jnp.exp(jnp.clip(r, -EXP_THRESHOLD, EXP_THRESHOLD)))
    low = scale * math.log(1.0 + MIN_EXP)
    return jnp.where(r > EXP_THRESHOLD, x, jnp.where(r < -EXP_THRESHOLD, low, inside))


def _tunnel(a, b, c, vox, prefactor, exponent):
    """``prefactor·exp(exponent·(A + (A C − B) V_ox − B C V_ox²))`` with the guarded exp."""
    return prefactor * _exp_limited(exponent * (a + (a * c - b) * vox - b * c * vox * vox))


def tunnelling(p: dict, ex: dict, vgs, vgd, forward, igc: bool, igb: bool, pigcd_given: bool):
    r"""The gate tunnelling currents of bsim4v5 (``b4v5ld.c``), NMOS-oriented: ``(I_gs,
    I_gd, I_gb)`` from the gate to the true source, drain and bulk. ``ex`` is
    :func:`evaluate`'s ``extras`` of the mode, ``vgs``, ``vgd`` the true (type-multiplied)
    gate voltages, ``forward`` the mode.

    With ``V_fbeff = V_fbzb − ½(V₃ + √(V₃² ± 4δ₃V_fbzb))``, ``V₃ = V_fbzb − V_gs,eff +
    V_bseff − δ₃``, the oxide voltages ``V_ox,acc = max(V_fbzb − V_fbeff, 0)`` and
    ``V_ox,depinv = K1ox(√(K1ox²/4 + T) − K1ox/2) + V_gsteff`` (``−T + V_gsteff`` for ``T <
    0``), ``T = V_gs,eff − V_fbeff − V_bseff − V_gsteff``:

    * igcMod 1: ``I_gc = A V_gs,eff V_aux e^{B(AIGC + (AIGC·CIGC − BIGC)V_ox,depinv −
      BIGC·CIGC V_ox,depinv²)}``, ``V_aux = NIGC V_t ln(1 + e^{(V_gs,eff − V_th0)/NIGC V_t})``,
      split by ``T₇ = −PIGCD V_dseff`` into ``I_gcs = I_gc (e^{T₇} − 1 + 10⁻⁴ − T₇)/(T₇² +
      2·10⁻⁴)`` and ``I_gcd = I_gc (T₇e^{T₇} − e^{T₇} + 1 + 10⁻⁴)/(T₇² + 2·10⁻⁴)`` (PIGCD
      not given: ``B·TOXE/V_gsteff² (1 − V_dseff/2V_gsteff)``), the mode's source and drain;
      the edges ``I_gs = A_edge V_gs √((V_gs − V_fbsd)² + 10⁻⁴) e^{B_edge(…AIGSD, BIGSD,
      CIGSD…)}`` and ``I_gd`` alike;
    * igbMod 1: ``I_gb = I_gbacc + I_gbinv``, accumulation with ``V_ox,acc`` (NIGBACC,
      AIGBACC …), inversion with ``V_ox,depinv`` (``V_aux`` of ``V_ox,depinv − EIGBINV``
      over NIGBINV·V_t; AIGBINV …)."""
    vgs_eff, vbseff, vgsteff, vdseff = (ex[k] for k in ("vgs_eff", "vbseff", "vgsteff", "vdseff"))
    vtm = p["vtm"]
    zero = 0.0 * vgs_eff
    vfb = p["vfbzb"]
    v3 = vfb - vgs_eff + vbseff - DELTA_3
    t0 = jnp.sqrt(v3 * v3 + jnp.where(vfb <= 0.0, -4.0, 4.0) * DELTA_3 * vfb)
    vfbeff = vfb - 0.5 * (v3 + t0)
    voxacc = jnp.maximum(vfb - vfbeff, 0.0)
    k1ox = p["k1ox"]
    t3 = vgs_eff - vfbeff - vbseff - vgsteff
    if _float(k1ox) and k1ox == 0.0:
        voxdepinv = vgsteff
    else:
        half = 0.5 * k1ox
        root = jnp.sqrt(half * half + jnp.maximum(t3, 0.0))
        voxdepinv = jnp.where(t3 < 0.0, -t3, k1ox * (root - half)) + vgsteff
    i_gs = i_gd = i_gb = zero
    if igc:
        aux = _softplus(vgs_eff - p["sign"] * p["vth0"], vtm * p["nigc"])
        igc_ = _tunnel(p["aigc"], p["bigc"], p["cigc"], voxdepinv, p["aechvb"] * vgs_eff * aux,
                       p["bechvb"])  # fmt: skip
        if pigcd_given:
            pigcd = p["pigcd"]
        else:
            t12 = vgsteff + 1.0e-20
            pigcd = p["bechvb"] * p["toxe"] / t12 / t12 * (1.0 - 0.5 * vdseff / t12)
        t7 = -pigcd * vdseff
        t8 = t7 * t7 + 2.0e-4
        t9 = _exp_limited(t7)
        igcs = igc_ * (t9 - 1.0 + 1.0e-4 - t7) / t8
        igcd = igc_ * (t7 * t9 - (t9 - 1.0 - 1.0e-4)) / t8
        edge = []
        for v in (vgs, vgd):
            t0 = v - (p["vfbsd"] + p["vfbsdoff"])
            v_eff = jnp.sqrt(t0 * t0 + 1.0e-4)
            edge.append(_tunnel(p["aigsd"], p["bigsd"], p["cigsd"], v_eff,
                                p["aechvbedge"] * v * v_eff, p["bechvbedge"]))  # fmt: skip
        i_gs = edge[0] + jnp.where(forward, igcs, igcd)
        i_gd = edge[1] + jnp.where(forward, igcd, igcs)
    if igb:
        vgb = vgs_eff - vbseff
        aux = _softplus(-vgs_eff + vbseff + vfb, vtm * p["nigbacc"])
        t11 = 4.97232e-7 * p["weff"] * p["leff"] * p["toxratio"]
        t12 = -7.45669e11 * p["toxe"]
        acc = _tunnel(p["aigbacc"], p["bigbacc"], p["cigbacc"], voxacc, t11 * vgb * aux, t12)
        aux = _softplus(voxdepinv - p["eigbinv"], vtm * p["nigbinv"])
        inv = _tunnel(p["aigbinv"], p["bigbinv"], p["cigbinv"], voxdepinv,
                      0.75610 * t11 * vgb * aux, 1.31724 * t12)  # fmt: skip
        i_gb = acc + inv
    return i_gs, i_gd, i_gb


def gidl(p: dict, vds, vgs, vbs, form=None):
    """GIDL and GISL (gidlMod 0, ``b4v7ld.c``) of the true (NMOS-oriented) terminal
    voltages: ``(I_gidl, I_gisl)``, drain→bulk and source→bulk."""
    form = form if form is not None else dict(branches(p))
    vgd, vbd = vgs - vds, vbs - vds
    t0 = 3.0 * p["toxe"]
    out = []
    for key, on, vx, vgx, vbx in (("gidl", not form["no_gidl"], vds, vgs, vbd),
                                  ("gisl", not form["no_gisl"], -vds, vgd, vbs)):  # fmt: skip
        if not on:
            out.append(0.0 * vds)
            continue
        a, b, c, e = (p[k + key] for k in "abce")
        vg_eff = _poly(p, vgx) if form["poly"] else vgx
        t1 = (vx - vg_eff - e) / t0
        t1s = jnp.where(t1 > 0.0, t1, 1.0)
        t2 = b / t1s
        i = jnp.where(t2 < 100.0, a * p["weffcj"] * t1s * jnp.exp(-jnp.minimum(t2, 100.0)),
                      a * p["weffcj"] * 3.720075976e-44 * t1s)  # fmt: skip
        t5 = -vbx * vbx * vbx
        i = i * t5 / (c + t5)
        off = (t1 <= 0.0) | (vbx > 0.0)
        if not (_float(a) and _float(b) and _float(c)):
            off = off | (a <= 0.0) | (b <= 0.0) | (c <= 0.0)
        out.append(jnp.where(off, 0.0, i))
    return tuple(out)


def _charges(p, form, xpart, vgs_eff, vbseff, vth, n, vgst, abulk0, vds):
    """capMod 2's intrinsic ``(Q_g, Q_b, Q_d)`` (the charge-thickness model, ``b4v7ld.c``)."""
    vtm = p["vtm"]
    coxe, coxp = p["coxe"], p["coxp"]
    vbseffcv = vbseff  # (Φ − Φ_s is V_bseff itself)
    coxwl = coxe * p["weffcv"] * p["leffcv"]
    t0 = vtm * n * p["noff"]
    x = (vgst - p["voffcv"]) / t0
    vgsteff = jnp.where(
        x > EXP_THRESHOLD, vgst - p["voffcv"],
        jnp.where(x < -EXP_THRESHOLD, t0 * math.log(1.0 + MIN_EXP),
                  t0 * jnp.log1p(jnp.exp(jnp.clip(x, -EXP_THRESHOLD, EXP_THRESHOLD)))),
    )  # fmt: skip
    vfbzb = p["vfbzb"]
    v3 = vfbzb - vgs_eff + vbseffcv - DELTA_3
    t0 = jnp.sqrt(v3 * v3 + jnp.where(vfbzb <= 0.0, -4.0, 4.0) * DELTA_3 * vfbzb)
    vfbeff = vfbzb - 0.5 * (v3 + t0)
    tox = 1.0e8 * p["toxp"]
    tmp = (vgs_eff - vbseffcv - vfbzb) / tox * p["acde"]
    tcen = p["ldeb"] * jnp.where(
        tmp >= EXP_THRESHOLD, MAX_EXP,
        jnp.where(tmp <= -EXP_THRESHOLD, MIN_EXP,
                  jnp.exp(jnp.clip(tmp, -EXP_THRESHOLD, EXP_THRESHOLD))),
    )  # fmt: skip
    link = 1.0e-3 * p["toxp"]
    v3 = p["ldeb"] - tcen - link
    v4 = jnp.sqrt(v3 * v3 + 4.0 * link * p["ldeb"])
    tcen = p["ldeb"] - 0.5 * (v3 + v4)
    ccen = EPSSI / tcen
    coxeff = coxp / (coxp + ccen) * ccen
    coxwlcen = coxwl * coxeff / coxe
    qac0 = coxwlcen * (vfbeff - vfbzb)
    k1ox = p["k1ox"]
    t0 = 0.5 * k1ox
    t3 = vgs_eff - vfbeff - vbseffcv - vgsteff
    if form["k1ox_zero"]:
        qsub0 = 0.0 * t3
    else:
        t1 = jnp.where(t3 < 0.0, t0 + t3 / k1ox, _sqrt(t0 * t0 + jnp.maximum(t3, 0.0)))
        qsub0 = coxwlcen * k1ox * (t1 - t0)
    if form["k1ox_nonpositive"]:
        denomi = 0.25 * p["moin"] * vtm
        t0 = 0.5 * p["sqrtphi"]
    else:
        denomi = p["moin"] * vtm * k1ox * k1ox
        t0 = k1ox * p["sqrtphi"]
    deltaphi = vtm * jnp.log1p((2.0 * t0 + vgsteff) * vgsteff / denomi)
    t0 = vgsteff - deltaphi - 0.001
    vgdp = 0.5 * (t0 + jnp.sqrt(t0 * t0 + vgsteff * 0.004))
    t0 = (vgsteff + p["vtfbphi2"]) / (2.0 * tox)
    tcen = p["model"]["ados"] * 1.9e-9 / (1.0 + jnp.exp(p["model"]["bdos"] * 0.7 * jnp.log(t0)))
    ccen = EPSSI / tcen
    coxeff = coxp / (coxp + ccen) * ccen
    coxwlcen = coxwl * coxeff / coxe
    abulkcv = abulk0 * p["abulkcvfactor"]
    vdsatcv = vgdp / abulkcv
    t0 = vdsatcv - vds - DELTA_4
    t1 = jnp.sqrt(t0 * t0 + 4.0 * DELTA_4 * vdsatcv)
    vdseffcv = jnp.where(
        t0 >= 0.0, vdsatcv - 0.5 * (t0 + t1),
        vdsatcv * (1.0 - 2.0 * DELTA_4 / jnp.where(t0 >= 0.0, 1.0, t1 - t0)),
    )  # fmt: skip
    vdseffcv = _zero_at_vds0(vdseffcv, vds)
    return inversion_charges(coxwlcen, abulkcv, vdseffcv, vgdp, qac0, qsub0, xpart)
