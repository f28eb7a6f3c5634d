r"""Netlist lines of behavioural sources, and ``E``/``G`` with ``VALUE=`` or ``TABLE``.

    Bname n+ n- V=expr          V(n+, n-) = expr
    Bname n+ n- I=expr          i = expr, from n+ through the source to n-
    Ename n+ n- VALUE={expr}    as B with V=expr (ngspice turns it into a B source)
    Gname n+ n- VALUE={expr}    as B with I=expr
    Ename n+ n- TABLE {expr} = (x1,y1) (x2,y2) …   V = the table at expr, linear
                                                   between points, flat outside
    Gname n+ n- TABLE {expr} = (x1,y1) …           the same as a current

The expression language is :mod:`._expr`; the part is
:func:`~diracvi.components.BehaviouralSource`. The lines name other elements
(``i(Vname)``), so B is read late (:data:`~._elements.LATE`), and the nodes and sources
they name are checked once every line is read (:func:`check_names`), all at once.
"""

from __future__ import annotations

import itertools
import re

import jax.numpy as jnp
import numpy as np

from .. import components as cp
from ..components._part import fields
from ._expr import ExprError, compile_expression
from ._values import number

_SENSE_PIN = re.compile(r"^c\d+[pn]$")
_FORM = "Bname n+ n- V=expr (or I=expr)"
_OUTPUT = re.compile(r"^\s*(\S+)\s+(\S+)\s+(\S+)\s+([VvIi])\s*=\s*(.+?)\s*$", re.S)


def _strip(text: str) -> str:
    text = text.strip()
    while len(text) >= 2 and text[0] + text[-1] in ("{}", "''"):
        text = text[1:-1].strip()
    return text


def expression_text(text: str) -> str:
    """A B source's expression (or a behavioural resistor's value, which ngspice turns into
    a B source) as ngspice 39 reads it: written (:func:`_strip`) with every ``{`` and
    ``}`` in it a blank (``inpcom.c``'s ``inp_bsource_compat`` → ``inp_modify_exp``, so
    numparam only substitutes parameters and the B parser reads the rest). A brace is not
    a parenthesis there: ``V='2*{1+V(a)}'`` is 2*1 + V(a), 3 V at V(a) = 1 V, and
    ``R1 a 0 r={2*{1+V(b)}}`` is 3 Ω at V(b) = 1 V, in ngspice 39 (measured)."""
    return re.sub(r"[{}]", " ", _strip(text)).strip()


def b_line(ctx, name, pos, kw, line):
    m = _OUTPUT.match(line.text)
    if m is None:
        raise line.fail(f"expected '{_FORM}'")
    _, a, b, kind, text = m.groups()
    return _build(ctx, name, line, kind.upper(), expression_text(text), a, b, pos[0])


def value_line(ctx, name, pos, kw, line, kind):
    """``E``/``G`` with ``VALUE=`` or ``TABLE``: ``None`` when the line is neither."""
    letter = pos[0][0].upper()
    m = re.match(r"^\s*(\S+)\s+(\S+)\s+(\S+)\s+value\s*=?\s*(.+?)\s*$", line.text, re.I | re.S)
    if m is not None:
        return _build(ctx, name, line, kind, _strip(m.group(4)), m.group(2), m.group(3), pos[0])
    m = re.match(
        r"^\s*(\S+)\s+(\S+)\s+(\S+)\s+table\s*(\{[^}]*\}|'[^']*'|[^=]+?)\s*=?\s*(\(.*)$",
        line.text,
        re.I | re.S,
    )
    if m is None:
        return None
    points = re.findall(r"\(\s*([^,()\s]+)\s*[,\s]\s*([^,()\s]+)\s*\)", m.group(5))
    xs = [ctx.value(x, line, f"{letter} TABLE x") for x, _ in points]
    ys = [ctx.value(y, line, f"{letter} TABLE y") for _, y in points]
    if len(points) < 2 or any(x1 <= x0 for x0, x1 in itertools.pairwise(xs)):
        raise line.fail(
            f"{letter} TABLE needs two or more (x, y) pairs with increasing x (got "
            f"{len(points)}); write TABLE {{expr}} = (x1,y1) (x2,y2) …"
        )
    xs_, ys_ = np.asarray(xs), np.asarray(ys)
    return _build(
        ctx, name, line, kind, _strip(m.group(4)), m.group(2), m.group(3), pos[0],
        table=(xs_, ys_),
    )  # fmt: skip


def expression_part(ctx, name, line, kind, text, a, b, written):
    """The behavioural source ``kind`` (``"V"`` or ``"I"``) of the expression ``text``
    between ``a`` and ``b`` (a behavioural resistor's current, :mod:`._resistor`)."""
    return _build(ctx, name, line, kind, text, a, b, written)


def _build(ctx, name, line, kind, text, a, b, written, table=None):
    if not text:
        raise line.fail(f"element {written!r}: empty expression; write {kind}=expr")
    try:
        expr = compile_expression(text, ctx.params, getattr(ctx, "funcs", {}))
    except ExprError as exc:
        raise line.fail(f"element {written!r}: {exc} in {text!r}") from None
    law = expr.fn
    if table is not None:
        xs, ys = table
        inner = law
        law = lambda v, i, t, d: jnp.interp(inner(v, i, t, d), xs, ys)  # noqa: E731
    if expr.discontinuous:
        ops = ", ".join(dict.fromkeys(expr.discontinuous))
        ctx.note(
            line,
            f"{written}: the expression jumps ({ops}); Newton steps over the jump as "
            "written (no smoothing, no breakpoint)",
        )
    return source_part(
        ctx, name, line, kind, law, a, b, written, expr.pairs, expr.currents, expr.derivatives
    )


def source_part(ctx, name, line, kind, law, a, b, written, pairs, currents, derivatives=()):
    """The :func:`~diracvi.components.BehaviouralSource` of ``law`` with its control
    ``pairs`` (node pairs as written) and ``currents`` (element names as written), and
    its nodes; the names are checked once the netlist is read (:func:`check_names`)."""
    nodes = {"p": a, "n": b}
    for k, (n1, n2) in enumerate(pairs):
        nodes[f"c{k}p"], nodes[f"c{k}n"] = n1, n2
    ctx.reader.name_checks.append(
        (line, ctx, written, [n for pair in pairs for n in pair], list(currents))
    )
    part = cp.BehaviouralSource(
        kind,
        law,
        name=name,
        pairs=len(pairs),
        currents=[ctx.ref(c) for c in currents],
        derivatives=derivatives,
        tau=ctx.tran[1] if ctx.tran else cp.behavioural.TAU,  # TSTOP: see TAU
    )
    return part, nodes


def check_names(reader) -> None:
    """Every node and source named in a B expression must exist: all the unknown ones of
    a line in one message."""
    if not reader.name_checks:
        return
    nodes = set()
    table = [(fields(part), at) for part, at in reader.circuit._parts]  # (see fields)
    for f, at in table:
        for pin, _, _ in f["pins"]:
            if not _SENSE_PIN.match(pin):  # a B source's sensing pins join no node
                nodes.add(at[pin])
    labels = {(label or f["name"]).lower() for f, _ in table for label, _ in f["currents"]}
    for line, scope, written, names, sources in reader.name_checks:
        bad_nodes = sorted({n for n in names if scope.node(n) not in nodes and not _ground(n)})
        bad_sources = sorted({s for s in sources if scope.ref(s).lower() not in labels})
        why = []
        if bad_nodes:
            why.append(f"nodes {bad_nodes} are not in the circuit (no element joins them)")
        if bad_sources:
            why.append(
                f"sources {bad_sources} are not elements of the circuit (i() reads a "
                "voltage source's or an inductor's current)"
            )
        if why:
            reader.problems.add(
                line.fail(f"element {written!r}: " + "; ".join(why)), ".".join(scope.path)
            )


def _ground(node: str) -> bool:
    return node.lower() in ("0", "gnd") or number(node) == 0.0
