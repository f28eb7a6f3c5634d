r"""BSIM3v3 (ngspice's ``bsim3``, VERSION 3.3.0, and ``bsim3v32``, VERSIONs 3.2–3.2.4) at
the model's TNOM: the card's parameters and their derived and size-dependent values
(``b3set.c``, ``b3temp.c``), the drain current and the substrate current of an
NMOS-oriented device in its mode (``V_DS ≥ 0``: source and drain swapped for
``V_DS < 0``), and the intrinsic charges of capMod 2 and 3 (``b3ld.c``). Written from
the equations (BSIM3v3.3 manual, Cheng and Hu, *MOSFET Modeling & BSIM3 User's Guide*);
ngspice's derivative bookkeeping is JAX's autodiff here.

**Size dependence** (at TNOM, ``T/TNOM = 1``). Every binnable parameter ``P`` becomes

    P = P₀ + P_L/L_eff + P_W/W_eff + P_P/(L_eff W_eff)          (BINUNIT = 1: lengths in µm)

with ``L_eff = L + XL − 2 dL``, ``dL = LINT + LL/L^LLN + LW/W^LWN + LWL/(L^LLN W^LWN)``
(``W_eff`` alike from WINT, WL, WW, WWL); the C–V lengths take DLC, DWC with LLC … . Then
``Φ = 2 V_tm ln(NCH/n_i)``, ``X_dep0 = √(2ε_Si Φ/(q NCH))``, ``V_bi = V_tm ln(10²⁰ NCH/n_i²)``,
``K1, K2`` from GAMMA1, GAMMA2, VBX, VBM (unless K1 or K2 is given), ``V_FB`` and ``V_th0``
from each other, ``θ_0 = e^{−DSUB L/2l_t0} + 2e^{−DSUB L/l_t0}`` (DIBL) and
``θ_rout = PDIBLC1 (e^{−DROUT L/2l_t0} + 2e^{−DROUT L/l_t0}) + PDIBLC2``.

**Drain current** (``b3ld.c``; ``V_bseff`` the smoothed ``V_BS`` floor at ``V_bsc``,
``Φ_s = Φ − V_bseff``):

    V_th = V_th0 − K1√Φ + K1ox√Φ_s − K2ox V_bseff − ΔV_th(L) − ΔV_th(W)
           + (K3 + K3B V_bseff) TOX Φ/(W_eff + W0) + K1ox(√(1 + NLX/L) − 1)√Φ
           − (ETA0 + ETAB V_bseff) θ_0 V_DS
    n      = 1 + (NFACTOR ε_Si/X_dep + (CDSC + CDSCB V_bseff + CDSCD V_DS)θ_th + CIT)/C_ox
    V_gsteff = 2nV_t ln(1 + e^{(V_gst)/2nV_t}) / (1 + 2n C_ox/C_dep0 · e^{−(V_gst − 2VOFF)/2nV_t})
    I_ds   = (I_dl (1 + (V_DS − V_dseff)/V_A)) (1 + (V_DS − V_dseff)/V_ASCBE),
    I_dl   = μ_eff C_ox (W/L) V_gsteff (1 − A_bulk V_dseff/2(V_gsteff + 2V_t)) V_dseff
             / ((1 + V_dseff/(E_sat L)) (1 + R_ds g_che))

with the mobility ``μ_eff = U0/(1 + (UA + UC V_bseff)(V_gsteff + 2V_th)/TOX +
UB((V_gsteff + 2V_th)/TOX)²)`` (mobMod 1; 2 and 3 as the manual), ``V_dsat`` the root of
the saturation condition with ``R_ds`` and ``λ`` (A1, A2), ``V_dseff = V_dsat −
((V_dsat − V_DS − δ) + √((V_dsat − V_DS − δ)² + 4δV_dsat))/2``, ``V_A = V_Asat + (1 +
PVAG V_gsteff/E_sat L)(1/V_ACLM + 1/V_ADIBL)⁻¹``. The region guards ngspice puts on
every denominator (``T < −0.9 → (0.8 + T)/(17 + 20T)`` …) are kept as written.

**Charges** (capMod 2 and 3; ``xpart`` 0, 0.4/0.6 and 0.5 partitions): the accumulation
charge ``Q_acc = C_oxWL (V_fbeff − V_fbzb)``, the depletion charge ``Q_sub0 = C_oxWL K1ox
(√(K1ox²/4 + V_gs − V_fbeff − V_bseff − V_gsteff,CV) − K1ox/2)`` and the inversion charge
of the bulk-charge-linearised channel, with capMod 3's charge-centroid oxide capacitance
``C_oxeff`` and ``Δφ_s``: the gate, bulk and drain charges ``(Q_g, Q_b, Q_d)`` of the mode.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..errors import ModelError

# ngspice's constants (b3temp.c, b3ld.c)
KBOQ = 8.617087e-5
EPSOX = 3.453133e-11
EPSSI = 1.03594e-10
CHARGE_Q = 1.60219e-19
PI = 3.141592654
MAX_EXP = 5.834617425e14
MIN_EXP = 1.713908431e-15
EXP_THRESHOLD = 34.0
DELTA_3 = 0.02
DELTA_4 = 0.02
CELSIUS = 273.15

#: the binnable parameters (each also with an L, W and P prefix: ``lvth0`` …), with
#: ngspice's defaults (``None``: derived in :func:`size_dependent` when not given)
BINNED = {
    "cdsc": 2.4e-4, "cdscb": 0.0, "cdscd": 0.0, "cit": 0.0, "nfactor": 1.0, "xj": 0.15e-6,
    "vsat": 8.0e4, "at": 3.3e4, "a0": 1.0, "ags": 0.0, "a1": 0.0, "a2": 1.0, "keta": -0.047,
    "nsub": 6.0e16, "nch": 1.7e17, "ngate": 0.0, "gamma1": None, "gamma2": None,
    "vbx": None, "vbm": -3.0, "xt": 1.55e-7, "k1": None, "kt1": -0.11, "kt1l": 0.0,
    "kt2": 0.022, "k2": None, "k3": 80.0, "k3b": 0.0, "w0": 2.5e-6, "nlx": 1.74e-7,
    "dvt0": 2.2, "dvt1": 0.53, "dvt2": -0.032, "dvt0w": 0.0, "dvt1w": 5.3e6,
    "dvt2w": -0.032, "drout": 0.56, "dsub": None, "vth0": None, "ua": 2.25e-9,
    "ua1": 4.31e-9, "ub": 5.87e-19, "ub1": -7.61e-18, "uc": None, "uc1": None, "u0": None,
    "ute": -1.5, "voff": -0.08, "elm": 5.0, "delta": 0.01, "rdsw": 0.0, "prwg": 0.0,
    "prwb": 0.0, "prt": 0.0, "eta0": 0.08, "etab": -0.07, "pclm": 1.3, "pdiblc1": 0.39,
    "pdiblc2": 0.0086, "pdiblcb": 0.0, "pscbe1": 4.24e8, "pscbe2": 1.0e-5, "pvag": 0.0,
    "wr": 1.0, "dwg": 0.0, "dwb": 0.0, "b0": 0.0, "b1": 0.0, "cgsl": 0.0, "cgdl": 0.0,
    "ckappa": 0.6, "cf": None, "clc": 0.1e-6, "cle": 0.6, "alpha0": 0.0, "alpha1": 0.0,
    "beta0": 30.0, "vfbcv": -1.0, "vfb": None, "acde": 1.0, "moin": 15.0, "noff": 1.0,
    "voffcv": 0.0,
}  # fmt: skip
#: the model parameters that are not binned, with ngspice's defaults (``None``: derived)
MODEL = {
    "mobmod": 1.0, "binunit": 1.0, "capmod": 3.0, "nqsmod": 0.0, "acnqsmod": 0.0,
    "acm": 0.0, "calcacm": 0.0, "noimod": 1.0, "paramchk": 0.0, "tox": 150.0e-10,
    "toxm": None, "tnom": None, "cgso": None, "cgdo": None, "cgbo": None, "xpart": 0.0,
    "rsh": 0.0, "js": 1.0e-4, "jsw": 0.0, "pb": 1.0, "nj": 1.0, "xti": 3.0, "mj": 0.5,
    "pbsw": 1.0, "mjsw": 0.33, "pbswg": None, "mjswg": None, "cj": 5.0e-4, "cjsw": 5.0e-10,
    "cjswg": None, "ijth": 0.1, "tpb": 0.0, "tcj": 0.0, "tpbsw": 0.0, "tcjsw": 0.0,
    "tpbswg": 0.0, "tcjswg": 0.0, "lint": 0.0, "ll": 0.0, "llc": None, "lln": 1.0,
    "lw": 0.0, "lwc": None, "lwn": 1.0, "lwl": 0.0, "lwlc": None, "lmin": 0.0, "lmax": 1.0,
    "wint": 0.0, "wl": 0.0, "wlc": None, "wln": 1.0, "ww": 0.0, "wwc": None, "wwn": 1.0,
    "wwl": 0.0, "wwlc": None, "wmin": 0.0, "wmax": 1.0, "xl": 0.0, "xw": 0.0, "dwc": None,
    "dlc": None, "hdif": 0.0, "ldif": 0.0, "ld": 0.0, "rd": 0.0, "rs": 0.0, "rdc": 0.0,
    "rsc": 0.0, "wmlt": 1.0, "lmlt": 1.0,
}  # fmt: skip
#: read by ngspice for the noise analysis or the safe-operating-area check only
NOISE_ONLY = ("noia", "noib", "noic", "em", "ef", "af", "kf", "lintnoi", "vgs_max",
              "vgd_max", "vgb_max", "vds_max", "vbs_max", "vbd_max", "vgsr_max",
              "vgdr_max", "vgbr_max", "vbsr_max", "vbdr_max")  # fmt: skip
#: every name of a card (but LEVEL, VERSION and the noise ones)
NAMES = frozenset(MODEL) | frozenset(BINNED) | {p + k for k in BINNED for p in "lwp"}


def _sqrt(x):
    """``√x``, its derivative finite where a discarded ``jnp.where`` branch has x ≤ 0."""
    return jnp.sqrt(jnp.maximum(x, 1e-300))


def _exp_clamped(t):
    """ngspice's ``exp`` guard: ``MIN_EXP`` below ``−EXP_THRESHOLD``, ``MAX_EXP`` above."""
    return jnp.where(
        t > EXP_THRESHOLD,
        MAX_EXP,
        jnp.where(t < -EXP_THRESHOLD, MIN_EXP, jnp.exp(jnp.clip(t, -EXP_THRESHOLD, EXP_THRESHOLD))),
    )


def version_code(version) -> int:
    """ngspice's revision of a VERSION: 330 (3.3.0, the ``bsim3`` model, its default),
    324, 323, 322 or 320 (``bsim3v32``: ``3.2.4``/``3.24``, … ``3.2``/``3.20``)."""
    text = "3.3.0" if version is None else (f"{version:g}" if isinstance(version, float)
                                           else str(version))  # fmt: skip
    if text.startswith("3.3"):
        return 330
    for code, names in ((324, ("3.2.4", "3.24")), (323, ("3.2.3", "3.23")),
                        (322, ("3.2.2", "3.22"))):  # fmt: skip
        if text == names[0] or text.startswith(names[1]):
            return code
    if text.startswith("3.2"):
        return 320
    raise ModelError(
        f"BSIM3 VERSION={text} is not supported: diracvi has ngspice's bsim3 (3.3.0) and "
        "bsim3v32 (3.2, 3.2.2, 3.2.3, 3.2.4); ngspice's 3.0 and 3.1 are separate models."
    )


def size_dependent(
    card: dict,
    sign: float,
    l: float,  # noqa: E741  (SPICE's name)
    w: float,
    delvto=0.0,
    mulu0=1.0,
    revision=330,
):
    r"""The size-dependent parameters of a device of drawn ``l`` × ``w`` (m) from the
    card's **given** values ``card`` (lower-case names; a name absent is not given),
    ``sign`` = type (+1 NMOS, −1 PMOS), at TNOM (module docstring; ``b3set.c`` and
    ``b3temp.c``). Returns a dict of floats or traced values."""
    m = {k: card.get(k, v) for k, v in MODEL.items()}
    tox = m["tox"]
    cox = EPSOX / tox
    m["toxm"] = tox if m["toxm"] is None else m["toxm"]
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
            m[base] = m[derived]
    m["pbswg"] = m["pbsw"] if m["pbswg"] is None else m["pbswg"]
    m["mjswg"] = m["mjsw"] if m["mjswg"] is None else m["mjswg"]
    m["cjswg"] = m["cjsw"] if m["cjswg"] is None else m["cjswg"]
    mob = int(m["mobmod"])
    # the binned values: the base (its default when not given) plus L, W, P terms
    base = {}
    for k, d in BINNED.items():
        if k in card:
            base[k] = card[k]
        elif k == "dsub":
            base[k] = card.get("drout", BINNED["drout"])
        elif k == "vth0":
            base[k] = 0.7 * sign
        elif k in ("uc", "uc1"):
            base[k] = {("uc", 3): -0.0465, ("uc1", 3): -0.056}.get(
                (k, mob), -0.0465e-9 if k == "uc" else -0.056e-9
            )
        elif k == "u0":
            base[k] = 0.067 if sign > 0 else 0.025
        elif k == "cf":
            base[k] = 2.0 * EPSOX / PI * math.log(1.0 + 0.4e-6 / tox)
        else:
            base[k] = 0.0 if d is None else d
    for k in ("nch", "lnch", "wnch", "pnch"):  # ngspice reads NCH above 1e20 as m⁻³
        if k in card and isinstance(card[k], float) and card[k] > 1.0e20:
            if k == "nch":
                base[k] = card[k] * 1e-6
            else:
                card = card | {k: card[k] * 1e-6}
    if "ngate" in card and isinstance(card["ngate"], float) and card["ngate"] > 1.000001e24:
        base["ngate"] = card["ngate"] * 1e-6
    l_drawn = l * m["lmlt"] if "lmlt" in card else l
    lln, lwn, wln, wwn = (m[k] for k in ("lln", "lwn", "wln", "wwn"))
    t0, t1 = l_drawn**lln, w**lwn
    dl = m["lint"] + m["ll"] / t0 + m["lw"] / t1 + m["lwl"] / (t0 * t1)
    dlc = m["dlc"] + m["llc"] / t0 + m["lwc"] / t1 + m["lwlc"] / (t0 * t1)
    t2, t3 = l_drawn**wln, w**wwn
    dw = m["wint"] + m["wl"] / t2 + m["ww"] / t3 + m["wwl"] / (t2 * t3)
    dwc = m["dwc"] + m["wlc"] / t2 + m["wwc"] / t3 + m["wwlc"] / (t2 * t3)
    leff = l_drawn + m["xl"] - 2.0 * dl
    weff = w + m["xw"] - 2.0 * dw
    leffcv = l_drawn + m["xl"] - 2.0 * dlc
    weffcv = w + m["xw"] - 2.0 * dwc
    for what, x in (("L_eff", leff), ("W_eff", weff), ("L_eff,CV", leffcv),
                    ("W_eff,CV", weffcv)):  # fmt: skip
        if isinstance(x, float) and x <= 0.0:
            raise ModelError(
                f"BSIM3: the effective channel {what} = {x:g} m must be > 0 (l={l:g}, w={w:g},"
                f" LINT/WINT/DLC/DWC and their L/W terms shorten it)."
            )
    unit = 1.0e-6 if m["binunit"] == 1.0 else 1.0
    inv_l, inv_w, inv_lw = unit / leff, unit / weff, unit * unit / (leff * weff)
    p = {k: base[k] + card.get("l" + k, 0.0) * inv_l + card.get("w" + k, 0.0) * inv_w
         + card.get("p" + k, 0.0) * inv_lw for k in BINNED}  # fmt: skip
    p.update(leff=leff, weff=weff, leffcv=leffcv, weffcv=weffcv, cox=cox, tox=tox,
             toxm=m["toxm"], sign=sign)  # fmt: skip
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
    p["abulkcvfactor"] = 1.0 + (p["clc"] / leffcv) ** p["cle"]
    u0 = p["u0"]  # U0 above 1 is read in cm²/V·s
    p["u0temp"] = jnp.where(u0 > 1.0, u0 / 1.0e4, u0) * mulu0
    p["vsattemp"] = p["vsat"]
    p["rds0"] = p["rdsw"] / (weff * 1e6) ** p["wr"]
    p["cgdo_eff"] = None  # set below from the card's CGDO
    if "nch" not in card and "gamma1" in card:
        p["nch"] = 3.021e22 * (p["gamma1"] * cox) ** 2
    nch = p["nch"]
    phi = 2.0 * vtm0 * jnp.log(nch / ni)
    p["phi"] = phi
    p["sqrtphi"] = jnp.sqrt(phi)
    p["phis3"] = p["sqrtphi"] * phi
    p["xdep0"] = jnp.sqrt(2.0 * EPSSI / (CHARGE_Q * nch * 1.0e6)) * p["sqrtphi"]
    p["litl"] = jnp.sqrt(3.0 * p["xj"] * tox)
    p["vbi"] = vtm0 * jnp.log(1.0e20 * nch / (ni * ni))
    p["cdep0"] = jnp.sqrt(CHARGE_Q * EPSSI * nch * 1.0e6 / 2.0 / phi)
    p["ldeb"] = jnp.sqrt(EPSSI * vtm0 / (CHARGE_Q * nch * 1.0e6)) / 3.0
    p["acde"] = p["acde"] * (nch / 2.0e16) ** -0.25
    if "k1" in card or "k2" in card:  # the other one takes ngspice's fixed value
        if "k1" not in card:
            p["k1"] = 0.53
        if "k2" not in card:
            p["k2"] = -0.0186
    else:
        vbx = p["vbx"] if "vbx" in card else phi - 7.7348e-4 * nch * p["xt"] ** 2
        vbx = -jnp.abs(vbx)
        vbm = -jnp.abs(p["vbm"])
        p["vbm"] = vbm
        g1 = p["gamma1"] if "gamma1" in card else 5.753e-12 * jnp.sqrt(nch) / cox
        g2 = p["gamma2"] if "gamma2" in card else 5.753e-12 * jnp.sqrt(p["nsub"]) / cox
        t1 = jnp.sqrt(phi - vbx) - p["sqrtphi"]
        t2 = jnp.sqrt(phi * (phi - vbm)) - phi
        p["k2"] = (g1 - g2) * t1 / (2.0 * t2 + vbm)
        p["k1"] = g2 - 2.0 * p["k2"] * jnp.sqrt(phi - vbm)
    k1, k2 = p["k1"], p["k2"]
    vbsc = jnp.where(
        k2 < 0.0,
        jnp.clip(0.9 * (phi - (0.5 * k1 / jnp.where(k2 < 0.0, k2, -1.0)) ** 2), -30.0, -3.0),
        -30.0,
    )
    p["vbsc"] = jnp.minimum(vbsc, p["vbm"])
    if "vfb" not in card:
        p["vfb"] = (sign * p["vth0"] - phi - k1 * p["sqrtphi"]) if "vth0" in card else -1.0
    if "vth0" not in card:
        p["vth0"] = sign * (p["vfb"] + phi + k1 * p["sqrtphi"])
    p["k1ox"] = k1 * tox / m["toxm"]
    p["k2ox"] = k2 * tox / m["toxm"]
    factor1 = math.sqrt(EPSSI / EPSOX * tox)
    p["factor1"] = factor1
    lt0 = jnp.sqrt(EPSSI / EPSOX * tox * p["xdep0"])
    t0 = jnp.exp(-0.5 * p["dsub"] * leff / lt0)
    p["theta0vb0"] = t0 + 2.0 * t0 * t0
    t0 = jnp.exp(-0.5 * p["drout"] * leff / lt0)
    p["thetarout"] = p["pdiblc1"] * (t0 + 2.0 * t0 * t0) + p["pdiblc2"]
    # V_FB at zero bias (the C–V model's): V_th at V_BS = V_DS = 0 less Φ + K1√Φ
    v0 = p["vbi"] - phi
    tmp2 = factor1 * jnp.sqrt(p["xdep0"])
    t2 = p["dvt0w"] * _theta(-0.5 * p["dvt1w"] * weff * leff / tmp2) * v0
    t3 = p["dvt0"] * _theta(-0.5 * p["dvt1"] * leff / tmp2) * v0
    t4 = tox * phi / (weff + p["w0"])
    t5 = p["k1ox"] * (jnp.sqrt(1.0 + p["nlx"] / leff) - 1.0) * p["sqrtphi"]
    vth_zb = sign * p["vth0"] - t2 - t3 + p["k3"] * t4 + t5
    p["vfbzb"] = vth_zb - phi - k1 * p["sqrtphi"] + sign * delvto
    p["vth0"] = p["vth0"] + delvto
    p["vfb"] = p["vfb"] + sign * delvto
    # the overlaps (b3set.c's defaults, b3temp.c's W_eff,CV and L_eff,CV)
    cgdo, cgso, cgbo = (card.get(k) for k in ("cgdo", "cgso", "cgbo"))
    dlc_card = card.get("dlc")
    if cgdo is None:
        cgdo = (dlc_card * cox - p["cgdl"] if dlc_card is not None and dlc_card > 0.0
                else 0.6 * p["xj"] * cox)  # fmt: skip
    if cgso is None:
        cgso = (dlc_card * cox - p["cgsl"] if dlc_card is not None and dlc_card > 0.0
                else 0.6 * p["xj"] * cox)  # fmt: skip
    if cgbo is None:
        cgbo = 2.0 * m["dwc"] * cox
    p["cgdo_eff"] = (cgdo + p["cf"]) * weffcv
    p["cgso_eff"] = (cgso + p["cf"]) * weffcv
    p["cgbo_eff"] = cgbo * leffcv
    p["model"] = m
    p["revision"] = revision
    return p


def _theta(t0):
    """``e^{t} + 2e^{2t}`` with ngspice's ``MIN_EXP`` floor below ``−EXP_THRESHOLD``."""
    t1 = jnp.where(t0 > -EXP_THRESHOLD, jnp.exp(jnp.maximum(t0, -EXP_THRESHOLD)), MIN_EXP)
    return t1 * (1.0 + 2.0 * t1)


def _float(x) -> bool:
    """Whether ``x`` is a number known when the part is built (not a traced value)."""
    return isinstance(x, float)


def branches(p: dict) -> tuple:
    """The forms :func:`evaluate` takes, decided once from the size-dependent values ``p``
    (a value known when the part is built may switch a term off or to a simpler exact
    form; a traced value takes the general one): ``(name, choice)`` pairs, hashable, so
    that a part stores them as static data and its numbers as arrays — parts whose
    choices agree compute one function of different numbers.

    ``poly``: the poly-gate depletion (``1e18 < NGATE < 1e25``); ``a1``: λ's form
    (``"zero"``, ``"positive"`` or ``"general"``); ``simple``: ``V_dsat`` without R_ds
    and λ (RDS0 = 0, A1 = 0, A2 = 1); ``no_clm``, ``no_dibl``, ``no_scbe``, ``no_isub``:
    PCLM ≤ 0, θ_rout ≤ 0, PSCBE2 ≤ 0, ALPHA0 + ALPHA1 L_eff ≤ 0 or BETA0 ≤ 0 (the term
    off); ``k1ox_zero``, ``k1ox_nonpositive``: the charges' K1ox forms."""
    ngate, a1, a2, k1ox = p["ngate"], p["a1"], p["a2"], p["k1ox"]
    rds0 = p["rds0"]
    tmp = p["alpha0"] + p["alpha1"] * p["leff"]
    if _float(a1) and a1 == 0.0:
        lam = "zero"
    elif _float(a1) and a1 > 0.0:
        lam = "positive"
    else:
        lam = "general"
    return (
        ("poly", not _float(ngate) or 1.0e18 < ngate < 1.0e25),
        ("a1", lam),
        ("simple", bool(_float(rds0) and rds0 == 0.0 and lam == "zero" and _float(a2) and a2 == 1)),
        ("no_clm", bool(_float(p["pclm"]) and p["pclm"] <= 0.0)),
        ("no_dibl", bool(_float(p["thetarout"]) and p["thetarout"] <= 0.0)),
        ("no_scbe", bool(_float(p["pscbe2"]) and p["pscbe2"] <= 0.0)),
        ("no_isub", bool(_float(tmp) and (tmp <= 0.0 or p["beta0"] <= 0.0))),
        ("k1ox_zero", bool(_float(k1ox) and k1ox == 0.0)),
        ("k1ox_nonpositive", bool(_float(k1ox) and k1ox <= 0.0)),
    )


def saturation_voltage(p, form, vgsteff, vtm, abulk, esatl, wvcoxrds):
    r"""BSIM3's (and BSIM4's) saturation voltage with its source/drain resistance, the
    smaller root of

        ½ T₀ V_dsat² − T₁ V_dsat + T₂ = 0,   V_dsat = (T₁ − √(T₁² − 2 T₀ T₂)) / T₀,

    ``T₀ = 2 A_bulk (A_bulk W v_sat C_ox R_ds − 1 + 1/λ)``, ``T₁ = (V_gst + 2v_t)(2/λ − 1) +
    A_bulk E_sat L_eff + 3 (V_gst + 2v_t) A_bulk W v_sat C_ox R_ds``, ``T₂ = (V_gst + 2v_t)
    (E_sat L_eff + 2 (V_gst + 2v_t) W v_sat C_ox R_ds)``, with ``λ`` from ``A1``, ``A2`` (the
    non-saturation factor, smoothed to stay in (0, 1]); where ``R_ds = 0`` and ``λ = 1``
    (``form["simple"]``) it is ``E_sat L_eff (V_gst + 2v_t)/(A_bulk E_sat L_eff + V_gst +
    2v_t)``. Returns ``(λ, V_gst + 2v_t, V_dsat)``: the same equations in both models'
    manuals and in ngspice's ``b3ld.c`` and ``b4v7ld.c``."""
    a1, a2 = p["a1"], p["a2"]
    if form["a1"] == "zero":
        lam = a2 + 0.0 * vgsteff
    elif form["a1"] == "positive":
        t0l = 1.0 - a2
        t1l = t0l - a1 * vgsteff - 0.0001
        lam = a2 + t0l - 0.5 * (t1l + jnp.sqrt(t1l * t1l + 0.0004 * t0l))
    else:
        t1l = a2 + a1 * vgsteff - 0.0001
        lam = 0.5 * (t1l + jnp.sqrt(t1l * t1l + 0.0004 * a2))
    vgst2vtm = vgsteff + 2.0 * vtm
    if form["simple"]:
        vdsat = esatl * vgst2vtm / (abulk * esatl + vgst2vtm)
    else:
        t9v = abulk * wvcoxrds
        t0v = 2.0 * abulk * (t9v - 1.0 + 1.0 / lam)
        t1v = vgst2vtm * (2.0 / lam - 1.0) + abulk * esatl + 3.0 * vgst2vtm * t9v
        t2v = vgst2vtm * (esatl + 2.0 * vgst2vtm * wvcoxrds)
        vdsat = (t1v - jnp.sqrt(t1v * t1v - 2.0 * t0v * t2v)) / t0v
    return lam, vgst2vtm, vdsat


def evaluate(p: dict, vgs, vds, vbs, *, mobmod=1, capmod=None, xpart=0.0, charges_only=False):
    r"""``(I_ds, I_sub, (Q_g, Q_b, Q_d))`` of the NMOS-oriented mode (``V_DS ≥ 0``):
    the module docstring's current, the substrate current (ALPHA0, ALPHA1, BETA0, drain to
    bulk) and, for ``capmod`` 2 or 3, the intrinsic charges (``None``: none, as with
    XPART < 0). ``charges_only``: stop at the charges (the currents ``None``), which read
    the threshold and ``A_bulk0`` but none of the mobility and saturation terms."""
    if charges_only and (capmod is None or xpart < 0.0):
        return None, None, None
    # the forms: the part's own (its numbers arrays), else decided from p's values
    form = dict(p["branches"]) if "branches" in p else dict(branches(p))
    vtm = p["vtm"]
    cox, tox = p["cox"], p["tox"]
    leff = p["leff"]
    phi, sqrtphi = p["phi"], p["sqrtphi"]
    # V_bseff: V_BS floored smoothly at V_bsc
    t0 = vbs - p["vbsc"] - 0.001
    t1 = jnp.sqrt(t0 * t0 - 0.004 * p["vbsc"])
    vbseff = jnp.maximum(p["vbsc"] + 0.5 * (t0 + t1), vbs)
    pos = vbseff > 0.0
    phis = jnp.where(pos, phi * phi / (phi + jnp.maximum(vbseff, 0.0)), phi - vbseff)
    sqrtphis = jnp.where(pos, p["phis3"] / (phi + 0.5 * jnp.maximum(vbseff, 0.0)),
                         _sqrt(phi - vbseff))  # fmt: skip
    xdep = p["xdep0"] * sqrtphis / sqrtphi
    # threshold
    t3 = jnp.sqrt(xdep)
    v0 = p["vbi"] - phi

    def _dvt2(dvt2):
        t = dvt2 * vbseff
        return jnp.where(t >= -0.5, 1.0 + t, (1.0 + 3.0 * t) / (3.0 + 8.0 * jnp.minimum(t, -0.5)))

    lt1 = p["factor1"] * t3 * _dvt2(p["dvt2"])
    ltw = p["factor1"] * t3 * _dvt2(p["dvt2w"])
    theta0 = _theta(-0.5 * p["dvt1"] * leff / lt1)
    delt_vth = p["dvt0"] * theta0 * v0
    t2w = p["dvt0w"] * _theta(-0.5 * p["dvt1w"] * p["weff"] * leff / ltw) * v0
    t1 = p["k1ox"] * (jnp.sqrt(1.0 + p["nlx"] / leff) - 1.0) * sqrtphi
    tmp2 = tox * phi / (p["weff"] + p["w0"])
    t3e = p["eta0"] + p["etab"] * vbseff
    t3e = jnp.where(t3e < 1.0e-4, (2.0e-4 - t3e) / (3.0 - 2.0e4 * jnp.minimum(t3e, 1e-4)), t3e)
    dibl = t3e * p["theta0vb0"] * vds
    vth = (p["sign"] * p["vth0"] - p["k1"] * sqrtphi + p["k1ox"] * sqrtphis
           - p["k2ox"] * vbseff - delt_vth - t2w + (p["k3"] + p["k3b"] * vbseff) * tmp2
           + t1 - dibl)  # fmt: skip
    # subthreshold swing
    cdsc = p["cdsc"] + p["cdscb"] * vbseff + p["cdscd"] * vds
    tmp4 = (p["nfactor"] * EPSSI / xdep + cdsc * theta0 + p["cit"]) / cox
    n = jnp.where(
        tmp4 >= -0.5, 1.0 + tmp4, (1.0 + 3.0 * tmp4) / (3.0 + 8.0 * jnp.minimum(tmp4, -0.5))
    )
    # poly-gate depletion
    vgs_eff = vgs
    ngate = p["ngate"]
    if form["poly"]:
        tfb = p["vfb"] + phi
        t1g = 1.0e6 * CHARGE_Q * EPSSI * ngate / (cox * cox)
        t4g = _sqrt(1.0 + 2.0 * (vgs - tfb) / t1g)
        t2g = t1g * (t4g - 1.0)
        t3g = 0.5 * t2g * t2g / t1g
        t7 = 1.12 - t3g - 0.05
        t6 = jnp.sqrt(t7 * t7 + 0.224)
        t5 = 1.12 - 0.5 * (t7 + t6)
        vgs_eff = jnp.where(vgs > tfb, vgs - t5, vgs)
    vgst = vgs_eff - vth
    # V_gsteff
    t10 = 2.0 * n * vtm
    vgstnvt = vgst / t10
    exparg = (2.0 * p["voff"] - vgst) / t10
    strong = vgstnvt > EXP_THRESHOLD
    weak = (~strong) & (exparg > EXP_THRESHOLD)
    sub_arg = jnp.minimum((vgst - p["voff"]) / (n * vtm), EXP_THRESHOLD)
    vgsteff_weak = vtm * p["cdep0"] / cox * jnp.exp(sub_arg)
    mid_x = jnp.clip(vgstnvt, -EXP_THRESHOLD, EXP_THRESHOLD)
    t1m = t10 * jnp.log1p(jnp.exp(mid_x))
    t2m = 1.0 + t10 * cox / (vtm * p["cdep0"]) * jnp.exp(
        jnp.clip(exparg, -EXP_THRESHOLD, EXP_THRESHOLD)
    )
    vgsteff = jnp.where(strong, vgst, jnp.where(weak, vgsteff_weak, t1m / t2m))
    # effective width and R_ds
    t9 = sqrtphis - sqrtphi
    weff = p["weff"] - 2.0 * (p["dwg"] * vgsteff + p["dwb"] * t9)
    weff = jnp.where(
        weff < 2.0e-8, 2.0e-8 * (4.0e-8 - weff) / (6.0e-8 - 2.0 * jnp.minimum(weff, 2e-8)), weff
    )
    t0r = p["prwg"] * vgsteff + p["prwb"] * t9
    rds = p["rds0"] * jnp.where(
        t0r >= -0.9, 1.0 + t0r, (0.8 + t0r) / (17.0 + 20.0 * jnp.minimum(t0r, -0.9))
    )
    # A_bulk
    t1a = 0.5 * p["k1ox"] / sqrtphis
    t9a = jnp.sqrt(p["xj"] * xdep)
    t5a = leff / (leff + 2.0 * t9a)
    t2a = p["a0"] * t5a + p["b0"] / (p["weff"] + p["b1"])
    abulk0 = 1.0 + t1a * t2a
    abulk = abulk0 - t1a * p["ags"] * p["a0"] * t5a**3 * vgsteff

    def _floor01(a):
        return jnp.where(a < 0.1, (0.2 - a) / (3.0 - 20.0 * jnp.minimum(a, 0.1)), a)

    abulk0, abulk = _floor01(abulk0), _floor01(abulk)
    t2k = p["keta"] * vbseff
    kf = jnp.where(
        t2k >= -0.9, 1.0 / (1.0 + t2k), (17.0 + 20.0 * t2k) / (0.8 + jnp.minimum(t2k, -0.9))
    )
    abulk, abulk0 = abulk * kf, abulk0 * kf
    if charges_only:
        return None, None, _charges(p, form, capmod, xpart, vgs_eff, vbseff, phis, vth, n,
                                    vgst, abulk0, vds)  # fmt: skip
    # mobility
    if mobmod == 1:
        t3m = (vgsteff + 2.0 * vth) / tox
        t5m = t3m * (p["ua"] + p["uc"] * vbseff + p["ub"] * t3m)
    elif mobmod == 2:
        t5m = vgsteff / tox * (p["ua"] + p["uc"] * vbseff + p["ub"] * vgsteff / tox)
    else:
        t3m = (vgsteff + 2.0 * vth) / tox
        t5m = t3m * (p["ua"] + p["ub"] * t3m) * (1.0 + p["uc"] * vbseff)
    denomi = jnp.where(t5m >= -0.8, 1.0 + t5m, (0.6 + t5m) / (7.0 + 10.0 * jnp.minimum(t5m, -0.8)))
    ueff = p["u0temp"] / denomi
    # V_dsat
    wvcox = weff * p["vsattemp"] * cox
    wvcoxrds = wvcox * rds
    esat = 2.0 * p["vsattemp"] / ueff
    esatl = esat * leff
    lam, vgst2vtm, vdsat = saturation_voltage(p, form, vgsteff, vtm, abulk, esatl, wvcoxrds)
    # V_dseff
    delta = p["delta"]
    t1d = vdsat - vds - delta
    vdseff = vdsat - 0.5 * (t1d + jnp.sqrt(t1d * t1d + 4.0 * delta * vdsat))
    vdseff = jnp.where(vds == 0.0, 0.0, vdseff) if p["revision"] >= 322 else vdseff
    # V_Asat
    tmp4 = 1.0 - 0.5 * abulk * vdsat / vgst2vtm
    t0s = esatl + vdsat + 2.0 * wvcoxrds * vgsteff * tmp4
    t1s = 2.0 / lam - 1.0 + wvcoxrds * abulk
    vasat = t0s / t1s
    vdseff = jnp.minimum(vdseff, vds)
    diffvds = vds - vdseff
    # V_ACLM
    pclm = p["pclm"]
    clm_on = diffvds > 1.0e-10
    vaclm = jnp.where(
        clm_on, (leff * (abulk + vgsteff / esatl)) / (pclm * abulk * p["litl"]) * diffvds, MAX_EXP
    )
    if form["no_clm"]:
        vaclm = MAX_EXP + 0.0 * vds
    # V_ADIBL
    tr = p["thetarout"]
    t8 = abulk * vdsat
    vadibl = (vgst2vtm - vgst2vtm * t8 / (vgst2vtm + t8)) / tr
    t7 = p["pdiblcb"] * vbseff
    vadibl = vadibl * jnp.where(t7 >= -0.9, 1.0 / (1.0 + t7),
                                (17.0 + 20.0 * t7) / (0.8 + jnp.minimum(t7, -0.9)))  # fmt: skip
    if form["no_dibl"]:
        vadibl = MAX_EXP + 0.0 * vds
    # V_A
    t9p = p["pvag"] / esatl * vgsteff
    t0p = jnp.where(t9p > -0.9, 1.0 + t9p, (0.8 + t9p) / (17.0 + 20.0 * jnp.minimum(t9p, -0.9)))
    va = vasat + t0p * vaclm * vadibl / (vaclm + vadibl)
    # V_ASCBE
    pscbe1, pscbe2 = p["pscbe1"], p["pscbe2"]
    if form["no_scbe"]:
        vascbe = MAX_EXP + 0.0 * vds
    else:
        big = diffvds > pscbe1 * p["litl"] / EXP_THRESHOLD
        arg = pscbe1 * p["litl"] / jnp.where(big, diffvds, 1.0)
        vascbe = jnp.where(big, leff * jnp.exp(jnp.minimum(arg, EXP_THRESHOLD)) / pscbe2,
                           MAX_EXP * leff / pscbe2)  # fmt: skip
    # I_ds
    beta = ueff * cox * weff / leff
    fgche1 = vgsteff * (1.0 - 0.5 * abulk * vdseff / vgst2vtm)
    fgche2 = 1.0 + vdseff / esatl
    gche = beta * fgche1 / fgche2
    idl = gche * vdseff / (1.0 + gche * rds)
    idsa = idl * (1.0 + diffvds / va)
    ids = idsa * (1.0 + diffvds / vascbe)
    # substrate current
    tmp = p["alpha0"] + p["alpha1"] * leff
    beta0 = p["beta0"]
    if form["no_isub"]:
        isub = 0.0 * ids
    else:
        big = diffvds > beta0 / EXP_THRESHOLD
        dv = jnp.where(big, diffvds, 1.0)
        t1s = jnp.where(
            big, tmp / leff * diffvds * jnp.exp(-beta0 / dv), tmp / leff * MIN_EXP * diffvds
        )
        isub = t1s * idsa
    if capmod is None or xpart < 0.0:  # ngspice: no intrinsic charge with XPART < 0
        return ids, isub, None
    charges = _charges(p, form, capmod, xpart, vgs_eff, vbseff, phis, vth, n, vgst, abulk0, vds)
    return ids, isub, charges


def inversion_charges(coxwlc, abulkcv, vdseffcv, vgdp, qac0, qsub0, xpart):
    r"""capMod 2's terminal charges (BSIM3 and BSIM4 alike) from the inversion charge's
    drain-end reduction, ``A = A_bulk,CV V_dseff,CV``, ``T₂ = 12 (V_gst − A/2)``:

        Q_g = C (V_gst − A (½ − A/T₂)),   Q_b,inv = C (1 − A_bulk,CV)(½ − A/T₂) V_dseff,CV,

    the channel charge split drain/source by XPART (0/100 above 0.5, 40/60 below it, 50/50
    at it), then the accumulation and depletion charges ``Q_ac0 + Q_sub0`` added to
    the gate and taken from the bulk, and ``Q_d = −(Q_g + Q_b + Q_s)``. ``C`` is
    ``W L C_ox`` (BSIM4: at the charge centroid)."""
    t0 = abulkcv * vdseffcv
    t1 = vgdp
    t2 = 12.0 * (t1 - 0.5 * t0 + 1.0e-20)
    t3 = t0 / t2
    qgate = coxwlc * (t1 - t0 * (0.5 - t3))
    t7 = 1.0 - abulkcv
    qbulk = coxwlc * t7 * (0.5 * vdseffcv - t0 * vdseffcv / t2)
    if xpart > 0.5:
        qsrc = -coxwlc * (t1 / 2.0 + t0 / 4.0 - 0.5 * t0 * t0 / t2)
    elif xpart < 0.5:
        t2b = t2 / 12.0
        t3b = 0.5 * coxwlc / (t2b * t2b)
        t4b = t1 * (2.0 * t0 * t0 / 3.0 + t1 * (t1 - 4.0 * t0 / 3.0)) - 2.0 * t0 * t0 * t0 / 15.0
        qsrc = -t3b * t4b
    else:
        qsrc = -0.5 * qgate
    qgate = qgate + qac0 + qsub0 - qbulk
    qbulk = qbulk - (qac0 + qsub0)
    qdrn = -(qgate + qbulk + qsrc)
    return qgate, qbulk, qdrn


def _charges(p, form, capmod, xpart, vgs_eff, vbseff, phis, vth, n, vgst, abulk0, vds):
    """The intrinsic ``(Q_g, Q_b, Q_d)`` of capMod 2 or 3 (module docstring; ``b3ld.c``)."""
    vtm, cox = p["vtm"], p["cox"]
    vbseffcv = jnp.where(vbseff < 0.0, vbseff, p["phi"] - phis)
    coxwl = cox * p["weffcv"] * p["leffcv"]
    noff = n * p["noff"]
    t0 = vtm * noff
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
    k1ox = p["k1ox"]
    abulkcv = abulk0 * p["abulkcvfactor"]
    if capmod == 2:
        coxwlc = coxwl
    else:
        tox_a = 1.0e8 * p["tox"]
        tmp = (vgs_eff - vbseffcv - vfbzb) / tox_a * p["acde"]
        tcen = p["ldeb"] * _exp_clamped(tmp)
        link = 1.0e-3 * p["tox"]
        v3c = p["ldeb"] - tcen - link
        tcen = p["ldeb"] - 0.5 * (v3c + jnp.sqrt(v3c * v3c + 4.0 * link * p["ldeb"]))
        ccen = EPSSI / tcen
        coxeff = cox / (cox + ccen) * ccen
        coxwlc = coxwl * coxeff / cox
    qac0 = coxwlc * (vfbeff - vfbzb)
    t0 = 0.5 * k1ox
    t3 = vgs_eff - vfbeff - vbseffcv - vgsteff
    if form["k1ox_zero"]:
        qsub0 = 0.0 * t3
    else:
        t1 = jnp.where(t3 < 0.0, t0 + t3 / k1ox, _sqrt(t0 * t0 + jnp.maximum(t3, 0.0)))
        qsub0 = coxwlc * k1ox * (t1 - t0)
    if capmod == 2:
        vdsatcv = vgsteff / abulkcv
        v4 = vdsatcv - vds - DELTA_4
        vdseffcv = vdsatcv - 0.5 * (v4 + jnp.sqrt(v4 * v4 + 4.0 * DELTA_4 * vdsatcv))
        if p["revision"] >= 322:
            vdseffcv = jnp.where(vds == 0.0, 0.0, vdseffcv)
        t0 = abulkcv * vdseffcv
        t1 = 12.0 * (vgsteff - 0.5 * t0 + 1e-20)
        t2 = vdseffcv / t1
        t3 = t0 * t2
        qgate = coxwl * (vgsteff - 0.5 * vdseffcv + t3)
        t7 = 1.0 - abulkcv
        qbulk = coxwl * t7 * (0.5 * vdseffcv - t3)
        if xpart > 0.5:
            qsrc = -coxwl * (0.5 * vgsteff + 0.25 * t0 - t0 * t0 / (2.0 * t1))
        elif xpart < 0.5:
            t1b = t1 / 12.0
            t2b = 0.5 * coxwl / (t1b * t1b)
            t3b = (
                vgsteff * (2.0 * t0 * t0 / 3.0 + vgsteff * (vgsteff - 4.0 * t0 / 3.0))
                - 2.0 * t0 * t0 * t0 / 15.0
            )
            qsrc = -t2b * t3b
        else:
            qsrc = -0.5 * (qgate + qbulk)
        qgate = qgate + qac0 + qsub0
        qbulk = qbulk - (qac0 + qsub0)
        qdrn = -(qgate + qbulk + qsrc)
        return qgate, qbulk, qdrn
    # capMod 3: Δφ_s, the centroid of the inversion charge
    if form["k1ox_nonpositive"]:
        denomi = 0.25 * p["moin"] * vtm
        t0 = 0.5 * p["sqrtphi"]
    else:
        denomi = p["moin"] * vtm * k1ox * k1ox
        t0 = k1ox * p["sqrtphi"]
    deltaphi = vtm * jnp.log1p((2.0 * t0 + vgsteff) * vgsteff / denomi)
    t0 = vgsteff - deltaphi - 0.001
    vgdp = 0.5 * (t0 + jnp.sqrt(t0 * t0 + vgsteff * 0.004))
    t3 = 4.0 * (vth - vfbzb - p["phi"])
    tox2 = 2.0e8 * p["tox"]
    t0 = jnp.where(t3 >= 0.0, (vgsteff + t3) / tox2, (vgsteff + 1.0e-20) / tox2)
    tcen = 1.9e-9 / (1.0 + jnp.exp(0.7 * jnp.log(jnp.maximum(t0, 1e-300))))
    ccen = EPSSI / tcen
    coxeff = cox / (cox + ccen) * ccen
    coxwlc = coxwl * coxeff / cox
    vdsatcv = vgdp / abulkcv
    t0 = vdsatcv - vds - DELTA_4
    t1 = jnp.sqrt(t0 * t0 + 4.0 * DELTA_4 * vdsatcv)
    vdseffcv = jnp.where(
        t0 >= 0.0, vdsatcv - 0.5 * (t0 + t1),
        vdsatcv * (1.0 - 2.0 * DELTA_4 / jnp.where(t0 >= 0.0, 1.0, t1 - t0)),
    )  # fmt: skip
    if p["revision"] >= 322:
        vdseffcv = jnp.where(vds == 0.0, 0.0, vdseffcv)
    return inversion_charges(coxwlc, abulkcv, vdseffcv, vgdp, qac0, qsub0, xpart)
