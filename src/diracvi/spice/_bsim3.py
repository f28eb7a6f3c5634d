"""NMOS/PMOS ``.model`` cards at ``LEVEL=8`` or ``49``: BSIM3v3 (ngspice's ``bsim3`` for
VERSION 3.3.0, its default, and ``bsim3v32`` for VERSION 3.2, 3.2.2, 3.2.3, 3.2.4).

Every parameter name of ngspice 39's BSIM3 is read (:data:`~diracvi.components._bsim3.NAMES`:
the model parameters and the L-, W-, P-prefixed binning terms); those absent take
ngspice's defaults or are derived as ``b3set.c``/``b3temp.c`` derive them
(:func:`~diracvi.components._bsim3.size_dependent`). The noise and safe-operating-area
parameters are noted and ignored. Refused by name, at the element line with the card's
line: a VERSION ngspice runs with another model (3.0, 3.1), CAPMOD 0 and 1, NQSMOD and
ACNQSMOD ≠ 0, ACM ≠ 0, and a device whose temperature differs from the card's TNOM (the
temperature update is not built).
"""

from __future__ import annotations

from .. import components as cp
from ..components import _bsim3 as b3
from ..errors import ModelError
from ._cards import built

LEVELS = (8.0, 49.0)
#: the M line's instance parameters of a BSIM3 device, with ngspice's defaults
INSTANCE = {"l": 5e-6, "w": 5e-6, "m": 1.0, "ad": 0.0, "as": 0.0, "pd": 0.0, "ps": 0.0,
            "nrd": 1.0, "nrs": 1.0, "delvto": 0.0, "mulu0": 1.0}  # fmt: skip


def read_bsim3_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The given values of a BSIM3 card (names lower-case), checked: ``{name: value}``
    with ``"level"`` and ``"version"``; an unknown name or an unsupported selector is
    ``fail(why)``."""
    out = {"level": kw.get("level"), "version": kw.get("version", "3.3.0")}
    try:
        out["revision"] = b3.version_code(out["version"])
    except ModelError as exc:
        raise fail(str(exc)) from None
    for key, x in kw.items():
        if key in ("level", "version"):
            continue
        if key == "+":  # a continuation mark inside a line (es_cmos_nand's PMOS card)
            notes.append(
                f"{kind} a '+' inside the card's line ignored, as ngspice does "
                "('unrecognized parameter (+) - ignored')"
            )
            continue
        if key in b3.NOISE_ONLY:
            notes.append(f"{kind} {key.upper()} ignored (noise and SOA checks only)")
            continue
        if key not in b3.NAMES:
            raise fail(
                f"parameter {key!r} is not a BSIM3 (level {kw['level']:g}) parameter of ngspice"
            )
        out[key] = x
    for key, allowed, what in (
        ("capmod", (2.0, 3.0), "capMod 2 and 3 (capMod 0 and 1 are not built)"),
        ("nqsmod", (0.0,), "the quasi-static charges (NQSMOD = 0)"),
        ("acnqsmod", (0.0,), "the quasi-static charges (ACNQSMOD = 0)"),
        ("acm", (0.0,), "ACM = 0 (the source/drain area model)"),
        ("mobmod", (1.0, 2.0, 3.0), "mobMod 1, 2 and 3"),
    ):
        x = float(out.get(key, b3.MODEL[key]))
        if x not in allowed:
            raise fail(f"{kind} BSIM3 {key.upper()}={x:g} is not supported; diracvi has {what}")
    return out


def instance_values(model, defaults, name, pos, kw, values, value, fail, temperature, tnom):
    """A BSIM M line's instance values (``defaults`` with its ``key=value`` tokens read),
    after the checks BSIM3 and BSIM4 lines share: the circuit at the card's TNOM (no
    temperature update is built), six positional tokens besides ``OFF``, and only the
    ``defaults``' keys — each refusal naming the element, the value and the fix."""
    card_tnom = values.get("tnom", tnom)
    if temperature != card_tnom:
        raise fail(
            f"element {name!r}: {model} has no temperature update in diracvi yet; the device "
            f"would run at {temperature:g} °C with the card's TNOM {card_tnom:g} °C (set the "
            "circuit temperature to TNOM, or drop TNOM/.temp)"
        )
    extra = [t for t in pos[6:] if t.lower() != "off"]
    if len(pos) < 6 or extra:
        raise fail("expected 'Mname d g s b model [L=… W=… M=… AD AS PD PS NRD NRS OFF]'")
    geo = dict(defaults)
    for key, token in kw.items():
        if key not in geo:
            raise fail(
                f"element {name!r}: parameter {key.upper()} is not supported on {model} M lines"
            )
        geo[key] = value(token, f"{name} {key.upper()}")
    return geo


def bsim3_line(name, pos, kw, kind, values, value, fail, ic, notes, temperature, tnom, parts=None):
    """``Mname d g s b model [L= W= M= AD= AS= PD= PS= NRD= NRS= DELVTO= MULU0= OFF]`` of a
    BSIM3 card → (part, nodes); ``parts``: the read's parts by their arguments
    (:func:`~._cards.built`), for alike lines built once."""
    geo = instance_values("BSIM3", INSTANCE, name, pos, kw, values, value, fail, temperature, tnom)
    if any(t.lower() == "off" for t in pos[6:]):
        notes.append(f"{name} OFF ignored (it only seeds ngspice's DC solve)")
    card = {k: x for k, x in values.items() if k not in ("level", "version", "revision")}
    d, g, s, b = pos[1:5]
    vg = ic.get(g, 0.0)
    v0 = (vg - ic.get(s, 0.0), vg - ic.get(d, 0.0), vg - ic.get(b, 0.0))
    try:
        part = built(
            parts, cp.BSIM3, kind, w=geo["w"], l=geo["l"], name=name,
            version=values["version"], v0=v0, model=card, ad=geo["ad"], as_=geo["as"],
            pd=geo["pd"], ps=geo["ps"], nrd=geo["nrd"], nrs=geo["nrs"], m=geo["m"],
            delvto=geo["delvto"], mulu0=geo["mulu0"],
        )  # fmt: skip
    except ModelError as exc:
        raise fail(str(exc)) from None
    return part, {"d": d, "g": g, "s": s, "b": b}
