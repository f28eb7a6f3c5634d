r"""Element lines, one handler per first letter (:data:`ELEMENTS`).

Adding a netlist element means adding one handler here and one entry in the table.
A handler has the shape

    handler(ctx, name, pos, kw, line) -> (part, nodes)

- ``ctx``: the :class:`~diracvi.spice._scope.Scope` the line is read in (the top level
  or one subcircuit instance). It gives ``ctx.value(token, line, what)`` (a number or
  ``{expression}`` over the visible ``.param``\ s), ``ctx.model(token, line)`` (a
  visible ``.model``: ``(kind, params, its line)``), ``ctx.ref(element)`` (the part name
  of another element of the same scope, for K, F, H), ``ctx.ic(node)`` (the ``.ic``
  voltage of a node of the line), ``ctx.tran`` (``(TSTEP, TSTOP)`` or ``None``),
  ``ctx.note(line, text)`` and ``ctx.circuit``.
- ``name``: the part's name: the element's name at the top level; inside subcircuit
  instances a dot-free unique name (``r:x1:x2:r1`` for ngspice's ``r.x1.x2.r1``).
- ``pos``, ``kw``: the line's positional tokens (``pos[0]`` is the element's name as
  written) and ``key=value`` pairs (keys lower-case), from :func:`~._lines.split`.
- ``line``: the :class:`~._lines.Line`; ``raise line.fail("what is wrong; the fix")``.
- returns the part and ``{pin: node}`` with the node names *as written on the line*
  (the reader maps them into the instance's scope), or ``(None, {})`` for a line that
  adds to ``ctx.circuit`` itself (K).
"""

from __future__ import annotations

from .. import components as cp
from ..components.diode import NGSPICE39_NAMES, SPICE_ALIASES, SPICE_INERT
from ._behavioural import b_line
from ._cards import built, device_temperature
from ._controlled import cccs, ccvs, vccs, vcvs
from ._devices import q_line
from ._jfet import j_line
from ._mos import m_line
from ._reactive import c_line, l_line
from ._resistor import r_line
from ._sources import source
from ._switches import s_line, w_line
from ._tline import t_line
from ._xspice import a_line


def _need(pos, count, line, form):
    if len(pos) != count:
        raise line.fail(f"expected '{form}', got {len(pos)} fields")


def _two(ctx, pos, kw, line, form, extra=()):
    """``Xname n+ n- value`` (or ``Xname n+ n- x=value``, ngspice's keyword form) with the
    keywords ``extra``: the nodes and the value."""
    letter = pos[0][0].lower()
    if len(pos) == 3 and letter in kw:
        kw = dict(kw)
        pos = [*pos, kw.pop(letter)]
    _need(pos, 4, line, form)
    unknown = sorted(set(kw) - set(extra))
    if unknown:
        raise line.fail(f"unsupported parameters {unknown} (form: '{form}')")
    return pos[1], pos[2], ctx.value(pos[3], line, f"{pos[0]} value")


def _k(ctx, name, pos, kw, line):
    _need(pos, 4, line, "Kname Lname1 Lname2 k")
    if kw:
        raise line.fail(f"unsupported parameters {sorted(kw)} (form: 'Kname Lname1 Lname2 k')")
    k = ctx.value(pos[3], line, "coupling")
    ctx.circuit.add(cp.MutualInductance(ctx.ref(pos[1]), ctx.ref(pos[2]), k, name=name))
    return None, {}


def _v(ctx, name, pos, kw, line):
    return cp.VoltageSource(source(ctx, pos, kw, line), name=name), {"p": pos[1], "n": pos[2]}


def _i(ctx, name, pos, kw, line):
    return cp.CurrentSource(source(ctx, pos, kw, line), name=name), {"p": pos[1], "n": pos[2]}


def _d(ctx, name, pos, kw, line):
    """``Dname anode cathode model [area] [AREA=a] [PJ=p] [M=m] [OFF] [IC=v] [TEMP=t]
    [DTEMP=d]`` with a ``.model NAME D(…)`` of :data:`~diracvi.components.SPICE_PARAMETERS`
    (ngspice's names, aliases and defaults), at :func:`device_temperature`. A model name
    ngspice 39's diode does not know (PSpice's ``IBVL``, ``NBVL``, ``TBV1``…) is ignored
    with a note, as ngspice 39 ignores it."""
    form = "Dname anode cathode model [area] [AREA=a] [PJ=p] [M=m] [OFF] [IC=v] [TEMP=t] [DTEMP=d]"
    flags = [t for t in pos[4:] if t.lower() == "off"]
    rest = [t for t in pos[4:] if t.lower() != "off"]
    if (
        len(pos) < 4 or len(rest) > 1 or len(flags) > 1
        or set(kw) - {"ic", "area", "pj", "m", *_TEMP}
    ):  # fmt: skip
        raise line.fail(f"expected '{form}'")
    kind, params, where = ctx.model(pos[3], line)
    if kind != "D":
        raise line.fail(f"model {pos[3]!r} ({where}) is a {kind} model, not a diode (D) model")
    foreign = sorted(k for k in params if k not in NGSPICE39_NAMES)
    if foreign:
        ctx.note(
            line,
            f"diode model {pos[3]!r} ({where}): {', '.join(k.upper() for k in foreign)} "
            "ignored (ngspice 39's diode does not have them and ignores them too"
            + ("; ngspice ≥ 40 reads TBV1 as TCV)" if "tbv1" in foreign else ")"),
        )
        params = {k: x for k, x in params.items() if k not in foreign}
    known = set(cp.SPICE_PARAMETERS) | set(SPICE_ALIASES) | set(SPICE_INERT)
    refused = sorted(k for k in params if k not in known)
    if refused:
        raise line.fail(
            f"diode model {pos[3]!r} ({where}) sets {refused}, which diracvi's diode does "
            f"not have (it reads {', '.join(k.upper() for k in cp.SPICE_PARAMETERS)}); "
            "remove them to run without"
        )
    area = rest[0] if rest else kw.get("area")
    area = None if area is None else ctx.value(area, line, "diode area")
    pj = ctx.value(kw["pj"], line, "diode PJ") if "pj" in kw else None
    mult = ctx.value(kw["m"], line, "diode M") if "m" in kw else 1.0
    ic = ctx.value(kw["ic"], line, "IC") if "ic" in kw else 0.0
    if flags:
        ctx.note(line, f"{pos[0]} OFF: its junction starts the operating point at 0 V")
        ctx.reader.off.add(name)
    temp = device_temperature(ctx, pos[0], kw, line)
    part = built(
        ctx.reader.parts, cp.spice_diode, params, name=name, area=area, ic=ic, pj=pj, m=mult,
        temperature=temp, tnom=ctx.tnom,
    )  # fmt: skip
    return part, {"p": pos[1], "n": pos[2]}


#: the instance temperature keywords of ngspice's semiconductor lines
_TEMP = ("temp", "dtemp")


def _x(ctx, name, pos, kw, line):
    """A subcircuit instance: expanded into ``ctx.circuit`` by the scope itself."""
    ctx.instance(pos, kw, line)
    return None, {}


#: first letter -> handler (see the module docstring for the handler's shape). A method
#: written in the old ``_Reader`` style, ``def _e(self, name, pos, kw, line)``, is such a
#: handler with ``self`` = ``ctx``: ``ctx`` has ``value``, ``_need``, ``_two``, ``tran``,
#: ``circuit``; read a model with ``ctx.model(token, line)`` and a node's ``.ic`` with
#: ``ctx.ic(node)`` (today's ``self.models[...]`` and ``self.ic[...]``).
ELEMENTS = {
    "R": r_line,
    "C": c_line,
    "L": l_line,
    "K": _k,
    "V": _v,
    "I": _i,
    "D": _d,
    "B": b_line,
    "E": vcvs,
    "F": cccs,
    "G": vccs,
    "H": ccvs,
    "J": j_line,
    "M": m_line,
    "Q": q_line,
    "S": s_line,
    "T": t_line,
    "W": w_line,
    "X": _x,
    "A": a_line,
}

#: letters read after the other elements of their scope, because their lines name other
#: elements (K its inductors; the controlled sources F and H and the switch W their
#: controlling V; B the sources of its i(…); A the sources of its %vnam inputs)
LATE = ("K", "F", "H", "W", "B", "A")

#: element letters ngspice knows and diracvi does not build yet: what each one is, and
#: whether it names a model (refused at the element line, which names the model's line)
UNSUPPORTED = {
    "Z": ("a MESFET", True),
    "O": ("a lossy transmission line", True),
    "U": ("a uniform distributed RC line", True),
    "Y": ("a single lossy transmission line (TXL)", True),
    "P": ("a coupled multiconductor line", True),
    "N": ("an OSDI (Verilog-A) device", True),
}

SUPPORTED = (
    "R, C, L, K, V, I, D, B, E, F, G, H, S, W, T, Q, J, M (levels 1, 2, 3 and 6), A (XSPICE's "
    "analog gain, summer, mult, divide, limit, climit, pwl, d_dt, int, aswitch, zener, "
    "memristor and magnetic lcouple, core) and X (subcircuits)"
)


def unsupported(ctx, pos, line):
    """The error for an element letter diracvi does not build, naming what is missing."""
    letter = pos[0][0].upper()
    what, has_model = UNSUPPORTED[letter]
    model = ""
    if has_model:
        found = ctx.find_model(pos[1:])
        if found is not None:
            token, kind, where = found
            model = f", model {token!r} ({kind}, {where})"
    return line.fail(
        f"element {pos[0]!r}: {what}{model} is not supported yet; diracvi reads {SUPPORTED}"
    )
