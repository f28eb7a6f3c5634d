r"""The part of ngspice's control language a transient needs: the first ``tran`` command
of the deck's ``.control`` blocks, with its ``$&name`` and ``$name`` substituted.

diracvi runs no ``.control`` block, but a netlist with no ``.tran`` takes the blocks'
first ``tran`` as its ``.tran`` (:mod:`._parse`). Before ngspice runs a command it
substitutes the words' variables (``cp_variablesubst``, ``src/frontend/variable.c``):

- ``$&name`` is the vector ``name`` (``cp_enqvar``'s ``&`` case,
  ``src/frontend/options.c``), made by ``let name = expr`` in the block or by
  ``.csparam name = expr`` in the netlist (``src/frontend/inp.c``: a ``let`` of each
  pair, numparam's value, when the deck is loaded). A one-element vector is written into
  the word as C's ``%G``: six significant digits (``cp_varwl``; ngspice 39 has no
  ``csnumprec``), so ``let t = 1/3*1e-6`` runs ``tran … $&t`` to 3.33333e-7, and so does
  diracvi. A ``let`` is evaluated in full precision (vectors are doubles); only the
  substitution rounds.
- ``$name`` is the variable of ``set name = value`` (``cp_setparse``): a number
  (``ft_numparse``) is written as ``%d`` when whole and ``%G`` otherwise, a quoted value as
  written. A vector is not a variable: ngspice says "no such variable" and drops the word.

A ``let`` is read like a ``.param`` (:func:`~._values.evaluate`: numbers with their
scales, arithmetic, the math functions) over the ``.csparam`` values and the ``let``\s
before it — never the ``.param`` values, which the control language does not see.
Vectors live in plots: a ``let`` before any analysis lands in the ``const`` plot, seen
from every later plot; one after an analysis (``op``, ``ac``, …) lands in that analysis's
plot and is not seen once the next analysis has made a new one. All of this was checked
against ngspice 39 (``tests/test_control_vars.py``). A ``let`` whose value diracvi cannot
know before the run (``v(1)``, ``vector(3)``, an index), one inside an ``if``/``while``
block, or one made before a ``setplot`` is refused when the ``tran`` uses it, naming its
line; unused, it is ignored, as the rest of the block is.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ._lines import Line, card
from ._values import ExpressionError, evaluate, number

__all__ = ["ControlTran", "first_tran"]

#: commands after which ngspice's current plot is a new one (the analyses, and the
#: commands that make a plot of their own)
_NEW_PLOT = frozenset("op ac dc noise tf sens pz disto pss sp run linearize load fft spec".split())
#: commands opening a block that ``end`` closes (a ``let`` in one may not run)
_BLOCK = frozenset("if while repeat dowhile foreach".split())
#: commands that change the circuit or its options for the runs after them
_CHANGES = frozenset("alter altermod alterparam reset option options mc_source".split())

_LET = re.compile(r"let\s+([^\s=]+)\s*=\s*(.*)$", re.IGNORECASE)
_SET = re.compile(r'([A-Za-z_]\w*)\s*=\s*("[^"]*"|\S+)|([A-Za-z_]\w*)')
_REF = re.compile(r"\$(&?)([A-Za-z_]\w*)")
_NAME = re.compile(r"[A-Za-z_]\w*")


@dataclass
class _Let:
    """A vector of a ``let``: its value, or why it has none before the run."""

    line: Line
    value: float | None
    why: str = ""


@dataclass
class ControlTran:
    """The first ``tran`` of the ``.control`` blocks and what its variables can be.

    ``notes``: the further ``tran`` commands (skipped) and the commands before the first
    that change the circuit (not applied), each with its line."""

    line: Line
    lets: list = field(default_factory=list)  # (plot, name, line, expression, depth)
    sets: dict = field(default_factory=dict)  # name -> (line, text written or None)
    setplots: list = field(default_factory=list)  # the setplot lines before the tran
    plot: int = 0  # the current plot at the tran (0: const)
    notes: list = field(default_factory=list)

    def resolve(self, csparams: dict[str, tuple[Line, float]]) -> tuple[str, list[str]]:
        """The ``tran`` command's text with its ``$&name`` and ``$name`` written as
        ngspice writes them, and what each was (for the notes). ``csparams``: the
        ``.csparam`` vectors, name → (line, value). Raises ``line.fail`` naming the
        value and the fix for a variable it cannot give."""
        vectors = self._vectors(csparams)
        said: list[str] = []

        def one(m: re.Match) -> str:
            amp, name = m.group(1), m.group(2).lower()
            if amp:
                return self._vector(vectors, name, said)
            return self._variable(vectors, name, said)

        text = _REF.sub(one, self.line.text)
        if "$" in text:
            raise self.line.fail(
                f"{text!r}: a '$' diracvi cannot substitute (it reads $&name, a vector of a "
                "let or .csparam, and $name, a variable of set); write the number"
            )
        return text, said

    # ------------------------------------------------------------------ vectors
    def _vectors(self, csparams) -> dict:
        """(plot, name) → :class:`_Let` at the tran: the ``.csparam`` vectors in the
        const plot (0), then each ``let`` (or ``unlet``) in order, in the plot current at
        its line."""
        env: dict = {(0, k): _Let(line, value) for k, (line, value) in csparams.items()}
        for plot, name, line, expr, depth in self.lets:
            key = (plot, name.lower())
            if expr is None:  # unlet: the vector vec_get finds is gone
                env.pop(key if key in env else (0, key[1]), None)
            elif not _NAME.fullmatch(name):
                base = (plot, name.split("[")[0].lower())
                env[base] = _Let(line, None, f"'let {name} = …' sets an element of a vector")
            elif depth:
                env[key] = _Let(line, None, "the let is inside an if/while/repeat/foreach block")
            else:
                known = {n: v for (p, n), v in env.items() if p == 0}
                known.update({n: v for (p, n), v in env.items() if p == plot and plot})
                env[key] = _value(line, name, expr, known)
        return env

    def _lookup(self, vectors, name):
        """The vector ``name`` as ngspice's ``vec_get`` finds it at the tran: the current
        plot's, else the const plot's (``None``: neither)."""
        return vectors.get((self.plot, name)) or vectors.get((0, name))

    def _vector(self, vectors, name, said) -> str:
        found = self._lookup(vectors, name)
        if found is None:
            hidden = [k for k in vectors if k[1] == name]
            where = (
                f" (its let, {vectors[hidden[-1]].line.where}, is in a plot an analysis "
                "after it replaced as ngspice's current plot)"
                if hidden
                else ""
            )
            raise self.line.fail(
                f"'$&{name}': no vector {name!r} at this tran{where}; define it before the "
                f"tran with 'let {name} = <number or expression>' in the .control block, or "
                f"'.csparam {name} = <value>' in the netlist, or write the number"
            )
        if found.value is None:
            raise self.line.fail(
                f"'$&{name}': its value is not known before the run ({found.line.where}: "
                f"{found.why}); diracvi evaluates a let of numbers, .csparam values and earlier "
                "lets, outside if/while blocks; write the number in the tran, or a let of one"
            )
        if self.setplots and card(found.line) != ".csparam":
            raise self.line.fail(
                f"'$&{name}': a setplot ({self.setplots[0].where}) comes before the tran, and "
                "diracvi does not follow which plot a let lands in after it; write the "
                "number, or a .csparam"
            )
        text = f"{found.value:G}"
        said.append(f"$&{name} = {text} ({found.line.where})")
        return text

    def _variable(self, vectors, name, said) -> str:
        entry = self.sets.get(name)
        if entry is None:
            vector = (
                f" (a vector: ngspice says 'no such variable' and drops the word; write '$&{name}')"
                if self._lookup(vectors, name) is not None
                else ""
            )
            raise self.line.fail(
                f"'${name}': no 'set {name} = …' before the tran{vector}; $name is a "
                f"variable of set (write 'set {name} = <number>' before the tran, or the "
                "number)"
            )
        line, text = entry
        if text is None:
            raise self.line.fail(
                f"'${name}': the set at {line.where} gives no number ({line.text!r}); write "
                f"'set {name} = <number>' or the number"
            )
        said.append(f"${name} = {text} ({line.where})")
        return text


def _value(line: Line, name: str, expr: str, known: dict) -> _Let:
    """A ``let``'s vector: its expression over the visible vectors, or why not."""
    values = {n: v.value for n, v in known.items() if v.value is not None}
    try:
        return _Let(line, evaluate(expr, values))
    except ExpressionError as exc:
        blocked = [n for n in _NAME.findall(expr) if n.lower() in known and n.lower() not in values]
        if blocked:  # it reads a vector with no value: that one's reason
            inner = known[blocked[0].lower()]
            why = f"'let {name} = {expr}' reads {blocked[0]!r} ({inner.line.where}: {inner.why})"
            return _Let(line, None, why)
        hint = " (a vector of a run, or a list)" if re.search(r"[(\[]", expr) else ""
        told = str(exc).replace(" (or define it with .func)", "")  # no .func in a let
        return _Let(line, None, f"'let {name} = {expr}' is not a number{hint}: {told}")


def _set_text(value: str) -> str | None:
    """A ``set`` value as ``$name`` writes it (``cp_setparse``, ``cp_varwl``)."""
    if value.startswith('"'):
        return value.strip('"')
    x = number(value)
    if x is None:
        return value
    if float(int(x)) == x and abs(x) < 2**31:
        return str(int(x))
    return f"{x:G}"


def first_tran(commands: list[Line]) -> ControlTran | None:
    """The first ``tran`` of the ``.control`` lines ``commands`` with what its variables
    can be (the ``let``, ``set`` and plot-making commands before it), or ``None``."""
    plot, plots, depth = 0, 0, 0
    lets, sets, setplots, changes = [], {}, [], []
    found: ControlTran | None = None
    for line in commands:
        word = card(line)
        if found is not None:
            if word == "tran":
                found.notes.append(
                    f"{line.where}: a further 'tran' of the .control block is skipped "
                    f"(diracvi runs the first, {found.line.where}, ngspice's first transient plot)"
                )
            continue
        if word == "tran":
            found = ControlTran(line, lets, sets, setplots, plot)
            found.notes += [
                f"{c.where}: {c.text!r} before the .control block's tran is not applied "
                "(diracvi runs the netlist's circuit and options)"
                for c in changes
            ]
            continue
        if word in _BLOCK:
            depth += 1
        elif word == "end" and depth:
            depth -= 1
        elif word in _NEW_PLOT:
            plots += 1
            plot = plots
        elif word == "setplot":
            setplots.append(line)
        elif word in _CHANGES:
            changes.append(line)
        elif word == "let":
            m = _LET.match(line.text)
            if m:
                lets.append((plot, m.group(1), line, m.group(2).strip(), depth))
        elif word == "unlet":
            lets += [(plot, name, line, None, depth) for name in line.text.split()[1:]]
        elif word == "set":
            body = line.text.split(None, 1)[1] if len(line.text.split()) > 1 else ""
            for m in _SET.finditer(body):
                if m.group(1):
                    sets[m.group(1).lower()] = (line, _set_text(m.group(2)))
                else:
                    sets[m.group(3).lower()] = (line, None)  # a boolean
        elif word == "unset":
            for name in line.text.split()[1:]:
                sets.pop(name.lower(), None)
    return found
