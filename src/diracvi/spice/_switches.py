r"""Netlist lines of the switches S and W (ngspice's ``sw`` and ``csw`` models).

    Sname n+ n- nc+ nc- model [ON|OFF]     .model model SW(VT= VH= RON= ROFF=)
    Wname n+ n- Vname model [ON|OFF]       .model model CSW(IT= IH= RON= ROFF=)

Closed (``RON``) when the control — ``V(nc+, nc-)`` or ``i(Vname)`` — is above
``VT + VH`` (``IT + IH``), open (``ROFF``) below ``VT − VH``, unchanged in between.
ngspice's defaults: ``RON = 1``, ``ROFF = 1e12`` (1/GMIN), ``VT = VH = IT = IH = 0``.
``ON`` starts the switch closed (it matters when the control starts inside the
hysteresis window), ``OFF`` (the default) open. The parts are
:mod:`diracvi.components.switch`; W names its controlling source, so it is read late.
"""

from __future__ import annotations

from .. import components as cp
from ._controlled import _ammeter

_MODELS = {
    "SW": ("vt", "vh", "a voltage-controlled switch (S)"),
    "CSW": ("it", "ih", "a current-controlled switch (W)"),
}


def _card(ctx, token, line, kind):
    found, params, where = ctx.model(token, line)
    threshold, hysteresis, what = _MODELS[kind]
    if found != kind:
        raise line.fail(
            f"model {token!r} ({where}) is a {found} model; {what} needs a {kind} model"
        )
    known = (threshold, hysteresis, "ron", "roff")
    unknown = sorted(k for k in params if k not in known)
    if unknown:
        raise line.fail(
            f"{kind} model {token!r} ({where}) sets {unknown}; diracvi's switch reads "
            f"{', '.join(k.upper() for k in known)} (remove the others)"
        )
    return {
        "r_on": params.get("ron", 1.0),
        "r_off": params.get("roff", 1e12),
        "threshold": params.get(threshold, 0.0),
        "hysteresis": params.get(hysteresis, 0.0),
    }


def _state(pos, count, line, form):
    flags = [t.lower() for t in pos[count:]]
    if len(pos) < count or len(flags) > 1 or any(f not in ("on", "off") for f in flags):
        raise line.fail(f"expected '{form}'")
    return flags == ["on"]


def s_line(ctx, name, pos, kw, line):
    form = "Sname n+ n- nc+ nc- model [ON|OFF]"
    if kw:
        raise line.fail(f"unsupported parameters {sorted(kw)} (form: '{form}')")
    closed = _state(pos, 6, line, form)
    params = _card(ctx, pos[5], line, "SW")
    part = cp.VoltageSwitch(**params, name=name, closed=closed)
    return part, {"p": pos[1], "n": pos[2], "cp": pos[3], "cn": pos[4]}


def w_line(ctx, name, pos, kw, line):
    form = "Wname n+ n- Vname model [ON|OFF]"
    if kw:
        raise line.fail(f"unsupported parameters {sorted(kw)} (form: '{form}')")
    closed = _state(pos, 5, line, form)
    params = _card(ctx, pos[4], line, "CSW")
    control = _ammeter(ctx, pos[3], line)
    part = cp.CurrentSwitch(**params, control=control, name=name, closed=closed)
    return part, {"p": pos[1], "n": pos[2]}
