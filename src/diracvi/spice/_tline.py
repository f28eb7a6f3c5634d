r"""The netlist line of SPICE's lossless transmission line (ngspice's ``tra`` device).

    Tname n1+ n1- n2+ n2- Z0=value [TD=value | F=freq [NL=nrmlen]] [IC=v1,i1,v2,i2]

``Z0`` (or ``ZO``) is required; without ``TD`` the delay is ``NL/F`` with ngspice's
defaults ``NL = 0.25`` and ``F = 1 GHz`` (``trasetup.c``, ``tratemp.c``); ``TD`` given
wins over ``F``/``NL``. ``IC=`` (or ``V1= I1= V2= I2=``) sets the ports' values before
the run under ``UIC``. ``REL=``/``ABS=`` steer ngspice's breakpoints after a corner of
the line's waves (its slope test, ``traacct.c``): they are read and noted, not used — a
fixed-step run has no breakpoints, and the variable steps put one a delay after every
corner the circuit can have (:mod:`diracvi.driver.sparse_lines`), with no threshold. The
part is :func:`diracvi.components.TransmissionLine`.
"""

from __future__ import annotations

from .. import components as cp

FORM = "Tname n1+ n1- n2+ n2- Z0=value [TD=value | F=freq [NL=nrmlen]] [IC=v1,i1,v2,i2]"
_KNOWN = {"z0", "zo", "td", "f", "nl", "ic", "v1", "i1", "v2", "i2", "rel", "abs"}


def t_line(ctx, name, pos, kw, line):
    unknown = sorted(set(kw) - _KNOWN)
    if unknown:
        raise line.fail(f"unknown parameters {unknown} of a transmission line (form: '{FORM}')")
    extra = pos[5:]
    if len(pos) < 5 or (extra and "ic" not in kw):
        raise line.fail(
            f"a transmission line has four nodes and then keywords, got {pos[1:]} (form: '{FORM}')"
        )
    if "z0" not in kw and "zo" not in kw:
        raise line.fail(f"Z0= is required (ngspice: 'z0 must be given'); form: '{FORM}'")
    z0 = ctx.value(kw.get("z0", kw.get("zo")), line, "Z0")
    if "td" in kw:
        td = ctx.value(kw["td"], line, "TD")
    else:
        f = ctx.value(kw["f"], line, "F") if "f" in kw else 1e9
        nl = ctx.value(kw["nl"], line, "NL") if "nl" in kw else 0.25
        td = nl / f
    if z0 <= 0:
        raise line.fail(f"Z0={z0:g}: the characteristic impedance must be > 0 ohm")
    if not td > 0:
        raise line.fail(f"the delay TD={td:g} s must be > 0 (give TD=, or F= and NL= both > 0)")
    initial = [0.0, 0.0, 0.0, 0.0]
    if "ic" in kw:
        values = [kw["ic"], *extra]
        if len(values) > 4:
            raise line.fail(f"IC= takes at most four values v1, i1, v2, i2, got {values}")
        for j, token in enumerate(values):
            initial[j] = ctx.value(token, line, "IC")
    for j, key in enumerate(("v1", "i1", "v2", "i2")):
        if key in kw:
            initial[j] = ctx.value(kw[key], line, key.upper())
    for key in ("rel", "abs"):
        if key in kw:
            ctx.note(line, f"{key.upper()}= (ngspice's breakpoint control of a line) is not used")
    part = cp.TransmissionLine(z0, td, name=name, initial=tuple(initial))
    return part, {"p1": pos[1], "n1": pos[2], "p2": pos[3], "n2": pos[4]}
