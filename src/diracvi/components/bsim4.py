r"""The BSIM4 MOSFET (SPICE ``M`` at ``LEVEL=14`` or ``54``; ngspice's ``bsim4v7`` for
VERSION 4.7, ``bsim4v5`` for 4.0–4.5) at its default modes and, for bsim4v5, igcMod,
igbMod, rgateMod and rbodyMod 1, as a Lagrange–Dirac part with a charge port — BSIM3's
part (:mod:`~diracvi.components.bsim3`) with BSIM4's laws.

Branches in flux form (``L = w q̇``; ``ẇ`` the branch voltage): the channel ``d′→s′``, the
gate ``g→s′``, the bulk junctions ``b→s′`` and ``b→d′`` (rdsMod 0: ``R_ds`` is inside the
channel law; ``RSH`` times the line's NRD/NRS, when given, are resistors to ``d′``, ``s′``).
rgateMod 1: the gate branch starts at an internal ``g′``, joined to ``g`` by
``R_geltd = RSHG (XGW + W_eff,CJ/3NGCON)/(NGCON (L + XL − XGL))``. rbodyMod 1: the
intrinsic device's bulk is an internal ``b′`` (branches ``b′→s′``, ``b′→d′``), the
junctions start at internal ``sb``, ``db``, and five resistors ``1/(GBMIN + 1/R)`` join
``b′–db`` (RBPD), ``b′–b`` (RBPB), ``b′–sb`` (RBPS), ``db–b`` (RBDB), ``sb–b`` (RBSB).

**Gate tunnelling** (igcMod/igbMod 1, :func:`~diracvi.components._bsim4.tunnelling`): a
force on the gate branch, ``I_gs + I_gd + I_gb``; ``I_gd`` returns to ``d′`` through the
channel branch and ``I_gb`` to the bulk through ``b′→s′`` — the gate is no longer a pure
capacitor.

**Currents**: the channel carries ``type·I_ds`` of :func:`~diracvi.components._bsim4.evaluate`
in the mode (``V_DS < 0``: source and drain swapped); the substrate current ``I_sub`` flows
from the mode's drain to the bulk, GIDL from the drain and GISL from the source to the bulk
(:func:`~diracvi.components._bsim4.gidl`); each bulk junction carries dioMod 1's diode
``I_S(e^{V/N V_t} − 1) + G_min V`` continued by its tangent above ``V_jsm = N V_t
ln(IJTHFWD/I_S + 1)``, ``I_S = JSS·A_S + JSWS·P_S + JSWGS·W_eff,CJ`` (0 when ``A_S`` and
``P_S`` are 0: G_min alone).

**Charges** (the port): ``Q_G = Q_g + Q_gso + Q_gdo + CGBO L_eff,CV V_GB``, ``Q_D = Q_d −
Q_gdo − Q_bd``, ``Q_B = Q_b − CGBO L_eff,CV V_GB + Q_bs + Q_bd``, with capMod 2's intrinsic
charges, the overlaps (CGSO/CGDO + CF with CGSL/CGDL's bias-dependent part, CKAPPAS/D), and
each junction's bottom, sidewall and gate-edge depletion charges (``CJS·A_S``, ``CJSWS·P_S``,
``CJSWGS·W_eff,CJ``; linear in ``C`` above 0 V). ``P_S``, ``A_S`` not given: geoMod 0's
``P_S = 2(DMCG + DMCI − DMCGT) + W_eff,CJ``, ``A_S = (DMCG + DMCI − DMCGT) W_eff,CJ``;
given ``PS`` is perMod 1's: less ``W_eff,CJ`` (at least 0 for 4.7; VERSION 4.5 keeps a
negative ``P_S``, its sidewall then a negative capacitance that ``b4v5ld.c`` counts only
under forward bias, as here).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from . import _bsim4 as b4
from ._charge_port import ChargePortPart
from ._junction import depletion_charge
from ._mos_part import bulk_limits, pins_and_kcl, polarity
from ._part import finite, positive
from .bsim3 import _known, _Lagrangian, _Named, _overlap, initial_velocities, law_vector

__all__ = ["BSIM4", "bsim4_current"]


def _junction_form(i_s, nvtm, ijth):
    """dioMod 1's diode, decided once: ``("off", 0, 0)`` for ``I_S ≤ 0`` (G_min alone),
    else ``("limited", V_jsm, I_S e^{V_jsm/N V_t})`` (``BSIM4v7DioIjthVjmEval``)."""
    if isinstance(i_s, float) and i_s <= 0.0:
        return "off", 0.0, 0.0
    vjm = nvtm * np.log(ijth / i_s + 1.0)
    return "limited", vjm, i_s * np.exp(vjm / nvtm)


def _junction(v, form, i_s, nvtm, vjm, is_evjm, gmin):
    """dioMod 1's junction current with ``G_min`` (``b4v7ld.c``)."""
    if form == "off":
        return gmin * v
    t2 = v / nvtm
    below = jnp.where(
        t2 < -b4.EXP_THRESHOLD,
        i_s * (b4.MIN_EXP - 1.0),
        i_s * jnp.expm1(jnp.clip(jnp.minimum(v, vjm) / nvtm, -b4.EXP_THRESHOLD, None)),
    )
    above = is_evjm - i_s + is_evjm / nvtm * (v - vjm)
    return jnp.where(v <= vjm, below, above) + gmin * v


def _mode(vgs, vds, vbs, sign):
    """NMOS-oriented ``(V_GS, V_DS, V_BS)`` of the mode and whether it is forward (``V_DS
    ≥ 0``, ngspice's mode 1 at 0); ``V_DS`` of the mode as ``±V_DS``, whose derivative at 0
    is +1 (``|V_DS|``'s would be 0 there)."""
    gs, ds, bs = sign * vgs, sign * vds, sign * vbs
    forward = ds >= 0.0
    return (jnp.where(forward, gs, gs - ds), jnp.where(forward, ds, -ds),
            jnp.where(forward, bs, bs - ds), forward)  # fmt: skip


def bsim4_current(params: dict, kind: str, vgs, vds, vbs, mobmod=0):
    """The channel current into the drain for true (signed) terminal voltages of a device
    with :func:`~diracvi.components._bsim4.size_dependent`'s ``params``."""
    sign = polarity("bsim4_current", kind)
    g, d, b, fwd = _mode(vgs, vds, vbs, sign)
    i = b4.evaluate(params, g, d, b, mobmod=mobmod, xpart=-1.0)[0]
    return sign * jnp.where(fwd, i, -i)


class _Law(eqx.Module):
    """The part's force or charge as data (BSIM3's :class:`~.bsim3._Law`, BSIM4's laws)."""

    what: str = eqx.field(static=True)
    layout: tuple = eqx.field(static=True)
    numbers: jax.Array

    def __call__(self, q, v):
        layout = dict(self.layout)
        p = _Named(layout, self.numbers)
        p._static["model"] = dict(layout["model"])
        idx = {c: j for j, c in enumerate(layout["coords"])}
        return (_force if self.what == "force" else _charge)(layout, p, idx, q, v)


def _force(layout, p, idx, q, v):
    """``F``: minus the channel, junction (with I_sub, GIDL, GISL), gate tunnelling and
    resistor currents. The intrinsic bulk (rbodyMod 1: the internal ``b′``) carries I_sub,
    GIDL, GISL and I_gb; the junction branches (from ``sb``, ``db`` under rbodyMod 1) the
    diodes. The gate tunnelling leaves the gate on its branch ``g→s′`` and reaches the
    drain and the bulk through the channel and bulk branches."""
    sign, mult, g = layout["sign"], p["mult"], p["gmin"]
    bs, bd = layout["bulk"]
    vgs, vds, vbs = v[idx["wg"]], v[idx["w"]], v[idx[bs]]
    gm, dm, bm, fwd = _mode(vgs, vds, vbs, sign)
    extras = {}
    ids, isub, _ = b4.evaluate(p, gm, dm, bm, mobmod=layout["mobmod"], xpart=-1.0, extras=extras)
    i_ch = sign * jnp.where(fwd, ids, -ids)
    i_sub = sign * isub
    igidl, igisl = b4.gidl(p, sign * vds, sign * vgs, sign * vbs, dict(layout["form"]))
    f = jnp.zeros(len(idx), dtype=v.dtype)
    igc, igb, pigcd_given = layout["gate"]
    if igc or igb:
        i_gs, i_gd, i_gb = (sign * i for i in b4.tunnelling(
            p, extras, sign * vgs, sign * (vgs - vds), fwd, igc, igb, pigcd_given))  # fmt: skip
        f = f.at[idx["wg"]].set(-mult * (i_gs + i_gd + i_gb))
        i_ch = i_ch - i_gd  # I_gd flows s′ → d′ on the channel branch
    else:
        i_gb = 0.0
    f = f.at[idx["w"]].set(-mult * i_ch)
    for k, form in layout["junctions"]:
        vj = sign * v[idx["wbs" if k == "s" else "wbd"]]
        junction = sign * _junction(
            vj, form, p[f"isat_{k}"], p[f"nvtm_{k}"], p[f"vjm_{k}"], p[f"isevjm_{k}"], g
        )
        f = f.at[idx["wbs" if k == "s" else "wbd"]].add(-mult * junction)
    # I_sub (from the mode's drain), GIDL (drain), GISL (source) and I_gb (through s′)
    # enter the intrinsic bulk
    f = f.at[idx[bs]].add(mult * (jnp.where(fwd, 0.0, i_sub) + sign * igisl + i_gb))
    f = f.at[idx[bd]].add(mult * (jnp.where(fwd, i_sub, 0.0) + sign * igidl))
    for k in layout["resistors"]:
        f = f.at[idx[f"qr{k}"]].set(-p[f"r_{k}"] / mult * v[idx[f"qr{k}"]])
    return f


def _charge(layout, p, idx, q, v):
    """``Q``: the terminal charges on the gate, channel and junction lines (×M)."""
    sign = layout["sign"]
    bs, _ = layout["bulk"]
    vgs, vds, vbs = v[idx["wg"]], v[idx["w"]], v[idx[bs]]
    vjs, vjd = v[idx["wbs"]], v[idx["wbd"]]  # the junctions' (rbodyMod 1: from sb, db)
    gm, dm, bm, fwd = _mode(vgs, vds, vbs, sign)
    _, _, intrinsic = b4.evaluate(
        p, gm, dm, bm, mobmod=layout["mobmod"], xpart=layout["xpart"], charges_only=True
    )
    vgd, vgb = vgs - vds, vgs - vbs
    off_s, off_d = layout["overlap_off"]
    qgso = _overlap(sign * vgs, p["cgso_eff"], p["weffcv"], p["cgsl"], p["ckappas"], 2, off_s)
    qgdo = _overlap(sign * vgd, p["cgdo_eff"], p["weffcv"], p["cgdl"], p["ckappad"], 2, off_d)
    qgbo = p["cgbo_eff"] * sign * vgb
    if intrinsic is None:
        qg = qb = qd = 0.0 * vgs
    else:
        qg, qb, qmode = intrinsic
        qd = jnp.where(fwd, qmode, -(qg + qb + qmode))
    junction = {"s": 0.0 * vjs, "d": 0.0 * vjd}
    for k, j in layout["caps"]:
        vn = sign * (vjs if k == "s" else vjd)
        junction[k] = junction[k] + depletion_charge(
            vn, p[f"c{j}_{k}"], p[f"pb{j}_{k}"], p[f"mj{j}_{k}"], 0.0
        )
    for k, j in layout["negative_caps"]:
        # b4v5ld.c: a wall of C < 0 is skipped under reverse bias, linear in C forward
        vn = sign * (vjs if k == "s" else vjd)
        c, pb, mj = p[f"c{j}_{k}"], p[f"pb{j}_{k}"], p[f"mj{j}_{k}"]
        junction[k] = junction[k] + jnp.where(vn > 0.0, c * vn * (1.0 + 0.5 * vn * mj / pb), 0.0)
    out = jnp.zeros(len(idx), dtype=v.dtype)
    out = out.at[idx["wg"]].set(sign * (qg + qgso + qgdo + qgbo))
    out = out.at[idx["w"]].set(sign * (qd - qgdo))
    out = out.at[idx[bs]].add(sign * (qb - qgbo))
    out = out.at[idx["wbs"]].add(sign * junction["s"])
    return p["mult"] * out.at[idx["wbd"]].add(sign * junction["d"])


_INSTANCE = {"ad": None, "as_": None, "pd": None, "ps": None, "nrd": None, "nrs": None,
             "m": 1.0, "delvto": 0.0, "mulu0": 1.0}  # fmt: skip


def junction_geometry(m: dict, weffcj: float, inst: dict, revision=47, where="BSIM4") -> dict:
    """``{"s": (A, P), "d": (A, P)}``: the junctions' effective areas and perimeters
    (``b4v7temp.c`` with ``BSIM4v7PAeffGeo`` at geoMod 0, NF = 1, perMod 1; bsim4v5 does
    not clamp a given perimeter below W_eff,CJ at 0)."""
    t0 = m["dmcg"] - m["dmcgt"] + m["dmci"]
    out = {}
    for k in "sd":
        a, per = inst["as_" if k == "s" else "ad"], inst["p" + k]
        if per is None:
            p_eff = 2.0 * t0 + weffcj
        elif revision == 45:  # not clamped: a negative sidewall (module docstring)
            p_eff = per - weffcj
        elif per <= 0.0:
            p_eff = 0.0
        else:
            p_eff = max(per - weffcj, 0.0)
        a_eff = t0 * weffcj if a is None else max(a, 0.0)
        out[k] = (a_eff, p_eff)
    return out


def BSIM4(
    kind="nmos",
    *,
    w=5e-6,
    l=5e-6,  # noqa: E741  (SPICE's name)
    name: str,
    version="4.7",
    gmin=1e-12,
    v0=(0.0, 0.0, 0.0),
    model: dict | None = None,
    **instance,
) -> ChargePortPart:
    r"""A BSIM4 MOSFET with pins ``d g s b`` (module docstring) of drawn ``w`` × ``l`` (m),
    its card's **given** parameters ``model`` (ngspice's lower-case names,
    :data:`~diracvi.components._bsim4.NAMES`), ``version`` the card's VERSION (4.7, or
    4.0–4.5), and the line's ``ad``, ``as_``, ``pd``, ``ps`` (m², m; ``None``: not given),
    ``nrd``, ``nrs``, ``m``, ``delvto``, ``mulu0``. At the card's TNOM, the modes of
    :data:`~diracvi.components._bsim4.MODES` (igcMod, igbMod, rgateMod, rbodyMod 1 for
    4.0–4.5 only); others are refused by name."""
    where = f"BSIM4 {name!r}"
    sign = polarity(where, kind)
    unknown = sorted(set(instance) - set(_INSTANCE))
    if unknown:
        raise TypeError(f"BSIM4() got an unexpected keyword argument {unknown[0]!r}")
    inst = _INSTANCE | instance
    card = dict(model or {})
    revision = b4.version_code(version)
    problems = check_card(card, revision)
    if problems:
        raise ModelError(f"{where}: " + "; ".join(problems))
    mult = positive(where, "m", inst["m"])
    w, l = positive(where, "w", w), positive(where, "l", l)  # noqa: E741
    p = b4.size_dependent(card, sign, l, w, inst["delvto"], inst["mulu0"], revision)
    m = p["model"]
    mobmod, xpart = int(m["mobmod"]), float(m["xpart"])
    g = positive(where, "gmin", gmin)
    for k in ("as_", "ad", "ps", "pd", "nrs", "nrd"):
        if inst[k] is not None:
            finite(where, k, inst[k])
    weffcj = float(p["weffcj"])
    geo = junction_geometry(m, weffcj, inst, revision, where)
    numbers = {k: x for k, x in p.items() if k not in ("model", "revision")}
    numbers.update(mult=mult, gmin=g)
    junction_forms, present, negative = [], [], []
    for k in "sd":
        a_eff, p_eff = geo[k]
        js, jsw, jswg = m[f"js{k}"], m[f"jsw{k}"], m[f"jswg{k}"]
        nj, ijth = m[f"nj{k}"], m[f"ijth{k}fwd"]
        if a_eff <= 0.0 and p_eff <= 0.0:
            i_sat = 1.0e-14 if revision == 45 else 0.0  # b4v5ld.c's floor, b4v7ld.c's 0
        else:
            i_sat = a_eff * js + p_eff * jsw + weffcj * jswg
        nvtm = float(p["vtm"]) * nj
        form, vjm, is_evjm = _junction_form(float(i_sat), nvtm, ijth)
        junction_forms.append((k, form))
        numbers.update({f"isat_{k}": i_sat, f"nvtm_{k}": nvtm, f"vjm_{k}": vjm,
                        f"isevjm_{k}": is_evjm})  # fmt: skip
        walls = ((m[f"cj{k}"] * a_eff, m[f"pb{k}"], m[f"mj{k}"]),
                 (m[f"cjsw{k}"] * p_eff, m[f"pbsw{k}"], m[f"mjsw{k}"]),
                 (m[f"cjswg{k}"] * weffcj, m[f"pbswg{k}"], m[f"mjswg{k}"]))  # fmt: skip
        for j, (c, pb, mj) in enumerate(walls):
            if isinstance(c, float) and c < 0.0:  # bsim4v5's negative sidewall
                negative.append((k, j))
                numbers.update({f"c{j}_{k}": c, f"pb{j}_{k}": pb, f"mj{j}_{k}": mj})
            elif not _known(c, 0.0):
                if _known(mj, 1.0):
                    raise ModelError(f"{where}: a junction grading coefficient of 1 is not built.")
                present.append((k, j))
                numbers.update({f"c{j}_{k}": c, f"pb{j}_{k}": pb, f"mj{j}_{k}": mj})
    res = {}
    for k in "ds":
        squares = inst["nr" + k]
        r = m["rsh"] * squares if squares is not None else 0.0
        if r < 0.0:
            raise ModelError(f"{where}: RSH·NR{k.upper()} = {r:g} Ω must be ≥ 0.")
        res[k] = r
        if r > 0.0:
            numbers[f"r_{k}"] = r
    inner = {k: k.upper() if res[k] > 0.0 else k for k in "ds"}
    rgate, rbody = (int(card.get(k, 0.0)) for k in ("rgatemod", "rbodymod"))
    gate = "G" if rgate else "g"
    # rbodyMod 1: the intrinsic bulk b′ (B), the junctions' sb (SB) and db (DB)
    body = {"b": "B", "sb": "SB", "db": "DB"} if rbody else {"b": "b", "sb": "b", "db": "b"}
    branches = {
        "ch": (("q", "w"), inner["d"], inner["s"]),
        "gs": (("sg", "wg"), gate, inner["s"]),
        "bs": (("qbs", "wbs"), body["sb"], inner["s"]),
        "bd": (("qbd", "wbd"), body["db"], inner["d"]),
    }
    if rbody:
        branches["bps"] = (("qbps", "wbps"), "B", inner["s"])
        branches["bpd"] = (("qbpd", "wbpd"), "B", inner["d"])
    for k in "ds":
        if res[k] > 0.0:
            branches[f"r{k}"] = ((f"qr{k}",), k, inner[k])
    resistors = [k for k in "ds" if res[k] > 0.0]
    if rgate:
        numbers["r_g"] = gate_resistance(m, float(p["weffcj"]), l, where)
        branches["rg"] = (("qrg",), "g", "G")
        resistors.append("g")
    if rbody:
        # b4v5temp.c: each conductance GBMIN + 1/R (1e3 S below 1 mΩ)
        for k, plus, minus in (("bpd", "B", "DB"), ("bpb", "B", "b"), ("bps", "B", "SB"),
                               ("bdb", "DB", "b"), ("bsb", "SB", "b")):  # fmt: skip
            r = m["rb" + k[1:]]
            numbers[f"r_{k}"] = 1.0e-3 if r < 1.0e-3 else 1.0 / (m["gbmin"] + 1.0 / r)
            branches[f"r{k}"] = ((f"qr{k}",), plus, minus)
            resistors.append(k)
    coords = [c for names, _, _ in branches.values() for c in names]
    idx = {c: j for j, c in enumerate(coords)}
    internal = [inner[k] for k in "ds" if res[k] > 0.0]
    internal += (["G"] if rgate else []) + (["B", "DB", "SB"] if rbody else [])
    pins, rows = pins_and_kcl(branches, idx, internal)
    names = tuple(numbers)
    model_static = tuple((k, float(m[k])) for k in ("ados", "bdos", "pditsl"))
    layout = (
        ("coords", tuple(coords)),
        ("sign", sign),
        ("mobmod", mobmod),
        ("xpart", xpart),
        ("revision", revision),
        ("form", b4.branches(p)),
        ("model", model_static),
        ("junctions", tuple(junction_forms)),
        ("caps", tuple(present)),
        ("negative_caps", tuple(negative)),
        ("resistors", tuple(resistors)),
        ("bulk", ("wbps", "wbpd") if rbody else ("wbs", "wbd")),
        ("gate", (bool(card.get("igcmod", 0.0)), bool(card.get("igbmod", 0.0)), "pigcd" in card)),
        ("overlap_off", tuple(isinstance(p[c], float) and p[c] == 0.0 for c in ("cgsl", "cgdl"))),
        ("names", names),
    )
    vector = law_vector(numbers, names)
    pairs = tuple((idx[ns[0]], idx[ns[1]]) for ns, _, _ in branches.values() if len(ns) == 2)
    initial_v = initial_velocities(where, v0, idx, len(coords))
    if rbody:
        for inner_b, junction in (("wbps", "wbs"), ("wbpd", "wbd")):
            initial_v[idx[inner_b]] = initial_v[idx[junction]]
    # Newton limits the bulk junctions (pnjlim at b4v5ld.c's V_crit of 1e-14 A) and, under
    # rbodyMod 1, the intrinsic bulk b′ too, as b4v5ld.c limits V_BS (and V_DBS, V_SBS):
    # unlimited, the first step of ng_ro_17_4's inverter (body resistors ×100) from V = 0
    # swung the PMOS's b′ to +40 V, −112 V, +2.5 V, … (Newton cycling with period 4 at a
    # residual of 1e-13, its scaled Jacobian's condition ~300: not a singular step); with
    # b′ limited it converges in 4 iterations
    bulk = ("wbs", "wbd", "wbps", "wbpd") if rbody else ("wbs", "wbd")
    junctions, limits = bulk_limits(sign, dict.fromkeys(bulk, 1.0e-14))
    return ChargePortPart(
        tuple(coords),
        _Lagrangian(pairs),
        force=_Law("force", layout, vector),
        charge=_Law("charge", layout, vector),
        junctions=junctions,
        junction_limits=limits,
        constraints=np.array(rows) if rows else None,
        constraint_names=tuple(f"KCL({n.lower()}')" for n in internal) if rows else None,
        name=name,
        pins=tuple(pins),
        currents=(),
        initial_v=initial_v,
        role="transistor",
        branch_roles=(("sg", "current"),),
        parameters=(),
    )


def gate_resistance(m: dict, weffcj: float, l: float, where: str) -> float:  # noqa: E741
    """rgateMod 1's gate electrode resistance (``b4v5temp.c``, NF = 1): ``R_geltd =
    RSHG (XGW + W_eff,CJ/3NGCON)/(NGCON (L + XL − XGL))``; 1 mΩ (ngspice's 1e3 S) when
    that is not positive."""
    r = m["rshg"] * (m["xgw"] + weffcj / 3.0 / m["ngcon"]) / (m["ngcon"] * (l + m["xl"] - m["xgl"]))
    return r if r > 0.0 else 1.0e-3


#: the modes built for bsim4v5 (VERSION 4.0–4.5) only
V5_MODES = ("igcmod", "igbmod", "rgatemod", "rbodymod")


def check_card(card: dict, revision=None) -> list[str]:
    """Every reason the card's **given** values ``card`` (lower-case names, without LEVEL
    and VERSION) are outside what is built: unknown names, modes and fixed parameters
    (:data:`~._bsim4.MODES`, :data:`~._bsim4.FIXED`), each with its fix; ``revision`` 47
    (bsim4v7) also refuses :data:`V5_MODES` at 1 (built from bsim4v5's equations)."""
    problems = []
    for key in V5_MODES:
        if revision == 47 and card.get(key, 0.0) == 1.0:
            problems.append(
                f"{key}=1 is not supported at VERSION 4.7 (diracvi builds it as ngspice's "
                f"bsim4v5 computes it, VERSION 4.0–4.5); set {key}=0 or VERSION=4.5"
            )
    ngcon = card.get("ngcon", 1.0)
    if isinstance(ngcon, float) and ngcon not in (1.0, 2.0):
        problems.append(f"ngcon={ngcon:g} is not supported (ngspice allows 1 or 2); use 1 or 2")
    for key, x in card.items():
        if key in b4.FIXED:
            default, why = b4.FIXED[key]
            if default is None or not (isinstance(x, float) and x == default):
                problems.append(f"{key}={x:g} is not supported ({why}); remove it")
            continue
        if key not in b4.NAMES:
            problems.append(f"parameter {key!r} is not supported by diracvi's BSIM4; remove it")
            continue
        if key in b4.MODES:
            allowed, what = b4.MODES[key]
            if float(x) not in allowed:
                problems.append(f"{key}={x:g} is not supported; diracvi has {what}")
    return problems
