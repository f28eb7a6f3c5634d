r"""Read a SPICE netlist into a circuit of parts: :func:`read` and :class:`Netlist`.

The reader is split by concept: lines, comments, includes and ``.control`` blocks
(:mod:`._lines`); directives (:mod:`._directives`); element handlers, one per letter
(:mod:`._elements`); source specifications (:mod:`._sources`); subcircuits
(:mod:`._subckt`) read in scopes (:mod:`._scope`); the saved vectors (:mod:`._save`).
Every problem of a netlist is collected and reported at once in one
:class:`NetlistError`, each with its line, its text and the fix.
"""

from __future__ import annotations

import contextlib
import gc
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from .. import components as cp
from ..errors import ModelError
from ._behavioural import check_names
from ._control import first_tran
from ._directives import DIRECTIVES, circuit_temperatures
from ._gmin import GMIN, add_shunts
from ._lines import Line, NetlistError, Problems, card, load, split
from ._magnetic import assemble
from ._measure import check_measures
from ._save import probes, select
from ._scope import Scope, read_body
from ._values import NOMINAL_TEMPERATURE

__all__ = ["Netlist", "NetlistError", "read"]


#: whether a read builds each alike semiconductor line's part once (:func:`._cards.built`)
#: — off, every device is built by its constructor (the tests compare the two)
REMEMBER_PARTS = True


@dataclass
class Netlist:
    """A parsed netlist: the circuit, the analysis and where every element came from.

    Attributes:
        title: the first line (or ``.title``).
        circuit: the :class:`~diracvi.components.Circuit` of the elements.
        assembly: ``circuit.build()`` (the system, ``q0``, ``p0`` and name maps).
        dt, steps, stop: from ``.tran TSTEP TSTOP`` (``None`` without ``.tran``);
            ``steps`` covers ``[0, TSTOP]`` at ``dt``.
        uic: whether ``.tran … uic`` was given (without it a transient starts from the
            DC operating point, :func:`diracvi.spice.operating_point`).
        params: the evaluated top-level ``.param`` values (lower-case names).
        notes: what the reader accepted but does not act on (``.options``, ``.four``,
            AC specifications, unused models, …), each with its line.
        start: ``.tran``'s TSTART (0 if not given): SPICE outputs from there.
        tmax: ``.tran``'s TMAX (``None`` if not given).
        options: the ``.options`` values (lower-case names; numbers where they are).
        vectors: the saved vectors as ``(ngspice name, waveform key)``: the ``.save``
            lines, else node voltages and the currents of voltage sources and inductors
            (ngspice's default).
        display: part name -> the element's ngspice name (``v:xa:v1`` -> ``v.xa.v1``).
        ic: the ``.ic`` node voltages (with UIC they set capacitor voltages; without,
            they hold their nodes during the operating point, as SPICE does).
        op: whether the netlist asks for ``.op``.
        off: diodes marked ``OFF`` (their junctions start the operating point at 0 V).
        potentials: the MMF nodes of XSPICE's magnetic loops (no KCL row: their "voltage"
            is an MMF, a sum of the windings' ampere-turns), node ->
            ``((current label, turns), …)`` (:mod:`._magnetic`).
        differences: the ``.probe vd(…)`` vectors, ngspice name ``v(vd_…)`` ->
            ``(node₊, node₋)`` (``None``: ground), added as ``v(node₊) − v(node₋)``.
        measures: the ``.measure tran`` lines, read (:mod:`._measure`); a run's
            ``result.measurements`` are their values.
        funcs: the ``.func`` user functions, name -> ``(argument names, body text)``
            (a ``.measure … PARAM='…'`` may call them).
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
    start: float = 0.0
    tmax: float | None = None
    options: dict = field(default_factory=dict)
    vectors: tuple = ()
    display: dict = field(default_factory=dict)
    ic: dict = field(default_factory=dict)
    op: bool = False
    off: frozenset = frozenset()
    potentials: dict = field(default_factory=dict)
    differences: dict = field(default_factory=dict)
    measures: tuple = ()
    funcs: dict = field(default_factory=dict)
    _start: tuple | None = field(default=None, repr=False)
    _modes: object = field(default=None, repr=False)
    _op: object = field(default=None, repr=False)

    @property
    def system(self):
        """The interconnected system (``assembly.system``)."""
        return self.assembly.system

    @property
    def q0(self):
        """The transient's initial coordinates, as SPICE starts it: with ``UIC`` the
        netlist's state (``assembly.q0``), otherwise the DC operating point's."""
        return self.initial_state()[0]

    @property
    def p0(self):
        """The transient's initial momenta (see :attr:`q0`)."""
        return self.initial_state()[1]

    def initial_state(self):
        """``(q0, p0)``: the netlist's state with ``UIC``, the DC operating point without
        (computed once; ``.ic`` values hold their nodes while it is solved)."""
        if self.uic:
            return self.assembly.q0, self.assembly.p0
        if self._start is None:
            from ._operating_point import operating_point

            try:
                op = operating_point(self, hold=self.ic, off=self.off)
            except ModelError as exc:
                raise NetlistError(f"netlist {self.title!r}: {exc}") from None
            self._start = (op.q0, op.p0)
            self._modes = op.modes
            self._op = op
        return self._start

    def operating_point(self):
        """The DC operating point the transient starts from (``None`` with ``UIC``)."""
        if self.uic:
            return None
        self.initial_state()
        return self._op

    def initial_modes(self):
        """The switches' states the transient starts with: the operating point's without
        ``UIC``, else as given (``ON``/``OFF``), in the order of
        :func:`diracvi.driver.events.relays` (empty without switches)."""
        from ..driver.events import initial_modes

        if self.uic:
            return initial_modes(self.system)
        self.initial_state()
        return self._modes

    @property
    def discretizations(self) -> tuple[str, ...]:
        """The rules ``diracvi run`` offers, default first. The left-point rule cannot step
        a capacitor in a loop with voltage sources or capacitors, nor a current-output
        controlled source (F, G: its output flux never enters the left-point equations);
        both make its step singular; so do transistors (the BJT's transport flux, the
        MOSFET's sense fluxes appear in no left-point equation)."""
        if any(
            (p.role == "current" and hasattr(p, "senses")) or p.role == "transistor"
            for p in self.circuit.parts
        ):
            return ("midpoint",)
        return ("midpoint", "retraction")

    @property
    def name(self) -> str:
        """The circuit's name (for summaries and plots)."""
        return self.circuit.name


class _Reader:
    """The state of one read: what the directives set, and the problems met."""

    def __init__(self, name: str, overrides=None):
        self.problems = Problems()
        # read(..., params=): values that win over the netlist's top-level .param lines
        self.overrides = {str(k).lower(): v for k, v in (overrides or {}).items()}
        self.off: set[str] = set()  # diodes marked OFF
        self.op = False
        self.circuit = cp.Circuit(name)
        self.title = ""
        self.tran: tuple[float, float] | None = None
        self.tran_line: Line | None = None
        # the .control block's first tran (spice/_control.py), read as the .tran when the
        # netlist has none, and the .csparam vectors its $&name may read: name -> (line, token)
        self.control = None
        self.control_tran: Line | None = None
        self.csparams: dict[str, tuple[Line, str]] = {}
        self.start, self.tmax, self.uic = 0.0, None, False
        self.ic: dict[str, float] = {}
        self.notes: list[str] = []
        self._noted: set[str] = set()  # the notes, for note_once
        self._noted_upto = 0  # how many of them are in it
        self.options: dict = {}
        self.saves: list = []
        self.probes: list = []  # .probe parameters, (token, line)
        self.instances: dict[str, list] = {}  # top-level element -> its nodes (for .probe)
        self.measures: list = []  # .measure tran lines (spice/_measure.py)
        self.globals: set[str] = set()
        self.all_models: list = []
        self.display: dict[str, str] = {}
        self.funcs: dict[str, tuple] = {}  # .func name -> (argument names, body)
        self.name_checks: list = []  # B sources' nodes and sources, checked at the end
        self.magnetics: list = []  # XSPICE lcouple and core lines (spice/_magnetic.py)
        self.potentials: dict = {}  # MMF node -> its current coefficients
        # alike devices' parts by their arguments (_cards.built); None: each one built
        self.parts: dict | None = {} if REMEMBER_PARTS else None
        self.top = Scope(self, params=dict(self.overrides))
        # the circuit temperature and ngspice's TNOM option (°C), set before the body is
        # read (directives.circuit_temperatures); every device's TEMP defaults to the first
        self.temperature = NOMINAL_TEMPERATURE
        self.tnom = NOMINAL_TEMPERATURE

    def note(self, line: Line, text: str) -> None:
        self.notes.append(f"{line.where}: {text}")

    def note_once(self, note: str) -> None:
        """Append ``note`` unless :attr:`notes` holds it already. The notes seen are a set
        kept in step with the list (which is only ever appended to): a subcircuit
        instantiated 10⁴ times notes each of its lines per instance, and a search of
        the list each time was quadratic (0.3 s at 6666 notes)."""
        if self._noted_upto < len(self.notes):
            self._noted.update(self.notes[self._noted_upto :])
            self._noted_upto = len(self.notes)
        if note not in self._noted:
            self.notes.append(note)
            self._noted.add(note)
            self._noted_upto += 1

    def directive(self, line: Line) -> None:
        """A top-level directive other than .param/.model/.subckt."""
        word = card(line)
        word = ".temp" if word.startswith(".temp=") else word  # ngspice's '.temp=125'
        handler = DIRECTIVES.get(word)
        if handler is None:
            raise line.fail(
                f"directive {word!r} is not supported (diracvi reads .tran, .ic, .param, "
                ".model, .subckt, .include, .lib, .options, .save, .global, .temp and "
                "tolerates the output and analysis directives)"
            )
        pos, kw = split(line) if getattr(handler, "reads_words", True) else ([], {})
        handler(self, line, pos, kw)

    def read(self, text: str, base: Path | None) -> Netlist:
        source = load(text, base, self.problems)
        self.title = source.title
        self.notes += source.notes
        lines = source.lines
        if not any(card(line) == ".tran" for line in lines):
            control = first_tran(source.control)
            if control is not None:  # a `tran` command of a .control block stands for it
                self.control = control
                self.control_tran = control.line.with_text("." + control.line.text)
                lines = [*lines, self.control_tran]
                self.note(control.line, "the .control block's 'tran' is used as the .tran")
                self.notes += control.notes
        circuit_temperatures(self, lines)
        # TEMPER in every expression (.param, element values, B sources) is the circuit
        # temperature, as ngspice evaluates it
        self.top.params.setdefault("temper", self.temperature)
        read_body(self.top, lines)
        assemble(self)  # XSPICE's windings and cores: one part per magnetic loop
        check_names(self)
        for model in self.all_models:
            if not model.used:
                note = f"{model.where}: .model {model.name} {model.kind} is not used (accepted)"
                if note not in self.notes:
                    self.notes.append(note)
        if not self.circuit._parts and not self.problems.found:
            raise NetlistError("the netlist has no elements (only a title and directives).")
        self.problems.check()
        gmin = self.options.get("gmin", GMIN)
        add_shunts(self.circuit, gmin if isinstance(gmin, float) else GMIN, self.notes.append)
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
        netlist = Netlist(
            self.title,
            self.circuit,
            assembly,
            dt,
            steps,
            stop,
            self.uic,
            {k: v for k, v in self.top.params.items() if k != "temper"},
            self.notes,
            start=self.start,
            tmax=self.tmax,
            options=self.options,
            display=self.display,
            ic=dict(self.ic),
            op=self.op,
            off=frozenset(self.off),
            potentials=dict(self.potentials),
            funcs=dict(self.funcs),
        )
        saves = self.saves
        if self.probes:  # ngspice adds '.save all' to a deck with .probe and no .save
            extra, netlist.differences = probes(netlist, self.probes, self.instances, self.note)
            saves = [*(saves or [("all", self.probes[0][1])]), *extra]
        netlist.vectors = select(
            netlist, saves, self.problems, self.note, derived=netlist.differences
        )
        if self.measures:  # their names against every vector a run can give
            netlist.measures = check_measures(
                self.measures, netlist.params, self.funcs, select(netlist, [], self.problems),
                self.note,
            )  # fmt: skip
        self.problems.check()
        return netlist


def read(source, name: str | None = None, params=None) -> Netlist:
    """Read a SPICE netlist from a path or from its text.

    Args:
        source: a :class:`~pathlib.Path`, a path string, or the netlist text (a string
            with a newline). The first line is the title.
        name: the circuit's name (default: the file's stem, or ``"netlist"``).
        params: ``{name: value}`` overriding the netlist's top-level ``.param`` values
            (names case-insensitive). Values may be JAX tracers, so ``jax.grad`` flows
            from a run to any parameter: ``R1 a b {rval}`` with ``params={"rval": r}``.

    Returns:
        A :class:`Netlist`; ``netlist.system``, ``q0``, ``p0``, ``dt``, ``steps``.

    Raises:
        NetlistError: listing every line that cannot be read (its number, text and the
            fix; ``error.problems``), or the element/node of a topology error (floating
            node, loop of voltage sources, cut-set of current sources).
    """
    base = None
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
        base = path.parent
    elif isinstance(source, str):
        text = source
    else:
        raise NetlistError(f"read({source!r}): pass a path or the netlist text (str).")
    with _collector_paused():
        return _Reader(name or "netlist", params).read(text, base)


@contextlib.contextmanager
def _collector_paused():
    """Python's cyclic garbage collector paused while a netlist is read. A read makes a
    few objects per element that all live on (parts, names, node maps): each of the
    collector's passes over the older generations, triggered by that growth, walks
    every object of the process (JAX's included), so they added a third to the reading
    of 10⁴ elements. Reference counting still frees everything at once; the collector
    resumes (as it was) when the read ends, errors included."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()
