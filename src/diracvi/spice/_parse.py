r"""A small, strict SPICE netlist reader: R, L, C, K, V, I, D, ``.tran``, ``.ic``,
``.param``, ``.model`` (diodes), ``.options`` (ignored), ``.end``.

The first line is the title (SPICE's rule). ``*`` starts a comment line, ``;`` and
`` $ `` an inline comment, ``+`` continues the previous line. Anything else is refused
with its line number and text (:class:`NetlistError`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from .. import components as cp
from ..errors import ModelError
from ._values import ExpressionError, evaluate, number


class NetlistError(ModelError):
    """A netlist line that cannot be read or a circuit that cannot be built."""


@dataclass
class Netlist:
    """A parsed netlist: the circuit, the analysis and where every element came from.

    Attributes:
        title: the first line.
        circuit: the :class:`~diracvi.components.Circuit` of the elements.
        assembly: ``circuit.build()`` (the system, ``q0``, ``p0`` and name maps).
        dt, steps, stop: from ``.tran TSTEP TSTOP`` (``None`` without ``.tran``).
        uic: whether ``.tran … uic`` was given.
        params: the evaluated ``.param`` values (lower-case names).
        notes: things the reader accepted but does not act on (``.options``, …).
    """

    title: str
    circuit: cp.Circuit
    assembly: cp.Assembly
    dt: float | None
    steps: int | None
    stop: float | None
    uic: bool
    params: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    @property
    def system(self):
        """The interconnected system (``assembly.system``)."""
        return self.assembly.system

    @property
    def q0(self):
        """Initial coordinates (``assembly.q0``)."""
        return self.assembly.q0

    @property
    def p0(self):
        """Initial momenta (``assembly.p0``)."""
        return self.assembly.p0

    #: the rules ``diracvi run`` offers, default first: the left-point rule cannot step a
    #: capacitor in a loop with voltage sources or capacitors (a singular step)
    discretizations = ("midpoint", "retraction")

    @property
    def name(self) -> str:
        """The circuit's name (for summaries and plots)."""
        return self.circuit.name


_TOKEN = re.compile(r"\{[^}]*\}|'[^']*'|=|[^\s,()={}']+")
_SUPPORTED = "R, C, L, K, V, I, D"


@dataclass
class _Line:
    number: int
    text: str

    def fail(self, why: str) -> NetlistError:
        return NetlistError(f"line {self.number}: {why}\n    {self.text}")


def _logical_lines(text: str) -> tuple[str, list[_Line]]:
    raw = text.splitlines()
    if not raw:
        raise NetlistError("the netlist is empty (SPICE expects a title line, then elements).")
    title = raw[0].strip()
    lines: list[_Line] = []
    for k, line in enumerate(raw[1:], start=2):
        body = re.split(r";| \$ |\t\$ ", line, maxsplit=1)[0].rstrip()
        stripped = body.strip()
        if not stripped or stripped.startswith("*"):
            continue
        if stripped.startswith("+"):
            if not lines:
                raise NetlistError(
                    f"line {k}: a '+' continuation with nothing to continue\n    {line}"
                )
            lines[-1].text += " " + stripped[1:].strip()
            continue
        lines.append(_Line(k, stripped))
    return title, lines


def _split(line: _Line) -> tuple[list[str], dict[str, str]]:
    """Positional tokens and ``key=value`` pairs."""
    tokens = _TOKEN.findall(line.text)
    if line.text.count("(") != line.text.count(")") or line.text.count("{") != line.text.count("}"):
        raise line.fail("unbalanced parentheses or braces")
    pos, kw = [], {}
    i = 0
    while i < len(tokens):
        if i + 2 < len(tokens) + 1 and i + 1 < len(tokens) and tokens[i + 1] == "=":
            if i + 2 >= len(tokens):
                raise line.fail(f"'{tokens[i]}=' has no value")
            kw[tokens[i].lower()] = tokens[i + 2]
            i += 3
            continue
        if tokens[i] == "=":
            raise line.fail("'=' without a name before it")
        pos.append(tokens[i])
        i += 1
    return pos, kw


class _Reader:
    def __init__(self, text: str, name: str):
        self.title, self.lines = _logical_lines(text)
        self.circuit = cp.Circuit(name)
        self.params: dict[str, float] = {}
        self.models: dict[str, dict[str, float]] = {}
        self.ic: dict[str, float] = {}
        self.tran: tuple[float, float] | None = None
        self.uic = False
        self.notes: list[str] = []
        self.elements: dict[str, _Line] = {}

    # --------------------------------------------------------------- values
    def value(self, token: str, line: _Line, what: str) -> float:
        x = number(token)
        if x is not None:
            return x
        text = token[1:-1] if token[:1] in "{'" else token
        try:
            return evaluate(text, self.params)
        except ExpressionError as exc:
            raise line.fail(f"{what}: {exc}") from None

    # ---------------------------------------------------------------- passes
    def read(self) -> Netlist:
        # directives first (.param, .model, .tran, .ic), in order, then the elements
        element_lines = []
        for line in self.lines:
            if line.text.startswith("."):
                if self.directive(line) == "end":
                    break
            else:
                element_lines.append(line)
        deferred = []
        for line in element_lines:
            kind = line.text[0].upper()
            if kind == "K":
                deferred.append(line)
            else:
                self.element(line)
        for line in deferred:
            self.element(line)
        if not self.elements:
            raise NetlistError("the netlist has no elements (only a title and directives).")
        try:
            assembly = self.circuit.build()
        except NetlistError:
            raise
        except ModelError as exc:
            raise NetlistError(str(exc)) from None
        dt = steps = stop = None
        if self.tran is not None:
            dt, stop = self.tran
            steps = max(1, math.ceil(stop / dt - 1e-9))
        return Netlist(
            self.title, self.circuit, assembly, dt, steps, stop, self.uic, self.params, self.notes
        )

    def directive(self, line: _Line) -> str | None:
        pos, kw = _split(line)
        card = pos[0].lower() if pos else line.text.split()[0].lower()
        if card == ".end":
            return "end"
        if card == ".param":
            if pos[1:]:
                raise line.fail(f"'.param' expects name=value pairs, got {pos[1:]}")
            for key, token in kw.items():
                self.params[key] = self.value(token, line, f".param {key}")
            return None
        if card == ".tran":
            args = [t for t in pos[1:] if t.lower() != "uic"]
            self.uic = len(args) != len(pos) - 1
            if len(args) < 2 or len(args) > 4 or kw:
                raise line.fail("'.tran' expects TSTEP TSTOP [TSTART [TMAX]] [UIC]")
            step, stop = (self.value(t, line, ".tran") for t in args[:2])
            if not (step > 0 and stop > 0):
                raise line.fail(f"'.tran' needs TSTEP > 0 and TSTOP > 0 (got {step}, {stop})")
            if len(args) > 2 and self.value(args[2], line, ".tran TSTART") != 0.0:
                raise line.fail("'.tran' with TSTART ≠ 0 is not supported")
            if self.tran is not None:
                raise line.fail("a second '.tran'")
            self.tran = (step, stop)
            return None
        if card == ".ic":
            pairs = re.findall(r"v\s*\(\s*([^)\s]+)\s*\)\s*=\s*(\S+)", line.text, re.IGNORECASE)
            rest = re.sub(r"v\s*\(\s*[^)\s]+\s*\)\s*=\s*\S+", "", line.text[3:], flags=re.I)
            if not pairs or rest.strip():
                raise line.fail("'.ic' expects V(node)=value pairs")
            for node, token in pairs:
                self.ic[node] = self.value(token, line, f".ic v({node})")
            return None
        if card == ".model":
            self.model(line)
            return None
        if card in (".options", ".option", ".opt", ".save", ".print", ".probe", ".plot"):
            self.notes.append(
                f"line {line.number}: {card} ignored (it tunes ngspice's output/solver)"
            )
            return None
        raise line.fail(
            f"directive {card!r} is not supported (supported: .tran, .ic, .param, .model for "
            "diodes, .options, .end)"
        )

    def model(self, line: _Line) -> None:
        m = re.match(r"\.model\s+(\S+)\s+(\w+)\s*\(?(.*?)\)?\s*$", line.text, re.IGNORECASE)
        if m is None:
            raise line.fail("'.model' expects NAME TYPE(param=value …)")
        name, kind, body = m.group(1).lower(), m.group(2).upper(), m.group(3)
        if kind != "D":
            raise line.fail(f"model type {kind!r} is not supported (only diodes, type D)")
        _, kw = _split(_Line(line.number, body))
        allowed = {"is": 1e-14, "n": 1.0}
        unknown = sorted(set(kw) - set(allowed))
        if unknown:
            raise line.fail(
                f"diode parameters {unknown} are not supported (only IS and N: a Shockley "
                "junction without series resistance or capacitance)"
            )
        self.models[name] = {k: self.value(kw.get(k, str(v)), line, k) for k, v in allowed.items()}

    # -------------------------------------------------------------- elements
    def element(self, line: _Line) -> None:
        pos, kw = _split(line)
        if not pos:
            raise line.fail("no element name (an element line starts with its name, e.g. R1)")
        name = pos[0]
        kind = name[0].upper()
        if kind not in "RCLKVID":
            raise line.fail(
                f"element {name!r}: type {kind!r} is not supported (supported: {_SUPPORTED}; "
                "no subcircuits, controlled sources or transistors)"
            )
        if name.upper() in self.elements:
            first = self.elements[name.upper()].number
            raise line.fail(f"element {name!r} is defined twice (first on line {first})")
        self.elements[name.upper()] = line
        try:
            part, nodes = getattr(self, f"_{kind.lower()}")(name, pos, kw, line)
        except NetlistError:
            raise
        except ModelError as exc:
            raise line.fail(str(exc)) from None
        self.circuit.origin[name] = f"line {line.number} ({name})"
        if not isinstance(part, _Skip):
            self.circuit.add(part, **nodes)

    def _need(self, pos, count, line, form):
        if len(pos) != count:
            raise line.fail(f"expected '{form}', got {len(pos)} fields")

    def _two(self, pos, kw, line, form, extra=()):
        self._need(pos, 4, line, form)
        unknown = sorted(set(kw) - set(extra))
        if unknown:
            raise line.fail(f"unsupported parameters {unknown} (form: '{form}')")
        return pos[1], pos[2], self.value(pos[3], line, f"{pos[0]} value")

    def _r(self, name, pos, kw, line):
        a, b, r = self._two(pos, kw, line, "Rname n+ n- value")
        return cp.Resistor(r, name=name), {"p": a, "n": b}

    def _c(self, name, pos, kw, line):
        a, b, c = self._two(pos, kw, line, "Cname n+ n- value [IC=v]", ("ic",))
        v0 = (
            self.value(kw["ic"], line, "IC")
            if "ic" in kw
            else self.ic.get(a, 0.0) - self.ic.get(b, 0.0)
        )
        return cp.Capacitor(c, name=name, v0=v0), {"p": a, "n": b}

    def _l(self, name, pos, kw, line):
        a, b, ell = self._two(pos, kw, line, "Lname n+ n- value [IC=i]", ("ic",))
        i0 = self.value(kw["ic"], line, "IC") if "ic" in kw else 0.0
        return cp.Inductor(ell, name=name, i0=i0), {"p": a, "n": b}

    def _k(self, name, pos, kw, line):
        self._need(pos, 4, line, "Kname Lname1 Lname2 k")
        if kw:
            raise line.fail(f"unsupported parameters {sorted(kw)}")
        k = self.value(pos[3], line, "coupling")
        self.circuit.add(cp.MutualInductance(pos[1], pos[2], k, name=name))
        return _Skip(), {}

    def _d(self, name, pos, kw, line):
        if len(pos) != 4 or kw:
            raise line.fail("expected 'Dname anode cathode model' (no area or options)")
        model = self.models.get(pos[3].lower())
        if model is None:
            raise line.fail(
                f"diode model {pos[3]!r} is not defined (add '.model {pos[3]} D(IS=… N=…)')"
            )
        return cp.Diode(model["is"], model["n"], name=name), {"p": pos[1], "n": pos[2]}

    def _v(self, name, pos, kw, line):
        return cp.VoltageSource(self.source(pos, kw, line), name=name), {"p": pos[1], "n": pos[2]}

    def _i(self, name, pos, kw, line):
        return cp.CurrentSource(self.source(pos, kw, line), name=name), {"p": pos[1], "n": pos[2]}

    def source(self, pos, kw, line):
        form = f"{pos[0][0]}name n+ n- [DC] value | SIN(…) | PULSE(…) | PWL(…)"
        if len(pos) < 4 or kw:
            raise line.fail(f"expected '{form}'")
        rest = pos[3:]
        dc = None
        if rest[0].lower() == "dc":
            if len(rest) < 2:
                raise line.fail("'DC' without a value")
            dc, rest = self.value(rest[1], line, "DC value"), rest[2:]
        elif rest[0].lower() not in ("sin", "pulse", "pwl"):
            dc, rest = self.value(rest[0], line, "value"), rest[1:]
        if not rest:
            return cp.DC(dc)
        fn, args = rest[0].lower(), [self.value(t, line, rest[0]) for t in rest[1:]]
        step, stop = self.tran or (None, None)
        try:
            if fn == "sin":
                if not 2 <= len(args) <= 6:
                    raise line.fail("SIN(VO VA [FREQ [TD [THETA [PHASE]]]]) takes 2 to 6 values")
                if len(args) < 3 or args[2] == 0.0:  # ngspice: FREQ 0 or absent → 1/TSTOP
                    args[2:3] = [self._default(stop, line, "SIN FREQ", 1)]
                return cp.Sine(*args)
            if fn == "pulse":
                if not 2 <= len(args) <= 8:
                    raise line.fail(
                        "PULSE(V1 V2 [TD [TR [TF [PW [PER [NP]]]]]]) takes 2 to 8 values"
                    )
                defaults = [0.0, step, step, stop, stop]
                full = (
                    args[:2]
                    + [
                        args[2 + j] if 2 + j < len(args) and (j == 0 or args[2 + j] > 0) else d
                        for j, d in enumerate(defaults)
                    ]
                    + args[7:]
                )
                if any(x is None for x in full):
                    raise line.fail("PULSE defaults TR, TF, PW, PER come from '.tran'; add one")
                return cp.Pulse(*full)
            if fn == "pwl":
                if len(args) < 2 or len(args) % 2:
                    raise line.fail("PWL(T1 V1 T2 V2 …) takes pairs of values")
                return cp.PWL(args[0::2], args[1::2])
        except ModelError as exc:
            if isinstance(exc, NetlistError):
                raise
            raise line.fail(str(exc)) from None
        raise line.fail(f"source function {rest[0]!r} is not supported (DC, SIN, PULSE, PWL)")

    def _default(self, stop, line, what, invert):
        if stop is None:
            raise line.fail(f"{what} defaults to 1/TSTOP, but there is no '.tran'; give it")
        return 1.0 / stop if invert else stop


class _Skip:
    """Placeholder returned for K lines (the coupling is registered directly)."""


def read(source, name: str | None = None) -> Netlist:
    """Read a SPICE netlist from a path or from its text.

    Args:
        source: a :class:`~pathlib.Path`, a path string, or the netlist text (a string
            with a newline). The first line is the title.
        name: the circuit's name (default: the file's stem, or ``"netlist"``).

    Returns:
        A :class:`Netlist`; ``netlist.system``, ``q0``, ``p0``, ``dt``, ``steps``.

    Raises:
        NetlistError: naming the line number and text of what cannot be read, or the
            element/node of a topology error (floating node, loop of voltage sources,
            cut-set of current sources).
    """
    if isinstance(source, Path) or (isinstance(source, str) and "\n" not in source):
        path = Path(source)
        try:
            exists = path.is_file()
        except (OSError, ValueError):  # an embedded NUL byte, a name too long
            exists = False
        if not exists:
            raise NetlistError(
                f"read({str(source)!r}): no such file (pass a path to a netlist, or the "
                "netlist text itself, which has several lines)"
            )
        text = path.read_text(encoding="utf-8", errors="replace")
        name = name or re.sub(r"[^A-Za-z0-9_]", "_", path.stem) or "netlist"
    elif isinstance(source, str):
        text = source
    else:
        raise NetlistError(f"read({source!r}): pass a path or the netlist text (str).")
    return _Reader(text, name or "netlist").read()
