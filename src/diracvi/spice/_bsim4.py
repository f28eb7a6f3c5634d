"""NMOS/PMOS ``.model`` cards at ``LEVEL=14`` or ``54``: BSIM4 at its default modes
(ngspice's ``bsim4v7`` for VERSION 4.7, ``bsim4v5`` for 4.0–4.5; ``inpdomod.c`` picks the
model by VERSION, and 4.6 and 4.8 — ngspice's default when VERSION is absent — run other
models, refused here), and for 4.0–4.5 igcMod, igbMod, rgateMod and rbodyMod 1 (gate
tunnelling, the gate electrode resistance, the body resistor network).

The parameters read are :data:`~diracvi.components._bsim4.NAMES`; those absent take
ngspice's defaults or are derived as ``b4v7set.c``/``b4v7temp.c`` derive them. The
temperature coefficients, noise, and the refused modes' parameters are read and have no
effect (at TNOM and the default modes they have none in ngspice either). Refused by
name, every problem of a card at once, with the fix: a mode other than those built
(igcMod, igbMod, rbodyMod, rgateMod above 1 or, at VERSION 4.7, at 1; rdsMod, trnqsMod,
acnqsMod, capMod ≠ 2, mobMod 3, dioMod ≠ 1, geoMod ≠ 0, gidlMod 1, mtrlMod …), NGCON other
than 1 or 2, LAMBDA, VTL and the trap-assisted
tunnelling (JTSS …) when given, any other parameter, and a device whose temperature is
not the card's TNOM. ``.option scale`` scales the line's L, W, PS, PD (and AS, AD by its
square), as ``b4v7par.c`` does.
"""

from __future__ import annotations

from .. import components as cp
from ..components import _bsim4 as b4
from ..components.bsim4 import check_card
from ..errors import ModelError
from ._bsim3 import instance_values
from ._cards import built

LEVELS = (14.0, 54.0)
#: the M line's instance parameters of a BSIM4 device (``None``: not given)
INSTANCE = {"l": 5e-6, "w": 5e-6, "m": 1.0, "ad": None, "as": None, "pd": None, "ps": None,
            "nrd": None, "nrs": None, "delvto": 0.0, "mulu0": 1.0, "nf": 1.0}  # fmt: skip


def read_bsim4_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The given values of a BSIM4 card (names lower-case), checked: ``{name: value}``
    with ``"level"`` and ``"version"``; every problem at once is ``fail(why)``."""
    out = {"level": kw.get("level"), "version": kw.get("version")}
    problems = []
    try:
        out["revision"] = b4.version_code(out["version"])
    except ModelError:
        v = out["version"]
        text = "4.8.3, ngspice's default" if v is None else (
            f"{v:g}" if isinstance(v, float) else str(v))  # fmt: skip
        problems.append(
            f"{kind} level {kw['level']:g} (BSIM4v{text}) is not supported; diracvi's BSIM4 has "
            "VERSION 4.7 (ngspice's bsim4v7) and 4.0–4.5 (bsim4v5), and ngspice runs 4.6 and "
            "4.8 (its default when VERSION is absent) with other models"
        )
    card = {}
    for key, x in kw.items():
        if key in ("level", "version"):
            continue
        if out.get("revision") == 45 and key in b4.ONLY_47:
            notes.append(
                f"{kind} {key.upper()} ignored: not a parameter of ngspice's bsim4v5, which "
                "runs VERSION 4.0–4.5 and ignores it ('unrecognized parameter')"
            )
            continue
        if key in b4.INERT or (key[1:] in b4.INERT_BINNED and key[0] in "lwp"):
            notes.append(f"{kind} {key.upper()} has no effect at TNOM and the default modes")
        card[key] = x
    problems += check_card(card, out.get("revision"))
    if problems:
        raise fail(f"{kind} BSIM4 (level {kw['level']:g}) card: " + "; ".join(problems))
    out.update(card)
    return out


def bsim4_line(name, pos, kw, kind, values, value, fail, ic, notes, temperature, tnom, scale,
               parts=None):  # fmt: skip
    """``Mname d g s b model [L= W= M= AD= AS= PD= PS= NRD= NRS= DELVTO= MULU0= NF=1]`` of
    a BSIM4 card → (part, nodes)."""
    geo = instance_values("BSIM4", INSTANCE, name, pos, kw, values, value, fail, temperature, tnom)
    if geo["nf"] != 1.0:
        raise fail(f"element {name!r}: NF={geo['nf']:g} is not supported (fingers: NF = 1 only)")
    if any(t.lower() == "off" for t in pos[6:]):
        notes.append(f"{name} OFF ignored (it only seeds ngspice's DC solve)")
    for key, power in (("l", 1), ("w", 1), ("ad", 2), ("as", 2), ("pd", 1), ("ps", 1)):
        if geo[key] is not None:
            geo[key] = geo[key] * scale**power
    card = {k: x for k, x in values.items() if k not in ("level", "version", "revision")}
    d, g, s, b = pos[1:5]
    vg = ic.get(g, 0.0)
    v0 = (vg - ic.get(s, 0.0), vg - ic.get(d, 0.0), vg - ic.get(b, 0.0))
    try:
        part = built(
            parts, cp.BSIM4, kind, w=geo["w"], l=geo["l"], name=name,
            version=values["version"], v0=v0, model=card, ad=geo["ad"], as_=geo["as"],
            pd=geo["pd"], ps=geo["ps"], nrd=geo["nrd"], nrs=geo["nrs"], m=geo["m"],
            delvto=geo["delvto"], mulu0=geo["mulu0"],
        )  # fmt: skip
    except ModelError as exc:
        raise fail(str(exc)) from None
    return part, {"d": d, "g": g, "s": s, "b": b}
