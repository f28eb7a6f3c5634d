r"""Netlist lines of the switches S and W (ngspice's ``sw`` and ``csw`` models).

    Sname n+ n- nc+ nc- model [ON|OFF]     .model model SW(VT= VH= RON= ROFF=)
    Wname n+ n- Vname model [ON|OFF]       .model model CSW(IT= IH= RON= ROFF=)

Closed (``RON``) when the control — ``V(nc+, nc-)`` or ``i(Vname)`` — is above
``VT + VH`` (``IT + IH``), open (``ROFF``) below ``VT − VH``, unchanged in between.
ngspice's defaults: ``RON = 1``, ``ROFF = 1e12`` (1/GMIN), ``VT = VH = IT = IH = 0``.
``ON`` starts the switch closed (it matters when the control starts inside the
hysteresis window), ``OFF`` (the default) open. The parts are
:mod:`diracvi.components.switch`; W names its controlling source, so it is read late.

PSpice's smooth switch models (ngspice reads them in its PSpice mode, ``ngbehavior=ps…``,
turning them into XSPICE code models):

    .model model VSWITCH(VON= VOFF= RON= ROFF=)    on S lines: ngspice's ``pswitch``
    .model model ISWITCH(ION= IOFF= RON= ROFF=)    on W lines: ngspice's ``aswitch``

are a resistance ``r(x)`` set by the control ``x`` (``V(nc+, nc-)`` or ``i(Vname)``),
``i = V(n+, n-) / r(x)`` from n+ through the switch to n-. With ``L = ln(RON/ROFF)``:

    VSWITCH:  u = clip((x − VOFF)/(VON − VOFF) − ½, −½, ½)
              ln r = max(ln √(RON·ROFF) + L·(3u/2 − 2u³), ln RON)
    ISWITCH:  ln r = clip(ln RON − L·(ION − x)/(ION − IOFF), ln RON, ln ROFF)

— PSpice's VSWITCH a cubic in ``ln r`` whose slope vanishes at both ends (``r`` and its
derivative continuous), the ISWITCH log-linear and clipped (ngspice's ``log=TRUE
limit=TRUE``). ngspice's defaults ``RON = 1``, ``ROFF = 1e6``, ``VON = ION = 1``,
``VOFF = IOFF = 0``; ``RON`` below 1 mΩ is raised to 1 mΩ, a VSWITCH's ``ROFF`` above
1e12 lowered to 1e12, and a VSWITCH with ``VON = VOFF`` widened to ``VON ± 1 mV`` (as
the code models do). No state and no hysteresis: each is a behavioural I-source
(:func:`~diracvi.components.BehaviouralSource`) sensing the control and its own
terminals (an instance's ``ON``/``OFF`` means nothing). ``pswitch`` also loads its
control with 1e12 Ω, which diracvi leaves out. A ``VSWITCH``/``ISWITCH`` card with
``VT``/``VH`` (``IT``/``IH``) is ngspice's ``SW``/``CSW`` switch instead, as in ngspice.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from .. import components as cp
from ._behavioural import source_part
from ._controlled import _ammeter

_MODELS = {
    "SW": ("vt", "vh", "a voltage-controlled switch (S)"),
    "CSW": ("it", "ih", "a current-controlled switch (W)"),
}


#: PSpice's smooth switches: the model kind, its (on, off) control names, the classic kind
#: a card with a threshold and hysteresis is instead
_SMOOTH = {"SW": ("VSWITCH", "von", "voff"), "CSW": ("ISWITCH", "ion", "ioff")}


def _card(ctx, token, line, kind):
    found, params, where = ctx.model(token, line)
    threshold, hysteresis, what = _MODELS[kind]
    smooth, on, off = _SMOOTH[kind]
    if found == smooth:
        if threshold in params or hysteresis in params:
            found = kind  # ngspice: a VSWITCH with VT/VH is the classic switch
        else:
            return _smooth_card(token, params, where, line, smooth, on, off)
    if found != kind:
        raise line.fail(
            f"model {token!r} ({where}) is a {found} model; {what} needs a {kind} model"
        )
    _only(params, (threshold, hysteresis, "ron", "roff"), line, f"{kind} model {token!r} "
          f"({where})", "diracvi's switch")  # fmt: skip
    return {
        "r_on": params.get("ron", 1.0),
        "r_off": params.get("roff", 1e12),
        "threshold": params.get(threshold, 0.0),
        "hysteresis": params.get(hysteresis, 0.0),
    }


def _only(params, known, line, card, reader):
    """Refuse a card that sets a parameter outside ``known``, naming them and the fix."""
    unknown = sorted(k for k in params if k not in known)
    if unknown:
        raise line.fail(
            f"{card} sets {unknown}; {reader} reads "
            f"{', '.join(k.upper() for k in known)} (remove the others)"
        )


def _smooth_card(token, params, where, line, smooth, on, off):
    _only(params, (on, off, "ron", "roff"), line, f"{smooth} model {token!r} ({where})", "diracvi")
    r_on, r_off = max(params.get("ron", 1.0), 1e-3), params.get("roff", 1e6)
    x_on, x_off = params.get(on, 1.0), params.get(off, 0.0)
    if smooth == "VSWITCH":
        r_off = min(r_off, 1e12)
        if abs(x_on - x_off) < 1e-12:  # pswitch widens the window
            x_on, x_off = x_on + 1e-3, x_off - 1e-3
    if not r_off > 0 or abs(x_on - x_off) < 1e-12:
        raise line.fail(
            f"{smooth} model {token!r} ({where}): needs ROFF > 0 and {on.upper()} ≠ "
            f"{off.upper()} (got ROFF={r_off:g}, {on.upper()}={x_on:g}, "
            f"{off.upper()}={x_off:g})"
        )
    return {"kind": smooth, "r_on": r_on, "r_off": r_off, "x_on": x_on, "x_off": x_off}


def smooth_law(kind, r_on, r_off, x_on, x_off, *, control, port):
    r"""``i = V / r(x)`` of a VSWITCH or ISWITCH (the module docstring's ``r``);
    ``control(v, i)`` and ``port(v)`` pick ``x`` and ``V``."""
    lo, hi = math.log(r_on), math.log(r_off)
    big = lo - hi  # L = ln(RON/ROFF)

    def log_r(x):
        if kind == "VSWITCH":
            u = jnp.clip((x - x_off) / (x_on - x_off) - 0.5, -0.5, 0.5)
            return jnp.maximum(0.5 * (lo + hi) + big * (1.5 * u - 2.0 * u**3), lo)
        return jnp.minimum(jnp.maximum(lo - big * (x_on - x) / (x_on - x_off), lo), hi)

    def law(v, i, t, d):
        return port(v) * jnp.exp(-log_r(control(v, i)))

    return law


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
    if "x_on" in params:  # VSWITCH: its ON/OFF flag means nothing (no state)
        law = smooth_law(**params, control=lambda v, i: v[0], port=lambda v: v[1])
        pairs = [(pos[3], pos[4]), (pos[1], pos[2])]
        return source_part(ctx, name, line, "I", law, pos[1], pos[2], pos[0], pairs, [])
    part = cp.VoltageSwitch(**params, name=name, closed=closed)
    return part, {"p": pos[1], "n": pos[2], "cp": pos[3], "cn": pos[4]}


def w_line(ctx, name, pos, kw, line):
    form = "Wname n+ n- Vname model [ON|OFF]"
    if kw:
        raise line.fail(f"unsupported parameters {sorted(kw)} (form: '{form}')")
    closed = _state(pos, 5, line, form)
    params = _card(ctx, pos[4], line, "CSW")
    if "x_on" in params:  # ISWITCH
        _ammeter(ctx, pos[3], line)  # SPICE's rule: a voltage source
        law = smooth_law(**params, control=lambda v, i: i[0], port=lambda v: v[0])
        pairs = [(pos[1], pos[2])]
        return source_part(ctx, name, line, "I", law, pos[1], pos[2], pos[0], pairs, [pos[3]])
    control = _ammeter(ctx, pos[3], line)
    part = cp.CurrentSwitch(**params, control=control, name=name, closed=closed)
    return part, {"p": pos[1], "n": pos[2]}
