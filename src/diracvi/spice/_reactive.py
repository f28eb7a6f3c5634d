r"""The C and L lines as ngspice 39 reads them, with their ``.model`` cards and their
temperature coefficients (``captemp.c``, ``capsetup.c``, ``indtemp.c``, ``indsetup.c``).

``Cname n+ n- [value] [mname] [m=M] [scale=S] [temp=T] [dtemp=D] [tc1=…] [tc2=…] [w=W]
[l=L] [ic=v]`` (the value also as ``c=``, ``cap=``, ``capacitance=``) is a capacitor

    C_eff = C · f · S · M,   f = 1 + tc1·Δ + tc2·Δ²,   Δ = T − TNOM

(ngspice multiplies the charge by ``M`` in its load), where ``C`` is ``value`` when
given; else the model's ``CAP``; else ``CJ·(W − NARROW)·(L − SHORT) + 2·CJSW·((L − SHORT) +
(W − NARROW))`` with ``W`` defaulting to the model's ``DEFW`` (10 µm) and ``L`` to 0
(ngspice reads no ``DEFL`` there), ``CJ`` from ``DI·ε₀/THICK`` (or ``ε_SiO₂/THICK``) when
not given, ``NARROW`` and ``SHORT`` defaulting to ``2·DEL``.

``Lname n+ n- [value] [mname] [m=M] [scale=S] [temp=T] [dtemp=D] [tc1=…] [tc2=…] [ic=i]``
(the value also as ``inductance=``) is an inductor ``L_eff = L · f · S / M``, ``L`` the
value, else the model's ``IND``. ngspice's geometric inductance (``NT``, ``CSECT``,
``DIA``, ``LENGTH``, ``MU``: a solenoid with Lundin's correction) is refused by name.

In both, ``T`` is ``TEMP`` if given (``DTEMP`` then ignored, as ngspice does), else the
circuit temperature plus ``DTEMP``; ``TNOM`` is the model's, else ``.options tnom``;
instance ``TC1``/``TC2`` override the model's. ``BV_MAX`` (a warning level) does not
enter a transient.
"""

from __future__ import annotations

from .. import components as cp
from ._resistor import read_line

#: ngspice's ε₀ and ε_SiO₂ (F/m, ``const.h``: CONSTepsZero, CONSTepsSiO2 = 3.9 ε₀)
EPS0 = 8.854214871e-12
EPS_SIO2 = 3.9 * EPS0

#: the capacitor's model names (ngspice 39's CAPmPTable, aliases → the name they set)
C_MODEL = {"cap": "cap", "cj": "cj", "cox": "cj", "cjsw": "cjsw", "capsw": "cjsw",
           "defw": "defw", "w": "defw", "defl": "defl", "l": "defl", "narrow": "narrow",
           "short": "short", "del": "del", "tc1": "tc1", "tc2": "tc2", "tnom": "tnom",
           "di": "di", "thick": "thick", "bv_max": "bv_max"}  # fmt: skip
C_INSTANCE = ("ic", "m", "scale", "temp", "dtemp", "tc1", "tc2", "w", "l", "bv_max")
#: the inductor's model names diracvi reads, and the geometric ones it refuses
L_MODEL = ("ind", "tc1", "tc2", "tnom")
L_GEOMETRY = ("csect", "dia", "length", "nt", "mu")
L_INSTANCE = ("ic", "m", "scale", "temp", "dtemp", "tc1", "tc2")


def factor(kw: dict, model: dict, here: float, tnom: float) -> float:
    """``1 + tc1·Δ + tc2·Δ²`` at ``here`` (°C), the instance's TC1/TC2 over the model's,
    ``Δ = here − (the model's TNOM, else tnom)``."""
    delta = here - model.get("tnom", tnom)
    tc1 = kw.get("tc1", model.get("tc1", 0.0))
    tc2 = kw.get("tc2", model.get("tc2", 0.0))
    return 1.0 + tc1 * delta + tc2 * delta * delta


def capacitance(value, model: dict, kw: dict) -> float:
    """``C`` of the module docstring before the temperature factor, SCALE and M."""
    if value is not None:
        return value
    if "cap" in model:
        return model["cap"]
    cj = model.get("cj")
    if cj is None:
        thick = model.get("thick", 0.0)
        di = model.get("di")
        cj = (di * EPS0 if di is not None else EPS_SIO2) / thick if thick > 0.0 else 0.0
    narrow = model.get("narrow", 2.0 * model.get("del", 0.0))
    short = model.get("short", 2.0 * model.get("del", 0.0))
    width = kw.get("w", model.get("defw", 10e-6)) - narrow
    length = kw.get("l", 0.0) - short
    return cj * width * length + model.get("cjsw", 0.0) * 2.0 * (length + width)


def _temperature(ctx, pos, numbers, line) -> float:
    """The element's temperature (°C), as :func:`~._cards.device_temperature` sets it."""
    if "temp" in numbers:
        if "dtemp" in numbers:
            ctx.note(line, f"{pos[0]}: TEMP given, so DTEMP is ignored (as ngspice does)")
        return numbers["temp"]
    return ctx.temperature + numbers.get("dtemp", 0.0)


def c_line(ctx, name, pos, kw, line):
    """A C line (module docstring): ``(Capacitor, pins)``."""
    form = "Cname n+ n- [value] [model] [m=…] [scale=…] [tc1=…] [tc2=…] [temp=…] [IC=v]"
    if len(pos) == 4 and not kw and pos[3].lower() not in ctx.models:
        c = ctx.value(pos[3], line, f"{pos[0]} value")  # the plain line (maybe traced)
        v0 = ctx.ic(pos[1]) - ctx.ic(pos[2])
        return cp.Capacitor(c, name=name, v0=v0, negative=True), {"p": pos[1], "n": pos[2]}
    pos, value, model, numbers, found = read_line(
        ctx, pos, kw, line, "C", form, C_INSTANCE, ("c", "cap", "capacitance")
    )
    model = {C_MODEL.get(k, k): x for k, x in model.items()}
    bad = sorted(k for k in model if k not in C_MODEL.values())
    if bad:
        raise line.fail(
            f"capacitor model {found[0]!r} ({found[2]}) sets {bad}; ngspice's capacitor "
            f"model has {', '.join(k.upper() for k in C_MODEL)}"
        )
    v0 = numbers.pop("ic") if "ic" in numbers else ctx.ic(pos[1]) - ctx.ic(pos[2])
    here = _temperature(ctx, pos, numbers, line)
    c = capacitance(value, model, numbers) * factor(numbers, model, here, ctx.tnom)
    c *= numbers.get("scale", 1.0) * numbers.get("m", 1.0)
    if c == 0.0:
        raise line.fail(
            f"{pos[0]}: its capacitance works out to 0 F (value, CAP or CJ/CJSW geometry, "
            "temperature factor, SCALE·M); a zero capacitor is an open circuit: remove it"
        )
    return cp.Capacitor(c, name=name, v0=v0, negative=True), {"p": pos[1], "n": pos[2]}


def l_line(ctx, name, pos, kw, line):
    """An L line (module docstring): ``(Inductor, pins)``."""
    form = "Lname n+ n- [value] [model] [m=…] [scale=…] [tc1=…] [tc2=…] [temp=…] [IC=i]"
    if len(pos) == 4 and not kw and pos[3].lower() not in ctx.models:
        ell = ctx.value(pos[3], line, f"{pos[0]} value")  # the plain line (maybe traced)
        return cp.Inductor(ell, name=name, negative=True), {"p": pos[1], "n": pos[2]}
    pos, value, model, numbers, found = read_line(
        ctx, pos, kw, line, "L", form, L_INSTANCE, ("inductance", "l")
    )
    geometric = sorted(k for k in model if k in L_GEOMETRY)
    bad = sorted(k for k in model if k not in L_MODEL and k not in L_GEOMETRY)
    if bad or geometric:
        raise line.fail(
            f"inductor model {found[0]!r} ({found[2]}) sets {bad or geometric}; diracvi "
            f"reads {', '.join(k.upper() for k in L_MODEL)} (ngspice's geometric inductance "
            f"from {', '.join(k.upper() for k in L_GEOMETRY)} is not supported: give IND)"
        )
    i0 = numbers.pop("ic", 0.0)
    if value is None:
        value = model.get("ind", 0.0)
    here = _temperature(ctx, pos, numbers, line)
    ell = value * factor(numbers, model, here, ctx.tnom)
    ell *= numbers.get("scale", 1.0) / numbers.get("m", 1.0)
    if ell == 0.0:
        raise line.fail(
            f"{pos[0]}: its inductance works out to 0 H (value or IND, temperature factor, "
            "SCALE/M); a zero inductor is a short: join its nodes"
        )
    return cp.Inductor(ell, name=name, i0=i0, negative=True), {"p": pos[1], "n": pos[2]}
