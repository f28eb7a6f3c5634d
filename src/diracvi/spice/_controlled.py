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

The SPICE2 polynomial forms (:func:`poly_line`) are behavioural sources whose law is a
polynomial in the controlling voltages (E, G) or currents (F, H):

    Ename n+ n- POLY(ND) nc1+ nc1- … ncND+ ncND- p0 p1 …   V(n+, n-) = P(x)
    Gname n+ n- POLY(ND) nc1+ nc1- … ncND+ ncND- p0 p1 …   i = P(x)
    Fname n+ n- POLY(ND) V1 … VND p0 p1 …                   i = P(x)
    Hname n+ n- POLY(ND) V1 … VND p0 p1 …                   V(n+, n-) = P(x)

with ``P(x) = Σ_k p_k x^{e_k}`` over the monomials in SPICE2's order
(:func:`spice2_exponents`).
"""

from __future__ import annotations

import dataclasses
import itertools
import re

from .. import components as cp
from ._behavioural import source_part, value_line
from ._lines import split


def _linear_form(name, pos, kw, line, form, count):
    """The fields of a linear controlled-source line; ``VALUE=``/``TABLE`` on F and H
    (which ngspice does not have) refused."""
    fields = [t.lower() for t in pos[1:]]
    if "value" in kw or "value" in fields or "table" in fields:
        letter = pos[0][0].upper()
        alt = (
            f"or the behavioural forms '{letter}name n+ n- VALUE={{expr}}' / 'TABLE {{expr}} = "
            "(x,y) …'"
            if letter in "EG"
            else "or a B source 'Bname n+ n- I=expr' / 'V=expr' with i(Vname) in expr"
        )
        raise line.fail(
            f"element {name!r}: the VALUE= and TABLE forms of {letter} sources are not "
            f"supported; write the linear form '{form}' {alt}"
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
    polynomial = poly_line(ctx, name, pos, kw, line)
    if polynomial is not None:
        return polynomial
    form = "Ename n+ n- nc+ nc- gain"
    _, a, b, c, d, k = _linear_form(name, pos, kw, line, form, 6)
    gain = ctx.value(k, line, f"{pos[0]} gain")
    return cp.VCVS(gain, name=name), {"p": a, "n": b, "cp": c, "cn": d}


def vccs(ctx, name, pos, kw, line):
    behavioural = value_line(ctx, name, pos, kw, line, "I")
    if behavioural is not None:
        return behavioural
    polynomial = poly_line(ctx, name, pos, kw, line)
    if polynomial is not None:
        return polynomial
    form = "Gname n+ n- nc+ nc- transconductance"
    _, a, b, c, d, k = _linear_form(name, pos, kw, line, form, 6)
    gm = ctx.value(k, line, f"{pos[0]} transconductance")
    return cp.VCCS(gm, name=name), {"p": a, "n": b, "cp": c, "cn": d}


def cccs(ctx, name, pos, kw, line):
    polynomial = poly_line(ctx, name, pos, kw, line)
    if polynomial is not None:
        return polynomial
    _, a, b, vctrl, k = _linear_form(name, pos, kw, line, "Fname n+ n- Vname gain", 5)
    gain = ctx.value(k, line, f"{pos[0]} gain")
    return cp.CCCS(gain, control=_ammeter(ctx, vctrl, line), name=name), {"p": a, "n": b}


def ccvs(ctx, name, pos, kw, line):
    polynomial = poly_line(ctx, name, pos, kw, line)
    if polynomial is not None:
        return polynomial
    form = "Hname n+ n- Vname transresistance"
    _, a, b, vctrl, k = _linear_form(name, pos, kw, line, form, 5)
    r = ctx.value(k, line, f"{pos[0]} transresistance")
    return cp.CCVS(r, control=_ammeter(ctx, vctrl, line), name=name), {"p": a, "n": b}


# ---------------------------------------------------------------- SPICE2 POLY
_IC = re.compile(r"\bic\s*=", re.IGNORECASE)
_FORMS = {
    "E": ("V", "Ename n+ n- POLY(ND) nc1+ nc1- … ncND+ ncND- p0 p1 …"),
    "G": ("I", "Gname n+ n- POLY(ND) nc1+ nc1- … ncND+ ncND- p0 p1 …"),
    "F": ("I", "Fname n+ n- POLY(ND) V1 … VND p0 p1 …"),
    "H": ("V", "Hname n+ n- POLY(ND) V1 … VND p0 p1 …"),
}


def spice2_exponents(nd: int, count: int) -> list[tuple[int, ...]]:
    r"""The exponents ``e_k`` of the first ``count`` monomials ``x^{e_k} = Π_j x_j^{e_kj}``
    of a SPICE2 polynomial in ``nd`` variables, ``P(x) = Σ_k p_k x^{e_k}``.

    The order is SPICE2's (its ``NXTPWR``; ngspice's ``spice2poly`` code model keeps
    it): by total degree ``0, 1, 2, …``, and within one degree the exponent tuples in
    decreasing lexicographic order — for ``nd = 2``: ``1, x1, x2, x1², x1x2, x2², x1³,
    x1²x2, …``; for ``nd = 3``: ``1, x1, x2, x3, x1², x1x2, x1x3, x2², x2x3, x3², x1³, …``.
    """

    def of_degree(d: int, n: int):
        if n == 1:
            yield (d,)
            return
        for first in range(d, -1, -1):
            for rest in of_degree(d - first, n - 1):
                yield (first, *rest)

    out: list[tuple[int, ...]] = []
    for d in itertools.count():
        if len(out) >= count:
            return out[:count]
        out.extend(of_degree(d, nd))
    raise AssertionError("unreachable")  # pragma: no cover


def polynomial(coefficients, nd: int):
    r"""``x ↦ Σ_k p_k x^{e_k}`` (:func:`spice2_exponents`) as a function of a length-``nd``
    array; the powers are products with integer exponents (no ``x**0`` whose derivative
    reads ``0·x⁻¹``), so the function and its derivatives in ``x`` and in the ``p_k``
    (which may be traced) are exact polynomials."""
    terms = list(zip(coefficients, spice2_exponents(nd, len(coefficients)), strict=True))
    top = max(max(e) for _, e in terms)

    def p(x):
        powers = [[1.0, x[j]] for j in range(nd)]
        for j in range(nd):
            for _ in range(2, top + 1):
                powers[j].append(powers[j][-1] * x[j])
        total = 0.0 * x[0]
        for c, e in terms:
            monomial = 1.0
            for j, k in enumerate(e):
                if k:
                    monomial = monomial * powers[j][k]
            total = total + c * monomial
        return total

    return p


def poly_line(ctx, name, pos, kw, line):
    """An E/F/G/H line in SPICE2's polynomial form, or ``None`` when it is not one.

    The forms are the module docstring's; as in ngspice-39 the line is polynomial when
    its fourth field is ``POLY`` — the ``(ND)`` one positive integer — or, without
    ``POLY``, when it has more than one coefficient (ngspice reads that as ``POLY(1)``).
    The coefficients are ``p0, p1, …`` in :func:`spice2_exponents`' order, any number of
    them; a single coefficient is ``p0`` (ngspice-39; SPICE2 read it as ``p1``, so the
    reader notes it). ``IC=x1,…`` (SPICE2's first Newton guess of the controls, which
    does not change the solution) is read and left; ``M=`` multiplies a G or F output
    and is ignored on E and H, as ngspice does.
    """
    letter = pos[0][0].upper()
    kind, form = _FORMS[letter]
    per = 2 if letter in "EG" else 1  # fields per control
    written = pos[0]
    ic = _IC.search(line.text)
    guesses = []
    if ic is not None:  # IC=a,b,… : its values (comma-separated) leave the positions
        pos, kw = split(dataclasses.replace(line, text=line.text[: ic.start()]))
        guesses, _ = split(dataclasses.replace(line, text=line.text[ic.end() :]))
    has_poly = len(pos) > 3 and pos[3].lower() == "poly"
    linear = 6 if per == 2 else 5  # the linear form's field count
    if not has_poly and (len(pos) <= linear or pos[3].lower() in ("value", "table")):
        return None
    for g in guesses:
        ctx.value(g, line, f"{written} IC")
    if guesses:
        ctx.note(line, f"{written}: IC= (the first guess of the controls) is not needed")
    if has_poly:
        dim = pos[4] if len(pos) > 4 else ""
        if not re.fullmatch(r"\d+", dim) or int(dim) < 1:
            raise line.fail(
                f"element {written!r}: POLY({dim}) must have one positive integer, the number "
                f"of controls ND; write '{form}'"
            )
        nd, rest = int(dim), pos[5:]
    else:
        nd, rest = 1, pos[3:]
    controls, coefficients = rest[: per * nd], rest[per * nd :]
    if not coefficients:
        what = "node pairs" if per == 2 else "controlling voltage sources"
        raise line.fail(
            f"element {written!r}: POLY({nd}) needs {nd} {what} ({per * nd} fields) and then "
            f"at least one coefficient; got {len(rest)} fields after POLY({nd}); write '{form}'"
        )
    unknown = sorted(set(kw) - {"m"})
    if unknown:
        raise line.fail(f"element {written!r}: unsupported parameters {unknown} (form: '{form}')")
    if per == 1:
        bad = [c for c in controls if c[0].upper() != "V"]
        if bad:
            raise line.fail(
                f"element {written!r}: the controlling elements {bad} must be voltage sources "
                "(SPICE's rule); put a 0 V source in series with each branch to measure its "
                "current"
            )
    p = [ctx.value(c, line, f"{written} POLY coefficient p{k}") for k, c in enumerate(coefficients)]
    if len(p) == 1:
        ctx.note(
            line,
            f"{written}: a single POLY coefficient is p0, a constant (ngspice-39; SPICE2 read "
            "it as the linear p1)",
        )
    scale = 1.0
    if "m" in kw:
        if letter in "GF":
            scale = ctx.value(kw["m"], line, f"{written} M")
        else:
            ctx.note(line, f"{written}: M= is ignored on {letter} POLY sources (as in ngspice)")
    poly = polynomial(p, nd)
    if per == 2:
        pairs = [(controls[2 * k], controls[2 * k + 1]) for k in range(nd)]
        law = lambda v, i, t, d: scale * poly(v)  # noqa: E731
        return source_part(ctx, name, line, kind, law, pos[1], pos[2], written, pairs, [])
    law = lambda v, i, t, d: scale * poly(i)  # noqa: E731
    return source_part(ctx, name, line, kind, law, pos[1], pos[2], written, [], controls)
