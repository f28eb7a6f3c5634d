"""The ``M`` line with a ``VDMOS`` card: ``Mname d g s model`` (ngspice's vertical power
MOSFET, :mod:`diracvi.components.vdmos`).

The element becomes four parts joined at internal nodes, as ngspice's ``vdmosset`` makes
them: the gate resistance ``RG`` from ``g`` to an internal gate ``g′`` (none when 0); the
channel (with ``CGS`` from ``g′`` to the source and ``RD``/``RS``) from ``d`` to ``s``; the
gate–drain capacitance from ``g′`` to the channel's drain; the body diode (``IS``, ``N``,
``CJO``, ``VJ``, ``M``, ``FC``, ``TT``, series resistance ``RB``) from ``s`` to ``d``
(``NCHAN``; reversed for ``PCHAN``). Card parameters diracvi does not implement
(quasi-saturation ``RQ``/``VQ``, self-heating, temperature coefficients, ``LAMBDA``,
``THETA``, breakdown ``BV``, ``RDS`` …) are refused by name at the element line.
"""

from __future__ import annotations

from .. import components as cp
from ..components.vdmos import VDMOS, GateDrainCapacitance
from ..errors import ModelError
from ._cards import Card, element_card, nominal_only

#: the card's parameters diracvi reads, with ngspice's defaults
DEFAULTS = {
    "vto": 0.0, "kp": 1.0, "ksubthres": 0.1, "subshift": 0.0,
    "rd": 0.0, "rs": 0.0, "rg": 0.0, "cgdmin": 0.0, "cgdmax": 0.0, "a": 1.0, "cgs": 0.0,
    "is": 1e-14, "n": 1.0, "rb": 0.0, "cjo": 0.0, "vj": 0.8, "m": 0.5, "fc": 0.5, "tt": 0.0,
}  # fmt: skip
#: parameters that only inform (ngspice ignores them too) or only act in noise
_IGNORED = ("kf", "af", "vds", "ron", "qg")
CARD = Card(
    defaults=DEFAULTS,
    alias={"vth0": "vto", "vt0": "vto"},
    skip=("pchan", "nchan"),
    ignored={k: "ignored (informational or noise only)" for k in _IGNORED},
    # parameters whose default is "off": given at their default they change nothing
    fixed={"lambda": (0.0, None), "theta": (0.0, None), "tnom": (27.0, None)},
    unknown="parameter {key}={x:g} is not supported; diracvi's VDMOS reads "
    + ", ".join(k.upper() for k in DEFAULTS)
    + " and PCHAN (remove it to run without)",
)


def vdmos_line(ctx, name, pos, kw, line):
    """``Mname d g s model`` with a VDMOS card: the channel part and its pins; the gate
    resistance, gate–drain capacitance and body diode are added to ``ctx.circuit``."""
    if len(pos) != 5 or kw:
        raise line.fail(
            "expected 'Mname d g s model' for a VDMOS (thermal nodes and instance "
            f"parameters are not supported; got {' '.join(pos[1:])} {kw or ''})"
        )
    _, params, _, fail = element_card(ctx, pos[4], line, ("VDMOS",))
    nominal_only(ctx, pos[0], kw, line, "the VDMOS")
    notes: list[str] = []
    kind = "pmos" if "pchan" in params else "nmos"
    v = CARD.read("VDMOS", params, fail, notes)
    d, g, s = pos[1:4]
    # ngspice's internal nodes (vdmosset): g′ behind RG, d′ behind RD, s′ behind RS
    inner = {k: (f"{pos[0]}#{word}" if v[r] != 0.0 else node)
             for k, r, word, node in (("g", "rg", "gate", g), ("d", "rd", "drain", d),
                                      ("s", "rs", "source", s))}  # fmt: skip
    vg, vd, vs = ctx.ic(g), ctx.ic(d), ctx.ic(s)
    circuit = ctx.reader.circuit
    try:
        channel = VDMOS(
            kind, v["vto"], v["kp"], ksubthres=v["ksubthres"], subshift=v["subshift"],
            cgs=v["cgs"], v0=(vg - vs, vg - vd), name=name,
        )  # fmt: skip
        extra = [
            (cp.Resistor(v[r], name=f"{name}:{r}"), {"p": node, "n": inner[k]})
            for k, r, node in (("g", "rg", g), ("d", "rd", d), ("s", "rs", s))
            if v[r] != 0.0
        ]
        if v["cgdmax"] > 0.0:
            cgd = GateDrainCapacitance(
                kind, v["cgdmin"], v["cgdmax"], v["a"], name=f"{name}:cgd", v0=vg - vd
            )
            extra.append((cgd, {"p": inner["g"], "n": inner["d"]}))
        # the body diode spans the outer terminals, its RB on the source side
        body = cp.Diode(
            v["is"], v["n"], name=f"{name}:body", series_resistance=v["rb"],
            junction_capacitance=v["cjo"], junction_potential=v["vj"], grading=v["m"],
            depletion_coefficient=v["fc"], transit_time=v["tt"],
        )  # fmt: skip
        extra.append((body, {"p": s, "n": d} if kind == "nmos" else {"p": d, "n": s}))
    except ModelError as exc:
        raise fail(str(exc)) from None
    for part, nodes in extra:
        circuit.add(part, **{pin: ctx.node(n) for pin, n in nodes.items()})
        circuit.origin[part.name] = f"{line.where} ({ctx.display(pos[0])})"
    for note in notes:
        ctx.note(line, note)
    return channel, {"d": inner["d"], "g": inner["g"], "s": inner["s"], "b": inner["s"]}
