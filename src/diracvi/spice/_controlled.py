r"""Netlist lines of the linear controlled sources E, F, G, H (E and G with ``VALUE=`` or
``TABLE`` are behavioural sources, :mod:`._behavioural`).

    Ename n+ n- nc+ nc- gain             V(n+, n-) = gain · V(nc+, nc-)
    Gname n+ n- nc+ nc- transconductance  i = gm · V(nc+, nc-), from n+ through G to n-
    Fname n+ n- Vname gain               i = gain · i(Vname)
    Hname n+ n- Vname transresistance    V(n+, n-) = r · i(Vname)

The parts are :mod:`diracvi.components.controlled` (how they enter the Lagrange–Dirac
structure is in ``docs/circuits.md``). Handlers have the shape of
:mod:`~diracvi.spice._elements`; F and H name their controlling source, so they are read
late (:data:`~diracvi.spice._elements.LATE`).
"""

from __future__ import annotations

from .. import components as cp
from ._behavioural import value_line


def _linear_form(name, pos, kw, line, form, count):
    """The fields of a linear controlled-source line; ``POLY`` (and ``VALUE=``/``TABLE``
    on F and H, which ngspice does not have) refused."""
    fields = [t.lower() for t in pos[1:]]
    if "value" in kw or "poly" in fields or "value" in fields or "table" in fields:
        letter = pos[0][0].upper()
        alt = (
            f"or the behavioural forms '{letter}name n+ n- VALUE={{expr}}' / 'TABLE {{expr}} = "
            "(x,y) …'"
            if letter in "EG"
            else "or a B source 'Bname n+ n- I=expr' / 'V=expr' with i(Vname) in expr"
        )
        forms = "POLY(…) form" if letter in "EG" else "POLY(…), VALUE= and TABLE forms"
        verb = "is" if letter in "EG" else "are"
        raise line.fail(
            f"element {name!r}: the {forms} of {letter} sources {verb} not supported; write the "
            f"linear form '{form}' {alt}"
        )
    if kw or len(pos) != count:
        extra = f" and {sorted(kw)}" if kw else ""
        raise line.fail(f"expected '{form}', got {len(pos)} fields{extra}")
    return pos


def _ammeter(ctx, vctrl, line):
    # SPICE: the controlling current is the one through a voltage source, from its +
    # node through it to its − node (the circuit checks that the source exists)
    if vctrl[0].upper() != "V":
        raise line.fail(
            f"the controlling element {vctrl!r} must be a voltage source (SPICE's rule); "
            "put a 0 V source in series with the branch to measure its current"
        )
    return ctx.ref(vctrl)


def vcvs(ctx, name, pos, kw, line):
    behavioural = value_line(ctx, name, pos, kw, line, "V")
    if behavioural is not None:
        return behavioural
    form = "Ename n+ n- nc+ nc- gain"
    _, a, b, c, d, k = _linear_form(name, pos, kw, line, form, 6)
    gain = ctx.value(k, line, f"{pos[0]} gain")
    return cp.VCVS(gain, name=name), {"p": a, "n": b, "cp": c, "cn": d}


def vccs(ctx, name, pos, kw, line):
    behavioural = value_line(ctx, name, pos, kw, line, "I")
    if behavioural is not None:
        return behavioural
    form = "Gname n+ n- nc+ nc- transconductance"
    _, a, b, c, d, k = _linear_form(name, pos, kw, line, form, 6)
    gm = ctx.value(k, line, f"{pos[0]} transconductance")
    return cp.VCCS(gm, name=name), {"p": a, "n": b, "cp": c, "cn": d}


def cccs(ctx, name, pos, kw, line):
    _, a, b, vctrl, k = _linear_form(name, pos, kw, line, "Fname n+ n- Vname gain", 5)
    gain = ctx.value(k, line, f"{pos[0]} gain")
    return cp.CCCS(gain, control=_ammeter(ctx, vctrl, line), name=name), {"p": a, "n": b}


def ccvs(ctx, name, pos, kw, line):
    form = "Hname n+ n- Vname transresistance"
    _, a, b, vctrl, k = _linear_form(name, pos, kw, line, form, 5)
    r = ctx.value(k, line, f"{pos[0]} transresistance")
    return cp.CCVS(r, control=_ammeter(ctx, vctrl, line), name=name), {"p": a, "n": b}
