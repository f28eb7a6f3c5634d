"""The ``M`` line with a ``VDMOS`` card: ``Mname d g s model`` (ngspice's vertical power
MOSFET, :mod:`diracvi.components.vdmos`).

The element becomes four parts joined at internal nodes, as ngspice's ``vdmosset`` makes
them: the gate resistance ``RG`` from ``g`` to an internal gate ``g′`` (none when 0); the
channel (with ``CGS`` from ``g′`` to the source and ``RD``/``RS``) from ``d`` to ``s``; the
gate–drain capacitance from ``g′`` to the channel's drain; the body diode (``IS``, ``N``,
``CJO``, ``VJ``, ``M``, ``FC``, ``TT``, series resistance ``RB``) from ``s`` to ``d``
(``NCHAN``; reversed for ``PCHAN``); ``RDS``, when given > 0, a shunt resistor from
``d`` to ``s`` (``vdmosset``'s ``dsConductance``). ``LAMBDA`` and ``THETA`` enter the
channel's ``β′``, ``MTRIODE`` its triode region (:mod:`diracvi.components.vdmos`). The
temperature coefficients act away from TNOM (:func:`~diracvi.components._temperature.vdmos`).
Card parameters diracvi does not implement (quasi-saturation ``RQ``/``VQ``, self-heating,
breakdown ``BV`` …) are refused by name at the element line.
"""

from __future__ import annotations

from .. import components as cp
from ..components._temperature import kelvin
from ..components._temperature import vdmos as vdmos_at
from ..components.vdmos import VDMOS, GateDrainCapacitance
from ..errors import ModelError
from ._cards import Card, device_temperature, element_card

#: the card's parameters diracvi reads, with ngspice's defaults
DEFAULTS = {
    "vto": 0.0, "kp": 1.0, "ksubthres": 0.1, "subshift": 0.0,
    "rd": 0.0, "rs": 0.0, "rg": 0.0, "cgdmin": 0.0, "cgdmax": 0.0, "a": 1.0, "cgs": 0.0,
    "is": 1e-14, "n": 1.0, "rb": 0.0, "cjo": 0.0, "vj": 0.8, "m": 0.5, "fc": 0.5, "tt": 0.0,
    "lambda": 0.0, "theta": 0.0, "mtriode": 1.0,
}  # fmt: skip
#: parameters that only inform (ngspice ignores them too) or only act in noise
_IGNORED = ("kf", "af", "vds", "ron", "qg")
#: ngspice's temperature coefficients with their defaults (vdmosset.c); TEXP0 acts only
#: where the card gives it (vdmostemp.c tests its "given" flag)
_TEMPERATURE = {
    "mu": -1.5, "tcvth": 0.0, "trd1": 0.0, "trd2": 0.0, "trg1": 0.0, "trg2": 0.0,
    "trs1": 0.0, "trs2": 0.0, "trb1": 0.0, "trb2": 0.0, "tksubthres1": 0.0,
    "tksubthres2": 0.0, "eg": 1.11, "xti": 3.0,
}  # fmt: skip
#: the safe-operating-area limits (ngspice's soa check: warnings, no effect on a run)
_SOA = ("vgs_max", "vgd_max", "vds_max", "vgsr_max", "vgdr_max", "pd_max", "id_max",
        "idr_max", "te_max", "derating")  # fmt: skip
#: the thermal network's parameters, read only by the five-terminal thermal instance
_THERMAL = ("rthjc", "rthca", "cthj", "rth_ext")
CARD = Card(
    defaults=DEFAULTS | _TEMPERATURE,
    # not VT0: ngspice 39's VDMOS ignores it (no such name); VTOTC and BEX are TCVTH's
    # and MU's other names (vdmos.c)
    alias={"vth0": "vto", "vtotc": "tcvth", "bex": "mu"},
    skip=("pchan", "nchan"),
    ignored={k: "ignored (informational or noise only)" for k in _IGNORED}
    | {"texp1": "ignored (the quasi-saturation resistance RQ's temperature exponent; RQ is "
       "refused)"}
    | {k: "ignored (a safe-operating-area limit: ngspice only warns past it)" for k in _SOA}
    | {k: "ignored (used only with the thermal nodes tj tc, which diracvi does not have)"
       for k in _THERMAL},
    fixed={},
    # read only where given: ngspice's shunt exists only then, TEXP0 and TNOM likewise
    optional=("rds", "texp0", "tnom"),
    unknown="parameter {key}={x:g} is not supported; diracvi's VDMOS reads "
    + ", ".join(k.upper() for k in DEFAULTS)
    + ", RDS and PCHAN (remove it to run without)",
    # ngspice 39's vdmos.c model table (aliases included); VDS, RON, QG (datasheet
    # words) are outside it and noted above
    ngspice=("VDMOS", frozenset(
        "vto vth0 kp phi lambda theta rd rs rg tnom kf af vdmosn vdmosp vdmos rq vq mtriode "
        "tcvth vtotc mu bex texp0 texp1 trd1 trd2 trg1 trg2 trs1 trs2 trb1 trb2 subshift "
        "ksubthres tksubthres1 tksubthres2 bv ibv nbv rds rb n tt eg xti is vj cjo m fc "
        "cgdmin cgdmax a cgs rthjc rthca cthj vgs_max vgd_max vds_max vgsr_max vgdr_max "
        "pd_max id_max idr_max te_max rth_ext derating".split())),
)  # fmt: skip


def vdmos_line(ctx, name, pos, kw, line):
    """``Mname d g s model [M=m]`` with a VDMOS card: the channel part and its pins; the
    gate resistance, gate–drain capacitance and body diode are added to ``ctx.circuit``.

    ``M`` puts ``m`` devices in parallel, as ngspice's ``vdmosset``/``vdmostemp`` scale
    one: KP and the body diode's IS and CJO times ``m``, RG, RD, RS, RDS and RB over
    ``m``, and — as ngspice since version 40 (``vdmosload``), not ngspice 39, which leaves
    them per device — the gate capacitances CGS, CGDMIN, CGDMAX times ``m``, so an
    instance with ``M=m`` is ``m`` instances side by side."""
    extra_kw = {k: t for k, t in kw.items() if k not in ("m", "temp", "dtemp")}
    if len(pos) != 5 or extra_kw:
        raise line.fail(
            "expected 'Mname d g s model [M=m] [TEMP=t] [DTEMP=d]' for a VDMOS (thermal "
            "nodes and other instance parameters are not supported; got "
            f"{' '.join(pos[1:])} {extra_kw or ''})"
        )
    _, params, _, fail = element_card(ctx, pos[4], line, ("VDMOS",))
    notes: list[str] = []
    kind = "pmos" if "pchan" in params else "nmos"
    v = CARD.read("VDMOS", params, fail, notes)
    temp = kelvin(device_temperature(ctx, pos[0], kw, line))
    v = vdmos_at(v, 1.0 if kind == "nmos" else -1.0, temp, kelvin(v.get("tnom", ctx.tnom)))
    m = ctx.value(kw["m"], line, f"{pos[0]} M") if "m" in kw else 1.0
    if not m > 0.0:
        raise line.fail(f"element {pos[0]!r}: M={m:g} must be > 0 (the parallel devices)")
    if m != 1.0:
        v = dict(v)
        for k in ("kp", "is", "cjo", "cgs", "cgdmin", "cgdmax"):
            v[k] = v[k] * m
        for k in ("rg", "rd", "rs", "rds", "rb"):
            if k in v:
                v[k] = v[k] / m
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
            lambda_=v["lambda"], theta=v["theta"], mtriode=v["mtriode"], cgs=v["cgs"],
            v0=(vg - vs, vg - vd), name=name,
        )  # fmt: skip
        extra = [
            (cp.Resistor(v[r], name=f"{name}:{r}"), {"p": node, "n": inner[k]})
            for k, r, node in (("g", "rg", g), ("d", "rd", d), ("s", "rs", s))
            if v[r] != 0.0
        ]
        if v.get("rds", 0.0) > 0.0:  # vdmosset: a conductance 1/RDS from d to s
            extra.append((cp.Resistor(v["rds"], name=f"{name}:rds"), {"p": d, "n": s}))
        if v["cgdmax"] > 0.0:
            cgd = GateDrainCapacitance(
                kind, v["cgdmin"], v["cgdmax"], v["a"], name=f"{name}:cgd", v0=vg - vd
            )
            extra.append((cgd, {"p": inner["g"], "n": inner["d"]}))
        # the body diode spans the outer terminals, its RB on the source side
        body = cp.Diode(
            v["is"], v["n"], name=f"{name}:body", series_resistance=v["rb"],
            junction_capacitance=v["cjo"], junction_potential=v["vj"], grading=v["m"],
            depletion_coefficient=v["fc"], transit_time=v["tt"], thermal_voltage=v["vt"],
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
