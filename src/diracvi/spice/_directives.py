r"""Top-level directives (``.tran``, ``.ic``, ``.save``, …), one handler per card
(:data:`DIRECTIVES`); ``.param``, ``.model`` and ``.subckt`` are read in every scope
(:mod:`._scope`), ``.include``/``.lib``/``.control``/``.end`` with the lines
(:mod:`._lines`).

A handler is ``handler(reader, line, pos, kw)``; it sets the reader's fields or adds a
note, and raises ``line.fail(…)`` for a line it cannot accept. What a transient run
does not need is accepted with a note (``netlist.notes``).
"""

from __future__ import annotations

import contextlib
import re

from ._lines import LineError, card, split
from ._measure import read_measure
from ._save import probe_tokens
from ._scope import Scope, parse_func
from ._values import KELVIN, NOMINAL_TEMPERATURE, number


def _tran(reader, line, pos, kw):
    """``.tran TSTEP TSTOP [TSTART [TMAX]] [UIC]``; the ``.control`` block's ``tran``
    with its ``$&name``/``$name`` written as ngspice writes them (:mod:`._control`)."""
    if line is reader.control_tran and "$" in line.text:
        csparams = {
            key: (where, reader.top.value(token, where, f".csparam {key}"))
            for key, (where, token) in reader.csparams.items()
        }
        text, said = reader.control.resolve(csparams)
        reader.note(line, f"{line.text[1:]!r} read as {text!r}: " + ", ".join(said))
        line = line.with_text("." + text)
        pos, kw = split(line)
    args = [t for t in pos[1:] if t.lower() != "uic"]
    uic = len(args) != len(pos) - 1
    if len(args) < 2 or len(args) > 4 or kw:
        raise line.fail("'.tran' expects TSTEP TSTOP [TSTART [TMAX]] [UIC]")
    values = [reader.top.value(t, line, ".tran") for t in args]
    step, stop, start, tmax = values + [0.0, None][len(values) - 2 :]
    if not (step > 0 and stop > 0):
        raise line.fail(f"'.tran' needs TSTEP > 0 and TSTOP > 0 (got {step:g}, {stop:g})")
    if not 0.0 <= start < stop:
        raise line.fail(f"'.tran' needs 0 ≤ TSTART < TSTOP (got TSTART={start:g}, TSTOP={stop:g})")
    if tmax is not None and not tmax > 0:
        raise line.fail(f"'.tran' needs TMAX > 0 (got {tmax:g})")
    if reader.tran is not None:
        raise line.fail(f"a second '.tran' (the first is {reader.tran_line.where}); keep one")
    reader.tran, reader.tran_line, reader.uic = (step, stop), line, uic
    reader.start, reader.tmax = start, tmax


_IC_PAIR = re.compile(r"v\s*\(\s*([^)\s]+)\s*\)\s*=\s*(\{[^}]*\}|\S+)", re.IGNORECASE)


def _ic(reader, line, pos, kw):
    """``.ic V(node)=value …`` (node names as ngspice prints them: ``v(xa.n2)``)."""
    body = line.text.split(None, 1)[1] if len(line.text.split(None, 1)) > 1 else ""
    pairs = _IC_PAIR.findall(body)
    if not pairs or _IC_PAIR.sub("", body).strip():
        raise line.fail("'.ic' expects V(node)=value pairs")
    for node, token in pairs:
        reader.ic[node.lower()] = reader.top.value(token, line, f".ic v({node})")


def _nodeset(reader, line, pos, kw):
    reader.note(line, ".nodeset noted (an operating-point hint; the transient starts from .ic/IC=)")


#: the ``.options`` tolerances a variable-step run meets (checked here, used by _tran)
TOLERANCES = ("reltol", "abstol", "vntol", "chgtol", "trtol")


def _options(reader, line, pos, kw):
    for key, token in kw.items():
        value = number(token)
        if key in TOLERANCES:  # the variable-step control meets these (spice._tran)
            value = reader.top.value(token, line, f".options {key}")
            if not value > 0.0:
                raise line.fail(f".options {key}={token} must be a positive number")
        reader.options[key] = value if value is not None else token
    reader.options.update({p.lower(): True for p in pos[1:]})
    reader.note(
        line,
        f"{card(line)} read into netlist.options (reltol, abstol, vntol, chgtol, trtol are "
        "used by variable-step runs; the rest tunes ngspice's solver)",
    )


def _temp(reader, line, pos, kw):
    """``.temp T``: read with ``.options temp=``/``tnom=`` before the body
    (:func:`circuit_temperatures`); here a note of what it set."""
    reader.note(line, f"circuit temperature {reader.temperature:g} °C (ngspice's .temp)")


#: the ``.options`` spellings
_OPTIONS = (".options", ".option", ".opt")


def circuit_temperatures(reader, lines) -> None:
    """Set ``reader.temperature`` and ``reader.tnom`` (°C) from the top-level ``.temp`` and
    ``.options temp=… tnom=…`` lines, before any ``.param`` or element is read: ngspice
    evaluates ``TEMPER`` in ``.param`` expressions at the circuit temperature, and every
    device's temperature update needs both.

    ngspice 39's rules (``inp.c``, checked against ngspice): the default is 27 °C for
    both; ``.options temp=`` sets the circuit temperature, and a ``.temp`` line wins over
    it wherever it stands (the last ``.temp`` if there are several lines); ``.temp=T`` is
    the same card. A ``.temp`` with several values (a temperature sweep) is not run by
    ngspice either: it warns and runs at 27 °C; diracvi refuses it, naming the fix.
    """
    depth, temp, option = 0, None, None
    for line in lines:
        word = card(line)
        if word == ".subckt":
            depth += 1
        elif word == ".ends":
            depth -= 1
        if depth:
            continue
        try:
            if word == ".temp" or word.startswith(".temp="):
                values = re.sub(r"^\.temp\s*=?", "", line.text, flags=re.I).split()
                if len(values) != 1:
                    raise line.fail(
                        f"'.temp' with {len(values)} values: ngspice runs one temperature "
                        "(with several it warns and runs at 27 °C); give one, e.g. '.temp 85' "
                        "(run the others as separate decks or with `diracvi sweep`)"
                    )
                temp = _temperature(reader, line, values[0], ".temp", lines)
            elif word in _OPTIONS:
                _, kw = split(line)
                if "temp" in kw:
                    option = _temperature(reader, line, kw["temp"], ".options temp")
                if "tnom" in kw:
                    reader.tnom = _temperature(reader, line, kw["tnom"], ".options tnom")
        except LineError as exc:
            reader.problems.add(exc)
    reader.temperature = next(t for t in (temp, option, NOMINAL_TEMPERATURE) if t is not None)


def _temperature(reader, line, token, what, lines=()) -> float:
    """A temperature in °C, above absolute zero; an expression is evaluated over the
    top-level ``.param`` values (read here ahead of the body, ``TEMPER`` at 27 °C)."""
    scope = reader.top
    if number(token) is None:
        scope = Scope(reader, params=dict(reader.top.params))
        for other in lines:
            if card(other) == ".param":
                for key, text in split(other)[1].items():
                    if key not in reader.overrides:
                        with contextlib.suppress(LineError):
                            scope.params[key] = scope.value(text, other, key)
    value = scope.value(token, line, what)
    if not value > -KELVIN:
        raise line.fail(f"{what}={token}: a temperature must be above −273.15 °C")
    return value


def _save(reader, line, pos, kw):
    if kw:
        raise line.fail(f"'.save' takes vector names (v(node), i(Vname), @R1[i]), got {kw}")
    reader.saves += [(token, line) for token in _vectors(line.text)]


def _probe(reader, line, pos, kw):
    """``.probe`` parameters, resolved once the elements are read (:func:`._save.probes`)."""
    tokens = probe_tokens(line.text)
    if not tokens or re.search(r"(?<![\w(])alli(?![\w)])", line.text, re.I):
        # ngspice reads a bare '.probe' as '.probe alli'
        reader.note(
            line,
            ".probe alli (every device's pin currents, ngspice's 0 V sources at its pins) "
            "not reported: diracvi gives no pin currents; i(R1) gives an element's current",
        )
    reader.probes += [(token, line) for token in tokens]


# a .probe line is not read word by word: ngspice goes on past a malformed parameter
_probe.reads_words = False


def _vectors(text: str) -> list[str]:
    """The vector names of a ``.save`` line: ``v(a) i(v1) @r1[i] all a``."""
    body = text.split(None, 1)[1] if len(text.split(None, 1)) > 1 else ""
    return re.findall(r"[vi]\s*\([^)]*\)|@[^\s\[]+\[[^\]]*\]|[^\s,]+", body, re.IGNORECASE)


def _global(reader, line, pos, kw):
    reader.globals.update(p.lower() for p in pos[1:])


def _title(reader, line, pos, kw):
    reader.title = line.text.split(None, 1)[1] if len(line.text.split(None, 1)) > 1 else ""


def _op(reader, line, pos, kw):
    reader.op = True  # spice.operating_point() reports it; a transient starts from it
    reader.note(
        line,
        ".op noted: spice.operating_point() gives the DC operating point; without UIC "
        "the transient starts from it",
    )


def _func(reader, line, pos, kw):
    """``.func name(a, b) = expr`` or ``.func name(a, b) {expr}``: a user function of the
    behavioural expressions (:mod:`._expr` inlines it at each call, its other names read
    where it is called). One inside a ``.subckt`` is read by :mod:`._scope`."""
    name, names, body = parse_func(line)
    if name in reader.funcs:
        raise line.fail(f".func {name} is defined twice; keep one")
    reader.funcs[name] = (names, body)


def _noted(what):
    def handler(reader, line, pos, kw):
        reader.note(line, f"{card(line)} {what}")

    # a line that is only noted is not read word by word: ngspice goes on past a
    # malformed .probe or .plot (it warns), and so does diracvi
    handler.reads_words = False
    return handler


def _csparam(reader, line, pos, kw):
    """``.csparam name=expr …``: ngspice makes each a vector of the control language
    (``inp.c``, at load, the value numparam's), which the ``.control`` block's ``tran``
    may read as ``$&name`` (:mod:`._control`; evaluated there, after every ``.param``). A
    word that is not ``name=value`` is skipped with the rest of the line, as ngspice
    warns ("bad csparam definition") and skips it."""
    if pos[1:]:
        reader.note(
            line,
            f".csparam: {pos[1]!r} is not name=value; the line is skipped "
            "(ngspice warns 'bad csparam definition' and skips it)",
        )
        return
    for key, token in kw.items():
        reader.csparams[key] = (line, token)
    reader.note(
        line,
        f".csparam {', '.join(kw)}: the control language's vectors (a "
        ".control block's tran may read them as $&name)",
    )


def _refused(why):
    def handler(reader, line, pos, kw):
        raise line.fail(f"directive {card(line)!r} is not supported: {why}")

    return handler


_OUTPUT = _noted("ignored (ngspice's printing; diracvi writes all saved vectors)")


def _measure(reader, line, pos, kw):
    """``.meas[ure] tran NAME …`` (:mod:`._measure`); another analysis's noted."""
    read_measure(reader, line)


# the measure reader splits its own words: a line the general splitter refuses (an open
# parenthesis, 'v(2)==v(1)') is a malformed measure, noted and skipped as ngspice does
_measure.reads_words = False


_ANALYSIS = _noted("ignored (another analysis; diracvi runs the transient)")

#: card -> handler(reader, line, pos, kw)
DIRECTIVES = {
    ".tran": _tran,
    ".ic": _ic,
    ".nodeset": _nodeset,
    ".options": _options,
    ".option": _options,
    ".opt": _options,
    ".temp": _temp,
    ".save": _save,
    ".global": _global,
    ".title": _title,
    ".op": _op,
    ".meas": _measure,
    ".measure": _measure,
    ".probe": _probe,
    **dict.fromkeys((".four", ".print", ".plot", ".width"), _OUTPUT),
    **dict.fromkeys(
        (".ac", ".dc", ".noise", ".tf", ".disto", ".pz", ".sens", ".sp", ".pss"), _ANALYSIS
    ),
    ".func": _func,
    ".csparam": _csparam,
    ".step": _refused("parameter steps; use `diracvi sweep`"),
}
