r"""The R line as ngspice reads it, with its semiconductor-resistor ``.model``.

``Rname n+ n- [value] [mname] [l=L] [w=W] [m=M] [scale=S] [temp=T] [dtemp=D] [tc1=…]
[tc2=…] [tce=…] [ac=…] [noisy=…]`` (``tc=a``: TC1, as ngspice 39 reads it) is a resistor
``v = R_eff · i`` with (ngspice's ``RESupdate_conduct``)

    R_eff = R · f · S / M,  f = 1 + tc1·Δ + tc2·Δ²  (or 1.01^(tce·Δ) when TCE is given),
    Δ = T − TNOM,  T = TEMP if given (DTEMP then ignored, as ngspice 39 does), else
    the circuit temperature + DTEMP;  TNOM the model's, else ``.options tnom`` (27 °C),

where ``R`` is ``value`` when given; else, when ``L·W·RSH > 0`` (``L`` defaults to the
model's ``L``, ``W`` to its ``DEFW``, both 10 µm),

    R = RSH · (L − 2·SHORT) / (W − 2·NARROW);

else the model's ``R``; else 1 mΩ (ngspice's fallback, with its warning as a note).
A width ``W = 2·NARROW`` makes ``R`` infinite: ngspice's conductance is then 0, an open
circuit, and the element is left out (with a note). Noise (KF, AF, LF, WF, EF, NOISY),
``BV_MAX`` (a warning level) and the AC resistance do not enter a transient.
"""

from __future__ import annotations

import math
import re

from .. import components as cp
from ..components._part import traced
from ._behavioural import expression_part, expression_text

FORM = "Rname n+ n- [value] [model] [l=…] [w=…] [m=…] [scale=…] [ac=…]"
#: instance keywords ngspice's resistor takes
INSTANCE = ("ac", "l", "w", "m", "scale", "temp", "dtemp", "tc1", "tc2", "tce", "noisy",
            "bv_max", "r", "resistance")  # fmt: skip
#: model parameters (ngspice's names and aliases) and their defaults
MODEL = {"rsh": 0.0, "narrow": 0.0, "dw": None, "short": 0.0, "dlr": None, "tc1": 0.0,
         "tc2": 0.0, "tce": None, "defw": 1e-5, "w": None, "l": 1e-5, "r": None, "res": None,
         "tnom": None, "kf": 0.0, "af": 0.0, "lf": 1.0, "wf": 1.0, "ef": 1.0,
         "bv_max": 1e99}  # fmt: skip
#: the model's aliases → the parameter they set
ALIASES = {"dw": "narrow", "dlr": "short", "w": "defw", "res": "r"}
#: ngspice's default circuit and nominal temperature (°C)
TEMP = 27.0


def effective(value, model: dict, kw: dict, temperature=TEMP, tnom=TEMP) -> float:
    """``R_eff`` of the module docstring (``math.inf`` for ngspice's zero conductance)
    from the instance's ``value`` (or ``None``), the model's parameters (aliases
    resolved) and the instance keywords, all numbers; ``temperature`` and ``tnom`` are
    the circuit's (°C)."""
    p = {k: v for k, v in MODEL.items() if k not in ALIASES}
    for key, v in model.items():
        p[ALIASES.get(key, key)] = v
    if value is None:
        length = kw.get("l", p["l"])
        width = kw.get("w", p["defw"])
        if length * width * p["rsh"] > 0.0:
            width_eff = width - 2.0 * p["narrow"]
            length_eff = length - 2.0 * p["short"]
            value = math.inf if width_eff == 0.0 else p["rsh"] * length_eff / width_eff
        elif p["r"] is not None:
            value = p["r"]
        else:
            value = 1e-3
    here = kw["temp"] if "temp" in kw else temperature + kw.get("dtemp", 0.0)
    delta = here - (tnom if p["tnom"] is None else p["tnom"])
    tc1, tc2 = kw.get("tc1", p["tc1"]), kw.get("tc2", p["tc2"])
    tce = kw.get("tce", p["tce"])
    factor = 1.01 ** (tce * delta) if tce is not None else 1.0 + (tc1 + tc2 * delta) * delta
    return value * factor * kw.get("scale", 1.0) / kw.get("m", 1.0)


def _given(ctx, pos, line, value):
    """A given resistance as ngspice 39 sets it (``RESparam``): 0 (to 3 ulps) is 1 mOhm,
    with a note; any other number, negative ones too, as it is."""
    if not traced(value) and abs(value) <= 3 * math.ulp(0.0):
        ctx.note(line, f"{pos[0]}: a resistance of 0 is 1 mOhm, as ngspice 39 sets it")
        return 1e-3
    return value


#: what each letter's line is called in messages: (its model's kind, its card)
_NOUNS = {"R": ("a resistor (R)", "a resistor .model")}


def read_line(ctx, pos, kw, line, letter, form, instance, keywords):
    """An R, C or L line's nodes, its value (or ``None``), its model's parameters
    (``{}``), its numeric instance keywords and its model as found (``(token, kind,
    where)`` or ``None``); ``keywords`` are ngspice's keyword forms of the value
    (``r=``, ``cap=``), ``instance`` the instance keywords the letter has."""
    kind_noun, card_noun = _NOUNS.get(letter, (f"a {letter} model", f"a {letter} .model"))
    kw = dict(kw)
    for key in keywords:  # ngspice's keyword form of the value
        if key in kw and len(pos) == 3:
            pos = [*pos, kw.pop(key)]
    if len(pos) < 3 or len(pos) > 5:
        raise line.fail(f"expected '{form}', got {len(pos)} fields")
    unknown = sorted(set(kw) - set(instance))
    if unknown:
        raise line.fail(f"unsupported parameters {unknown} (form: '{form}')")
    found = ctx.find_model(pos[3:])
    model = {}
    if found is not None:
        token, kind, where = found
        if kind != letter:
            raise line.fail(f"model {token!r} ({where}) is a {kind} model, not {kind_noun}")
        _, model, _ = ctx.model(token, line)
    values = [t for t in pos[3:] if found is None or t != found[0]]
    if len(values) > 1 or (not values and found is None):
        raise line.fail(f"expected '{form}' (a value, {card_noun}, or both)")
    value = ctx.value(values[0], line, f"{pos[0]} value") if values else None
    numbers = {
        k: ctx.value(v, line, f"{pos[0]} {k.upper()}")
        for k, v in kw.items()
        if k not in ("ac", "noisy", "bv_max")  # (ngspice's AC, noise and SOA keywords)
    }
    for key in ("m", "scale"):
        if key in numbers and numbers[key] <= 0.0:
            raise line.fail(f"{pos[0]} {key}={numbers[key]:g}: it must be positive")
    return pos, value, model, numbers, found


#: ``Rname n+ n- [R=]expr`` whose value reads the time, a node voltage or a current: a
#: behavioural resistor (ngspice's)
_BEHAVIOURAL = re.compile(
    r"^\s*\S+\s+(\S+)\s+(\S+)\s+(?:(?:r|resistance)\s*=\s*)?(.+?)\s*$", re.I | re.S
)
_READS = re.compile(r"\btime\b|\b[vi]\s*\(", re.I)


def behavioural(ctx, name, pos, line):
    """``Rname n+ n- R=expr`` with ``time``, ``v(…)`` or ``i(…)`` in ``expr``, as ngspice
    reads a behavioural resistor: the current ``i = V(n+, n−)/expr`` from ``n+`` to
    ``n−``, a :func:`~diracvi.components.BehaviouralSource` (a resistive port: with
    ``expr > 0`` it dissipates ``V²/expr``); ``None`` for any other R line."""
    m = _BEHAVIOURAL.match(line.text)
    if m is None or not _READS.search(m.group(3)):
        return None
    a, b, text = m.groups()
    law = f"v({a},{b})/({expression_text(text)})"
    return expression_part(ctx, name, line, "I", law, a, b, pos[0])


def r_line(ctx, name, pos, kw, line):
    """An R line (see the module docstring): ``(Resistor, pins)``, or ``(None, {})`` for
    an infinite resistance; a behavioural resistor's :func:`behavioural` part."""
    found = behavioural(ctx, name, pos, line)
    if found is not None:
        return found
    if len(pos) == 4 and not kw and pos[3].lower() not in ctx.models:
        # the plain line 'Rname n+ n- value' (most of a netlist), as the general reading
        # below takes it: no model named, no instance parameter
        value = _given(ctx, pos, line, ctx.value(pos[3], line, f"{pos[0]} value"))
        return cp.Resistor(value, name=name, negative=True), {"p": pos[1], "n": pos[2]}
    kw = dict(kw)
    if "tc" in kw and "tc1" not in kw:  # ngspice 39 reads 'tc=a' as TC1 (not 'tc=a,b')
        kw["tc1"] = kw.pop("tc")
    pos, value, model, numbers, found = read_line(
        ctx, pos, kw, line, "R", FORM, INSTANCE, ("r", "resistance")
    )
    bad = sorted(k for k in model if k not in MODEL)
    if bad:
        raise line.fail(
            f"resistor model {found[0]!r} ({found[2]}) sets {bad}; ngspice's resistor model "
            f"has {', '.join(k.upper() for k in MODEL)}"
        )
    value = None if value is None else _given(ctx, pos, line, value)
    if "ac" in kw:  # ngspice: a resistance for the AC analysis only
        ctx.note(line, f"{pos[0]} ac={kw['ac']} ignored (an AC-analysis resistance)")
    if found is None and not numbers:  # the plain R line: its value as given (maybe traced)
        return cp.Resistor(value, name=name, negative=True), {"p": pos[1], "n": pos[2]}
    if "temp" in numbers and "dtemp" in numbers:
        ctx.note(line, f"{pos[0]}: TEMP given, so DTEMP is ignored (as ngspice does)")
    r = effective(value, model, numbers, ctx.temperature, ctx.tnom)
    if math.isinf(r):
        ctx.note(
            line,
            f"{pos[0]}: W = 2·NARROW makes its resistance infinite (ngspice's conductance "
            "0): left out, an open circuit",
        )
        return None, {}
    if value is None and not model.get("rsh") and model.get("r", model.get("res")) is None:
        ctx.note(line, f"{pos[0]}: no value, RSH or R: 1 mOhm, as ngspice sets it")
    if r == 0.0:
        raise line.fail(
            f"{pos[0]}: its resistance works out to 0 Ohm (value, RSH·(L−2·SHORT)/"
            "(W−2·NARROW), temperature factor, SCALE/M); diracvi's resistor needs R ≠ 0 "
            "(a short: join the two nodes, or use a 0 V source)"
        )
    return cp.Resistor(r, name=name, negative=True), {"p": pos[1], "n": pos[2]}
