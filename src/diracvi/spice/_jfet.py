"""NJF/PJF ``.model`` cards and the ``J`` line (ngspice 39's JFET, level 1).

Parameter names, aliases and defaults are ngspice's (``jfet.c``, ``jfetset.c``): VTO
(VT0), BETA, LAMBDA, B, IS, RD, RS, CGS, CGD, PB, FC are used
(:func:`diracvi.components.JFET`); TNOM and the temperature coefficients EG (1.11), XTI,
TCV (0), VTOTC, BEX (0) and BETATCE act away from TNOM, with the instance's TEMP and DTEMP
(:func:`diracvi.components._temperature.jfet`). The noise parameters (KF, AF, NLEV,
GDSNOI) only act in noise analyses: they are accepted with a note, and so is a name
ngspice 39's JFET does not have (ngspice ignores it with a warning). Other levels
(ngspice's level 2, Parker–Skellern) are refused naming the model's line.
"""

from __future__ import annotations

from .. import components as cp
from ..components._temperature import jfet as jfet_at
from ..components._temperature import kelvin
from ..errors import ModelError
from ._cards import NOISE, Card, built, device_temperature, element_card

_DEFAULTS = {
    "vto": -2.0, "beta": 1e-4, "lambda": 0.0, "b": 1.0, "is": 1e-14, "rd": 0.0,
    "rs": 0.0, "cgs": 0.0, "cgd": 0.0, "pb": 1.0, "fc": 0.5,
}  # fmt: skip
#: the temperature coefficients with a default (jfetset.c); XTI, VTOTC and BETATCE act
#: only where the card gives them (jfettemp.c tests their "given" flags)
_TEMPERATURE = {"eg": 1.11, "tcv": 0.0, "bex": 0.0}
CARD = Card(
    defaults=_DEFAULTS | _TEMPERATURE,
    optional=("xti", "vtotc", "betatce", "tnom"),
    alias={"vt0": "vto"},
    ignored=NOISE,
    fixed={"level": (1.0, "LEVEL={x:g} (ngspice's Parker–Skellern JFET2) is not "
                                 "supported; diracvi has level 1 (Shichman–Hodges with B) only")},
    unknown="parameter {key!r} is not supported; diracvi's JFET reads "
    + ", ".join(k.upper() for k in _DEFAULTS),
    # ngspice 39's jfet.c model table (aliases included)
    ngspice=("JFET", frozenset(
        "njf pjf vt0 vto beta lambda rd rs cgs cgd pb is fc b tnom tcv vtotc bex betatce "
        "xti eg kf af nlev gdsnoi".split())),
)  # fmt: skip
FORM = "Jname d g s model [area] [AREA=a] [M=m] [OFF]"


def j_line(ctx, name, pos, kw, line):
    """``Jname d g s model [area] [AREA=a] [M=m] [OFF]`` (ngspice's level-1 JFET)."""
    flags = [t for t in pos[5:] if t.lower() == "off"]
    rest = [t for t in pos[5:] if t.lower() != "off"]
    if len(pos) < 5 or len(rest) > 1:
        raise line.fail(f"expected '{FORM}', got {len(pos)} fields")
    kind, params, _, fail = element_card(ctx, pos[4], line, ("NJF", "PJF"), "a J line")
    notes: list[str] = []
    v = CARD.read(kind, params, fail, notes)
    area = ctx.value(rest[0], line, f"{pos[0]} area") if rest else 1.0
    mult = 1.0
    for key, token in kw.items():
        if key == "area":
            area = ctx.value(token, line, f"{pos[0]} AREA")
        elif key == "m":
            mult = ctx.value(token, line, f"{pos[0]} M")
        elif key in ("temp", "dtemp"):
            pass  # device_temperature's
        else:
            raise line.fail(
                f"element {pos[0]!r}: parameter {key.upper()} is not supported on J lines "
                f"(form '{FORM}')"
            )
    temp = kelvin(device_temperature(ctx, pos[0], kw, line))
    try:
        v, bfac, emission = jfet_at(v, temp, kelvin(v.get("tnom", ctx.tnom)))
    except ModelError as exc:
        raise fail(str(exc)) from None
    if flags:
        notes.append(f"{pos[0]} OFF ignored (it only seeds ngspice's DC solve)")
    for note in notes:
        ctx.note(line, note)
    d, g, s = pos[1:4]
    vg = ctx.ic(g)
    part = built(
        ctx.reader.parts, cp.JFET, kind.lower(), v["vto"], v["beta"], v["lambda"], b=v["b"],
        is_=v["is"], rd=v["rd"], rs=v["rs"], cgs=v["cgs"], cgd=v["cgd"], pb=v["pb"],
        fc=v["fc"], area=area, m=mult,
        v0=(vg - ctx.ic(s), vg - ctx.ic(d)), name=name,
        bfac=bfac, emission=emission,
    )  # fmt: skip
    return part, {"d": d, "g": g, "s": s}
