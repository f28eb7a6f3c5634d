"""NMOS/PMOS ``.model`` cards and the ``M`` line (ngspice's level 1, Shichman–Hodges; level
2, Grove–Frohman: :mod:`._mos2`; level 3, semi-empirical: :mod:`._mos3`; level 6,
Sakurai–Newton: :mod:`._mos6`).

Parameter names, aliases, units and defaults are ngspice's ``mos1``: the process
parameters (``TOX`` m, ``U0`` cm²/V·s, ``NSUB`` cm⁻³, ``NSS`` cm⁻², ``TPG``) derive KP,
PHI, GAMMA and VTO when the card does not give them, and ``TOX`` gives Meyer's gate
capacitances (:mod:`diracvi.components._mos1`); ``RD``/``RS`` (or ``RSH`` times the
line's ``NRD``/``NRS``), ``CBD``/``CBS`` (or ``CJ`` times ``AD``/``AS``), ``CJSW`` times
``PD``/``PS``, ``JS`` times ``AD``/``AS`` (when both are given, else ``IS``), ``PB``,
``MJ``, ``MJSW``, ``FC``. A model name with bins (``nch.1``, ``nch.2``…) is resolved
by the line's ``L`` and ``W`` first (:mod:`._binning`). Other levels (MOS9, BSIM …) are
refused at the element line, by name, naming the model's line; a ``VDMOS`` card makes
the line ngspice's three-terminal VDMOS (:mod:`._vdmos`). Levels 2, 3 and 6 share all
of this but the drain current's parameters (:mod:`._mos_card` holds what they share;
:mod:`._mos2`, :mod:`._mos3`, :mod:`._mos6`); level 3 derives PHI with ``mos3temp``'s
intrinsic density at TNOM.
"""

from __future__ import annotations

from .. import components as cp
from ..components._mos1 import NI, intrinsic_density, process_parameters
from ..components._temperature import kelvin
from ..components._temperature import mos1 as mos1_at
from ..errors import ModelError
from ._binning import binned
from ._bsim3 import LEVELS as BSIM3_LEVELS
from ._bsim3 import bsim3_line, read_bsim3_model
from ._bsim4 import LEVELS as BSIM4_LEVELS
from ._bsim4 import bsim4_line, read_bsim4_model
from ._cards import NodeIC, built, device_temperature, element_card
from ._mos2 import law as law2
from ._mos2 import read_mos2_model
from ._mos3 import law as law3
from ._mos3 import read_mos3_model
from ._mos6 import law, read_mos6_model
from ._mos_card import PROCESS, level_card
from ._vdmos import vdmos_line

_ALIAS = {"vt0": "vto", "uo": "u0"}
CARD = level_card(1, "Shichman–Hodges", {"lambda": 0.0}, ("kp", *PROCESS, "tnom"))
# ngspice's MOSFET levels, for refusals that name the model a card asks for
LEVELS = {
    2: "MOS2, Grove–Frohman", 3: "MOS3, semi-empirical", 4: "BSIM1", 5: "BSIM2",
    6: "MOS6, Sakurai–Newton", 8: "BSIM3", 9: "MOS9", 10: "B4SOI", 14: "BSIM4",
    44: "EKV", 49: "BSIM3", 54: "BSIM4", 68: "HiSIM2", 73: "HiSIM_HV",
}  # fmt: skip


def level_name(level: float, version=None) -> str:
    """``"level 8 (BSIM3v3.2)"``: the level and the model ngspice runs at it."""
    name = LEVELS.get(int(level), "") if level == int(level) else ""
    if name.startswith("BSIM") and version is not None:
        name += f"v{version:g}" if isinstance(version, float) else f"v{version}"
    return f"level {level:g}" + (f" ({name})" if name else "")


def read_mos_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The values of an NMOS/PMOS card, checked: ``{name: value}`` with the defaults of
    :data:`CARD` (:mod:`._mos_card`), its optional and process ones only where given.
    Raises ``fail(why)`` naming the level of a card that is neither level 1 nor level 2,
    3 or 6 (:func:`~._mos2.read_mos2_model`, :func:`~._mos3.read_mos3_model`,
    :func:`~._mos6.read_mos6_model`)."""
    kw = {_ALIAS.get(k, k): x for k, x in kw.items()}
    level = kw.get("level", 1.0)
    if level == 6.0:
        return read_mos6_model(kind, kw, fail, notes)
    if level == 2.0:
        return read_mos2_model(kind, kw, fail, notes)
    if level == 3.0:
        return read_mos3_model(kind, kw, fail, notes)
    if level in BSIM3_LEVELS:
        return read_bsim3_model(kind, kw, fail, notes)
    if level in BSIM4_LEVELS:
        return read_bsim4_model(kind, kw, fail, notes)
    if level != 1.0:
        raise fail(
            f"{kind} {level_name(level, kw.get('version'))} is not supported; diracvi "
            "has levels 1 (Shichman–Hodges), 2 (Grove–Frohman), 3 (semi-empirical), 6 "
            "(Sakurai–Newton), 8/49 (BSIM3v3) and 14/54 (BSIM4)"
        )
    return CARD.read(kind, kw, fail, notes)


_INSTANCE = {"l": 100e-6, "w": 100e-6, "m": 1.0, "ad": 0.0, "as": 0.0, "pd": 0.0, "ps": 0.0,
             "nrd": 1.0, "nrs": 1.0}  # fmt: skip


def mosfet(name, pos, kw, kind, v, value, fail, ic, notes, temperature=27.0, tnom=27.0, parts=None):
    """``Mname d g s b model [L= W= M= AD= AS= PD= PS= NRD= NRS= OFF]`` → (part, nodes)
    for the card values ``v`` (:func:`read_mos_model`); a level-1 device at
    ``temperature`` (°C) from its card's TNOM, else ``tnom`` (°C), by ngspice 39's update
    (:func:`~diracvi.components._temperature.mos1`, which ``mos2temp`` and ``mos3temp``
    share for levels 2 and 3; level 3 also scales U0, and both laws read ``V_T`` at the
    device's temperature). ``parts``: the read's parts by their arguments
    (:func:`~._cards.built`), for alike lines built once."""
    extra = [t for t in pos[6:] if t.lower() != "off"]
    if len(pos) < 6 or extra:
        raise fail("expected 'Mname d g s b model [L=… W=… M=… AD AS PD PS NRD NRS OFF]'")
    geo = dict(_INSTANCE)
    for key, token in kw.items():
        if key not in geo:
            raise fail(f"element {name!r}: parameter {key.upper()} is not supported on M lines")
        geo[key] = value(token, f"{name} {key.upper()}")
    if any(t.lower() == "off" for t in pos[6:]):
        notes.append(f"{name} OFF ignored (it only seeds ngspice's DC solve)")
    sign = 1.0 if kind == "nmos" else -1.0
    try:
        nominal = kelvin(tnom if v.get("tnom") is None else v["tnom"])
        # mos3temp takes n_i at TNOM, levels 1 and 2 at 300 K
        ni = intrinsic_density(nominal) if v.get("level") == 3.0 else NI
        process = process_parameters(sign, v, f"model of {name!r}", nominal, ni)
    except ModelError as exc:
        raise fail(str(exc)) from None
    emission = 1.0
    level = v.get("level", 1.0)
    # mos2temp, mos3temp and mos6temp update as mos1temp does
    t = kelvin(temperature)
    v, process, emission = mos1_at(v, process, sign, t, nominal)
    mobility = 1.0 if t == nominal else (t / nominal) ** -1.5  # KP's, U0's, KC's factor
    if level == 3.0 and t != nominal:
        # mos3load's velocity saturation reads U0(T) = U0 (T/T_nom)^{-3/2} (tSurfMob);
        # mos2load reads the card's U0 unscaled, so level 2's stays as given
        v = v | {"u0": v["u0"] * mobility}

    def resistance(r, squares):  # RD over RSH·NRD, as mos1temp
        return v[r] if r in v else v["rsh"] * geo[squares]

    def bottom(c, area):  # CBD over CJ·AD
        return v[c] if c in v else v["cj"] * geo[area]

    with_js = v["js"] != 0.0 and geo["ad"] != 0.0 and geo["as"] != 0.0
    i_s = (v["js"] * geo["ad"], v["js"] * geo["as"]) if with_js else (v["is"], v["is"])
    d, g, s, b = pos[1:5]
    vg = ic.get(g, 0.0)
    v0 = (vg - ic.get(s, 0.0), vg - ic.get(d, 0.0), vg - ic.get(b, 0.0))  # ngspice's getic
    common = dict(
        ld=v["ld"], is_=i_s, m=geo["m"], cgso=v["cgso"], cgdo=v["cgdo"], cgbo=v["cgbo"],
        cox=process["cox"], rd=resistance("rd", "nrd"), rs=resistance("rs", "nrs"),
        cbd=bottom("cbd", "ad"), cbs=bottom("cbs", "as"), cbdsw=v["cjsw"] * geo["pd"],
        cbssw=v["cjsw"] * geo["ps"], pb=v["pb"], mj=v["mj"], mjsw=v["mjsw"], fc=v["fc"],
        v0=v0,
    )  # fmt: skip
    if emission != 1.0:  # V_T(T)/V_T(27 °C): the bulk junctions' and levels 2 and 3's laws'
        common["emission"] = emission
    if v.get("level") == 6.0:
        args = law(v, process)
        args["kc"] = args["kc"] * mobility  # mos6temp: KC (T/T_nom)^{-3/2}, KV unscaled
        part = built(parts, cp.MOSFET6, kind, process["vto"], w=geo["w"], l=geo["l"], name=name,
                     **args, **common)  # fmt: skip
    elif v.get("level") == 2.0:
        del common["cox"]  # level 2 always has an oxide: C'ox from TOX (or 0.1 µm)
        part = built(parts, cp.MOSFET2, kind, w=geo["w"], l=geo["l"], name=name,
                     **law2(v, process), **common)  # fmt: skip
    elif v.get("level") == 3.0:
        del common["cox"]  # level 3 always has an oxide: C'ox from TOX (or 0.1 µm)
        part = built(parts, cp.MOSFET3, kind, w=geo["w"], l=geo["l"], name=name,
                     **law3(v, process), **common)  # fmt: skip
    else:
        part = built(
            parts, cp.MOSFET, kind, process["vto"], process["kp"], v["lambda"], geo["w"],
            geo["l"], process["gamma"], process["phi"], name=name, **common,
        )  # fmt: skip
    return part, {"d": d, "g": g, "s": s, "b": b}


def m_line(ctx, name, pos, kw, line):
    """``Mname d g s b model [L= W= M= AD AS PD PS NRD NRS OFF]`` (levels 1, 2, 3 and 6)."""
    # a VDMOS names its model after three nodes, or after five (its thermal form,
    # 'Mname d g s tj tc model thermal', which vdmos_line refuses by name)
    found = ctx.find_model(pos[4:7])
    if found is not None and found[1] == "VDMOS":
        return vdmos_line(ctx, name, pos, kw, line)
    if len(pos) < 6:
        raise line.fail("expected 'Mname d g s b model [L=… W=…]'")
    pos = [*pos[:5], binned(ctx, pos[0], pos[5], kw, line), *pos[6:]]  # nch → nch.2
    if pos[5].lower() not in ctx.models:
        _more_nodes(ctx, pos, line)
    kind, params, _, fail = element_card(ctx, pos[5], line, ("NMOS", "PMOS"))
    notes: list[str] = []
    values = read_mos_model(kind, params, fail, notes)
    level = params.get("level", 1.0)
    if level in BSIM4_LEVELS:
        temp = device_temperature(ctx, pos[0], kw, line)
        kw = {k: t for k, t in kw.items() if k not in ("temp", "dtemp")}
        value = lambda t, what: ctx.value(t, line, what)  # noqa: E731
        part, nodes = bsim4_line(
            name, pos, kw, kind.lower(), values, value, line.fail, NodeIC(ctx), notes, temp,
            ctx.tnom, ctx.reader.options.get("scale", 1.0), ctx.reader.parts,
        )  # fmt: skip
        for note in notes:
            ctx.note(line, note)
        return part, nodes
    if level in BSIM3_LEVELS:
        temp = device_temperature(ctx, pos[0], kw, line)
        kw = {k: t for k, t in kw.items() if k not in ("temp", "dtemp")}
        value = lambda t, what: ctx.value(t, line, what)  # noqa: E731
        part, nodes = bsim3_line(
            name, pos, kw, kind.lower(), values, value, line.fail, NodeIC(ctx), notes, temp,
            ctx.tnom, ctx.reader.parts,
        )  # fmt: skip
        for note in notes:
            ctx.note(line, note)
        return part, nodes
    temp = device_temperature(ctx, pos[0], kw, line)
    kw = {k: t for k, t in kw.items() if k not in ("temp", "dtemp")}
    value = lambda t, what: ctx.value(t, line, what)  # noqa: E731
    part, nodes = mosfet(
        name, pos, kw, kind.lower(), values, value, line.fail, NodeIC(ctx), notes, temp, ctx.tnom,
        ctx.reader.parts,
    )  # fmt: skip
    for note in notes:
        ctx.note(line, note)
    return part, nodes


def _more_nodes(ctx, pos, line):
    """An M line whose model follows five to seven nodes (ngspice's SOI MOSFETs, the
    BSIM3SOI and BSIM4SOI levels: ``Mname d g s e [p] [b] [t] model``): refused by its model's
    level, or, for a level with four nodes, by the count, not as a model to define
    named by a node (ngspice takes the model as the first token after the nodes that
    names one)."""
    at = next((k for k in range(6, min(len(pos), 9)) if pos[k].lower() in ctx.models), None)
    if at is None:
        return  # no model further on: element_card names the missing one at pos[5]
    kind, params, _, fail = element_card(ctx, pos[at], line, ("NMOS", "PMOS"))
    read_mos_model(kind, params, fail, [])  # refuses a level diracvi does not have
    raise line.fail(
        f"element {pos[0]!r} has {at - 1} nodes before its model {pos[at]!r}; a MOSFET of "
        "levels 1, 2, 3 and 6 has four (Mname d g s b model)"
    )
