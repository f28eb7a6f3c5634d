"""``.model`` cards for bipolar transistors (NPN, PNP) and the ``Q`` line (the ``M`` line
and NMOS/PMOS cards are :mod:`._mos`).

Parameter names, aliases and defaults are ngspice's (Gummel–Poon level 1). A parameter is
either used, or accepted with a note because at its value it cannot change the answer
(noise coefficients, the grading of a capacitance that is zero, the temperature
coefficients of the refused TLEV = 3 and TLEVC = 1), or refused with the reason; the
temperature update is ngspice 39's (:func:`diracvi.components._temperature.bjt`). Other
levels are refused at the element line, naming the model's line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace

from .. import components as cp
from ..components._temperature import BJT as BJT_TEMPERATURE
from ..components._temperature import BJT_ALIASES as BJT_TEMPERATURE_ALIASES
from ..components._temperature import bjt as bjt_at
from ..components._temperature import kelvin
from ._cards import NodeIC, built, device_temperature, element_card

KINDS = {"NPN": "npn", "PNP": "pnp", "NMOS": "nmos", "PMOS": "pmos"}

_BJT = {
    "is": 1e-16, "bf": 100.0, "nf": 1.0, "vaf": 0.0, "ikf": 0.0, "ise": 0.0, "ne": 1.5,
    "br": 1.0, "nr": 1.0, "var": 0.0, "ikr": 0.0, "isc": 0.0, "nc": 2.0, "rb": 0.0,
    "re": 0.0, "rc": 0.0, "cje": 0.0, "vje": 0.75, "mje": 0.33, "tf": 0.0, "cjc": 0.0,
    "vjc": 0.75, "mjc": 0.33, "tr": 0.0, "fc": 0.5, "xtf": 0.0, "vtf": 0.0, "itf": 0.0,
    "cjs": 0.0, "vjs": 0.75, "mjs": 0.0,
}  # fmt: skip
_BJT_ALIAS = {
    "va": "vaf", "ik": "ikf", "c2": "ise", "vb": "var", "c4": "isc", "pe": "vje", "me": "mje",
    "pc": "vjc", "mc": "mjc", "tref": "tnom", "csub": "cjs", "ccs": "cjs", "ps": "vjs",
    "ms": "mjs",
}  # fmt: skip
# B-C capacitance split, bias-dependent base resistance (RBM: RB when not given)
_BJT.update({"xcjc": 1.0, "irb": 0.0, "rbm": None, "iss": 0.0, "ns": 1.0})
_BJT_FIXED = {
    "ptf": (0.0, "excess phase"),
}  # fmt: skip
# only act on noise (the temperature ones: components._temperature.BJT)
_BJT_INERT = ("kf", "af")
# the substrate junction's place: to c′ (vertical, 1: NPN's default) or b′ (lateral, −1)
_BJT_SUBS = {"NPN": 1.0, "PNP": -1.0}
# the temperature coefficients of TLEV = 3 and TLEVC = 1 (refused) and of ISS, IRB (fixed 0)
_TEMPCO = re.compile(r"^(t[a-z]+[12]|ctc|cte|cts|tvj[ces])$")


@dataclass
class DeviceModel:
    """A transistor ``.model`` card: its type, level, values (ngspice names) and notes."""

    kind: str  # npn | pnp | nmos | pmos
    level: float
    values: dict
    line: str  # where the .model card is ("line 7", "lib.mod line 3")
    notes: list = field(default_factory=list)


def read_model(kind: str, kw: dict, value, fail, number) -> DeviceModel:
    """Check a transistor ``.model`` card's parameters; ``value(token, what)`` evaluates,
    ``fail(why)`` builds the line's error."""
    table, alias = _BJT, _BJT_ALIAS
    fixed, inert = _BJT_FIXED, _BJT_INERT
    values, notes = dict(table) | BJT_TEMPERATURE, []
    level = value(kw["level"], f"{kind} LEVEL") if "level" in kw else 1.0
    if level != 1.0:
        # another model (VBIC, HICUM, …): refused by its level at the element line, not
        # by the first of its parameters that Gummel–Poon lacks
        return DeviceModel(KINDS[kind], level, values, number)
    for key, token in kw.items():
        key = BJT_TEMPERATURE_ALIASES.get(key, alias.get(key, key))
        x = value(token, f"{kind} {key.upper()}")
        if key == "level":
            level = x
        elif key in BJT_TEMPERATURE:
            values[key] = x
        elif key in table:
            values[key] = x
        elif key in fixed:
            default, what = fixed[key]
            if x != default:
                raise fail(
                    f"{kind} parameter {key.upper()}={token} ({what}) is not supported; only "
                    f"its default {default:g} (drop it)"
                )
        elif key in inert or _TEMPCO.match(key):
            notes.append(f"{number}: {kind} {key.upper()} ignored (no effect here)")
        elif key == "subs":
            if x != _BJT_SUBS[kind]:
                raise fail(
                    f"{kind} parameter SUBS={token} is not supported; only its default "
                    f"{_BJT_SUBS[kind]:g} (the substrate junction at the internal "
                    f"{'collector' if kind == 'NPN' else 'base'}; drop it)"
                )
        else:
            raise fail(f"{kind} parameter {key.upper()!r} is not known or not supported")
    return DeviceModel(KINDS[kind], level, values, number, notes)


#: ngspice's BJT levels, for refusals that name the model a card asks for
BJT_LEVELS = {4: "VBIC", 8: "HICUM level 2"}


def _level(name, model: DeviceModel, fail):
    if model.level != 1:
        known = BJT_LEVELS.get(int(model.level)) if model.level == int(model.level) else None
        raise fail(
            f"element {name!r}: model ({model.line}) is LEVEL={model.level:g}"
            + (f" ({known})" if known else "")
            + "; only level 1 is supported (Gummel–Poon)"
        )


def bjt(name, pos, kw, model: DeviceModel, value, fail, ic, notes, number, models, parts=None):
    """``Qname c b e [s] model [area] [OFF]`` → (part, nodes); ``parts``: the read's parts
    by their arguments (:func:`~._cards.built`), for alike lines built once."""
    _level(name, model, fail)
    if model.kind not in ("npn", "pnp"):
        raise fail(f"element {name!r}: model is {model.kind.upper()}, a Q line needs NPN/PNP")
    fields = [t for t in pos[1:] if t.lower() != "off"]
    at = next((k for k, t in enumerate(fields) if t.lower() in models), None)
    if at not in (3, 4) or len(fields) > at + 2:
        raise fail("expected 'Qname c b e [s] model [area] [OFF]'")
    nodes = {"c": fields[0], "b": fields[1], "e": fields[2], "s": fields[3] if at == 4 else "0"}
    area = value(fields[at + 1], f"{name} area") if len(fields) > at + 1 else 1.0
    for key, token in kw.items():
        if key == "area":
            area = value(token, f"{name} AREA")
        else:
            raise fail(f"element {name!r}: parameter {key.upper()} is not supported on Q lines")
    v = model.values
    vb, vc, ve, vs = (ic.get(nodes[k], 0.0) for k in "bces")
    part = built(
        parts, cp.BJT, model.kind, is_=v["is"], bf=v["bf"], br=v["br"], nf=v["nf"], nr=v["nr"],
        vaf=v["vaf"], var=v["var"], ikf=v["ikf"], ikr=v["ikr"], ise=v["ise"], ne=v["ne"],
        isc=v["isc"], nc=v["nc"], rb=v["rb"], rc=v["rc"], re=v["re"], cje=v["cje"],
        vje=v["vje"], mje=v["mje"], cjc=v["cjc"], vjc=v["vjc"], mjc=v["mjc"], tf=v["tf"],
        tr=v["tr"], xtf=v["xtf"], vtf=v["vtf"], itf=v["itf"], cjs=v["cjs"], vjs=v["vjs"],
        mjs=v["mjs"], fc=v["fc"], area=area, name=name, xcjc=v["xcjc"], rbm=v["rbm"],
        irb=v["irb"], iss=v["iss"], ns=v["ns"],
        v0=(vb - ve, vb - vc, vs - (vc if model.kind == "npn" else vb)),
    )  # fmt: skip
    return part, nodes


# ------------------------------------------------ handlers on the element table
def _card(ctx, token, line, kinds):
    """The transistor ``.model`` named ``token``, checked (its type among ``kinds``)."""
    kind, params, where, fail = element_card(ctx, token, line, kinds)
    model = read_model(kind, params, lambda x, what: x, fail, where)
    for note in model.notes:
        ctx.note(line, note)
    return model


def q_line(ctx, name, pos, kw, line):
    """``Qname c b e [s] model [area] [OFF] [TEMP=t] [DTEMP=d]`` (Gummel–Poon level 1) at
    its temperature (ngspice 39's update, :func:`~diracvi.components._temperature.bjt`)."""
    found = ctx.find_model(pos[4:6])
    if found is None:
        token = pos[4] if len(pos) > 4 else "?"
        raise line.fail(
            f"element {pos[0]!r}: no defined model among {pos[4:6]} (add '.model {token} "
            "NPN(IS=… BF=…)'); form 'Qname c b e [s] model [area]'"
        )
    token = found[0]
    model = _card(ctx, token, line, ("NPN", "PNP"))
    temp = device_temperature(ctx, pos[0], kw, line)
    nominal = ctx.tnom if model.values["tnom"] is None else model.values["tnom"]
    values = bjt_at(model.values, kelvin(temp), kelvin(nominal), name=name)
    model = replace(model, values=values)
    kw = {k: t for k, t in kw.items() if k not in ("temp", "dtemp")}
    notes: list[str] = []
    value = lambda t, what: ctx.value(t, line, what)  # noqa: E731
    part, nodes = bjt(
        name, pos, kw, model, value, line.fail, NodeIC(ctx), notes, line.where, {token.lower()},
        ctx.reader.parts,
    )  # fmt: skip
    for note in notes:
        ctx.note(line, note.split(": ", 1)[1])
    return part, nodes
