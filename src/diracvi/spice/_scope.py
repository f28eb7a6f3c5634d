r"""The scope a netlist line is read in: the top level, or one subcircuit instance.

A :class:`Scope` is what element handlers see (``ctx`` in :mod:`._elements`): values
over the visible parameters, the visible models and subcircuits, node names mapped into
the instance (``m`` in ``XA.X1`` → ``xa.x1.m``), and the part names of its elements.
:func:`read_body` reads a list of lines in a scope: its ``.subckt`` definitions, then
its directives in order, then its elements (K lines last, after the inductors they
couple), of the branches its ``.if``/``.elseif``/``.else``/``.endif`` take; every
problem is collected, each naming its line and, inside an instance, the instance chain
(``in xa.x1: …``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ..errors import ModelError
from ._cards import CIDER
from ._elements import ELEMENTS, LATE, SUPPORTED, UNSUPPORTED, _need, _two, unsupported
from ._expr import ExprError, evaluate_constant
from ._lines import Line, LineError, NetlistError, card, split
from ._subckt import MAX_DEPTH, body_params, collect, instance_parts
from ._values import ExpressionError, evaluate, number

GROUNDS = ("0", "gnd")


@dataclass
class Model:
    """A ``.model`` line: its type (upper-case), parameter tokens (evaluated on use)."""

    name: str
    kind: str
    tokens: dict
    line: Line
    scope: Scope
    used: bool = False

    @property
    def where(self) -> str:
        return self.line.where


@dataclass
class Scope:
    """Where a line is read (see the module docstring); ``path`` is the instance chain."""

    reader: object
    path: tuple = ()
    pins: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    models: dict = field(default_factory=dict)
    subckts: dict = field(default_factory=dict)
    names: dict = field(default_factory=dict)  # element name (lower) -> part name
    fixed: frozenset = frozenset()  # parameters the instance set over the body's .param
    # the .func functions of the enclosing subcircuit bodies and this one (name -> (argument
    # names, body)), over the top level's; own: the names this body defines
    local_funcs: dict = field(default_factory=dict)
    own_funcs: set = field(default_factory=set)

    # ---------------------------------------------------------------- for handlers
    @property
    def circuit(self):
        return self.reader.circuit

    @property
    def tran(self):
        return self.reader.tran

    @property
    def temperature(self) -> float:
        """The circuit temperature (°C): ``.temp``, else ``.options temp=``, else 27."""
        return self.reader.temperature

    @property
    def tnom(self) -> float:
        """ngspice's ``.options tnom=`` (°C, default 27): a model card's TNOM default."""
        return self.reader.tnom

    @property
    def funcs(self):
        """The ``.func`` functions visible here: name -> (argument names, body text). A
        ``.func`` of a subcircuit's body is its own (ngspice scopes it to the subcircuit,
        over a top-level one of that name); its names other than its arguments are read
        where it is called, so the instance's parameters (``beta``) are what it sees."""
        if not self.local_funcs:
            return self.reader.funcs
        return {**self.reader.funcs, **self.local_funcs}

    def value(self, token: str, line: Line, what: str) -> float:
        """A number (``4.7k``) or an expression (``{r*2}``, ``'r*2'``, ``r``)."""
        x = number(token)
        if x is not None:
            return x
        text = token[1:-1] if token[:1] in "{'" else token
        try:
            return evaluate(text, self.params, self.funcs)
        except ExpressionError as exc:
            raise line.fail(f"{what}: {exc}") from None

    def _need(self, pos, count, line, form):
        """``raise line.fail`` unless the line has ``count`` positional fields."""
        _need(pos, count, line, form)

    def _two(self, pos, kw, line, form, extra=()):
        """``Xname n+ n- value [extra=…]``: ``(n+, n-, value)``."""
        return _two(self, pos, kw, line, form, extra)

    def declared(self, token: str, line: Line, example: str = "TYPE(…)"):
        """The visible ``.model`` named ``token`` as declared (marked used); refused naming
        the models here and the line to add (``.model token example``)."""
        model = self.models.get(token.lower())
        if model is None:
            known = sorted(self.models) or "none"
            raise line.fail(
                f"model {token!r} is not defined (models here: {known}); add a '.model "
                f"{token} {example}' line"
            )
        model.used = True
        return model

    def model(self, token: str, line: Line):
        """The visible ``.model`` named ``token``: ``(kind, {param: value}, where)``."""
        model = self.declared(token, line)
        if model.kind in CIDER:  # its values are words (concmod=sg): refused before they are read
            raise line.fail(
                f"model {token!r} ({model.where}) is a {model.kind}{CIDER[model.kind]} model"
            )
        params = {}
        for key, tok in model.tokens.items():
            if key == "version" and re.fullmatch(r"\d+(\.\d+){2,}", tok):
                params[key] = tok  # a BSIM card's release, '3.3.0', kept as written
                continue
            params[key] = model.scope.value(tok, model.line, f".model {model.name} {key}")
        return model.kind, params, model.where

    def find_model(self, tokens):
        """The first of ``tokens`` naming a visible model: ``(token, kind, where)``."""
        for token in tokens:
            model = self.models.get(token.lower())
            if model is not None:
                model.used = True
                return token, model.kind, model.where
        return None

    def ref(self, element: str) -> str:
        """The part name of element ``element`` of this scope (for K, F, H)."""
        entry = self.names.get(element.lower())
        return entry[0] if entry else self.part_name(element)

    def node(self, local: str) -> str:
        """A node of a line in this scope → its circuit-wide name (lower-case)."""
        n = local.lower()
        if n in GROUNDS or n in self.reader.globals:
            return n
        if n in self.pins:
            return self.pins[n]
        return ".".join((*self.path, n))

    def ic(self, local: str) -> float:
        """The ``.ic v(node)=…`` voltage of a node of this scope (0 if none)."""
        return self.reader.ic.get(self.node(local), 0.0)

    def note(self, line: Line, text: str) -> None:
        chain = f" in {'.'.join(self.path)}" if self.path else ""
        self.reader.note_once(f"{line.where}{chain}: {text}")

    # --------------------------------------------------------------- names
    def display(self, element: str) -> str:
        """ngspice's name of an element of this scope (``v.xa.x1.v1``)."""
        if not self.path:
            return element
        return ".".join((element[0], *self.path, element)).lower()

    def part_name(self, element: str) -> str:
        """The part's name: the display name with ':' for '.' (parts' names have no dots)."""
        return self.display(element).replace(".", ":")

    # ------------------------------------------------------------ instances
    def instance(self, pos, kw, line) -> None:
        """Expand ``Xname n… SUB [params:] a=…`` into the circuit."""
        nodes, name, overrides = instance_parts(pos, kw, line)
        sub = self.subckts.get(name)
        if sub is None:
            known = sorted(self.subckts) or "none"
            raise line.fail(
                f"subcircuit {name!r} is not defined (subcircuits here: {known}); add "
                f"'.subckt {name} pin… ' … '.ends'"
            )
        if len(nodes) != len(sub.pins):
            raise line.fail(
                f"subcircuit {name!r} ({sub.line.where}) has {len(sub.pins)} pins "
                f"{list(sub.pins)}, the instance gives {len(nodes)} nodes {nodes}"
            )
        in_body = body_params(sub.body) - set(sub.defaults)
        unknown = sorted(set(overrides) - set(sub.defaults) - in_body)
        if unknown:
            raise line.fail(
                f"subcircuit {name!r} has no parameters {unknown} (it has "
                f"{sorted(sub.defaults) or 'none'}; declare them on its '.subckt' line "
                "after 'params:')"
            )
        path = (*self.path, pos[0].lower())
        if len(path) > MAX_DEPTH:
            raise line.fail(f"instances nested {MAX_DEPTH} deep: does {name!r} contain itself?")
        params = dict(self.params)
        for key, token in sub.defaults.items():
            if key in overrides:  # the instance's value, where the instance is
                params[key] = self.value(overrides[key], line, f"parameter {key}")
            else:  # the default, with the parameters before it
                child = Scope(self.reader, path, params=params)
                params[key] = child.value(token, sub.line, f"parameter {key}")
        fixed = frozenset(set(overrides) & in_body)
        for key in sorted(fixed):  # over the body's own .param of that name
            params[key] = self.value(overrides[key], line, f"parameter {key}")
        scope = Scope(
            self.reader,
            path,
            pins={p: self.node(n) for p, n in zip(sub.pins, nodes, strict=True)},
            params=params,
            models=dict(self.models),
            subckts=dict(self.subckts),
            fixed=fixed,
            local_funcs=dict(self.local_funcs),
        )
        sub.used.append(line)
        read_body(scope, sub.body)


# ------------------------------------------------------------------- reading
def read_body(scope: Scope, lines: list[Line]) -> None:
    """Read ``lines`` in ``scope``: the branches its conditionals take
    (:func:`conditional`), then definitions, directives in order, then elements."""
    reader = scope.reader
    try:
        lines = conditional(scope, lines)
    except LineError as exc:  # which lines the netlist means is unknown: read none
        reader.problems.add(exc, ".".join(scope.path))
        return
    rest, defs = collect(lines, reader.problems)
    scope.subckts.update(defs)
    elements, couplings = [], []
    for line in rest:
        if line.text.startswith("."):
            _guard(scope, line, lambda ln=line: _directive(scope, ln))
        elif line.text[0].upper() in LATE:
            couplings.append(line)
        else:
            elements.append(line)
    for line in elements + couplings:
        _guard(scope, line, lambda ln=line: _element(scope, ln))


_CONDITIONAL = re.compile(r"^\.(elseif|if|else|endif)(?![\w.])", re.IGNORECASE)


def conditional(scope: Scope, lines: list[Line]) -> list[Line]:
    """``lines`` with ngspice's netlist conditionals applied: of each ``.if (expr)`` …
    [``.elseif (expr)`` …]… [``.else`` …] ``.endif`` (nestable) the lines of the first
    branch whose expression is not 0 are kept, the rest and the conditional lines
    dropped. As ngspice (``inp.c``'s ``recifeval``, after numparam has replaced each
    expression by its value) the expression is what stands between the line's first
    ``(`` and last ``)``, evaluated over the ``.param`` values above it in this scope;
    the lines of a ``.subckt`` definition are left to the instances that read them.
    An unbalanced or malformed conditional is refused on its line."""
    if not any(_CONDITIONAL.match(line.text) for line in lines):
        return lines
    params = Scope(
        scope.reader, scope.path, params=dict(scope.params), fixed=scope.fixed,
        local_funcs=scope.local_funcs,
    )  # fmt: skip
    kept: list[Line] = []
    # one entry per open .if: [its line, a branch taken so far, this branch is kept]
    stack: list[list] = []
    depth = 0  # inside a .subckt definition (its body is read per instance)
    for line in lines:
        word = card(line)
        live = all(entry[2] for entry in stack)
        if depth or word in (".subckt", ".ends"):
            depth += (word == ".subckt") - (word == ".ends")
            if live:
                kept.append(line)
            continue
        m = _CONDITIONAL.match(line.text)
        if m is None:
            if live:
                kept.append(line)
                if word == ".param":  # the values a later condition reads
                    _param(params, line, quiet=True)
            continue
        kind = m.group(1).lower()
        if kind == "if":
            value = _condition(params, line, ".if") if live else 0.0
            stack.append([line, value != 0.0, value != 0.0])
            continue
        if not stack:
            raise line.fail(
                f"'.{kind}' without an '.if' before it (remove it or add the '.if (expr)')"
            )
        entry = stack[-1]
        if kind == "elseif":
            if entry[1] is None:
                raise line.fail(f"'.elseif' after the '.else' of the '.if' on {entry[0].where}")
            outer = all(e[2] for e in stack[:-1])
            take = not entry[1] and outer and _condition(params, line, ".elseif") != 0.0
            entry[1], entry[2] = entry[1] or take, take
        elif kind == "else":
            if entry[1] is None:
                raise line.fail(f"a second '.else' for the '.if' on {entry[0].where}")
            if line.text.split(None, 1)[1:]:
                raise line.fail("'.else' takes nothing after it; write '.elseif (expr)'")
            entry[1], entry[2] = None, not entry[1]
        else:
            stack.pop()
    if stack:
        raise stack[-1][0].fail("'.if' without its '.endif' (close the conditional)")
    return kept


def _condition(scope: Scope, line: Line, what: str) -> float:
    """The value of a ``.if``/``.elseif`` line's expression (between its first ``(``
    and last ``)``, as ngspice takes it)."""
    text = line.text
    first, last = text.find("("), text.rfind(")")
    if first < 0 or last < first or not text[first + 1 : last].strip():
        raise line.fail(f"'{what}' expects '{what} (expression)', e.g. '{what} (mode == 1)'")
    try:  # numparam's operators (==, <, &&, …): the behavioural expressions' parser
        return evaluate_constant(text[first + 1 : last], scope.params, scope.funcs, numparam=True)
    except ExprError as exc:
        raise line.fail(f"{what}: {exc}") from None


def _guard(scope: Scope, line: Line, action) -> None:
    """Run ``action``; a problem is recorded (with the instance chain), not raised."""
    try:
        action()
    except LineError as exc:  # the instance chain, for a line of this scope's body
        chain = ".".join(scope.path) if exc.line is line else ""
        scope.reader.problems.add(exc, chain)
    except NetlistError as exc:
        scope.reader.problems.add(exc)
    except ModelError as exc:  # a part refusing its values: the line's problem
        scope.reader.problems.add(line.fail(str(exc)), ".".join(scope.path))


def _directive(scope: Scope, line: Line) -> None:
    word = card(line)
    if word == ".param":
        _param(scope, line)
        return
    if word == ".model":
        _model(scope, line)
        return
    if word == ".ic" and scope.path:  # the instance's nodes, by their scoped names
        body = line.text.split(None, 1)[1] if len(line.text.split()) > 1 else ""
        pairs = re.findall(r"v\s*\(\s*([^)\s]+)\s*\)\s*=\s*(\{[^}]*\}|\S+)", body, re.I)
        if not pairs:
            raise line.fail("'.ic' expects V(node)=value pairs")
        for node, token in pairs:  # a top-level .ic of the same node wins, as in ngspice
            value = scope.value(token, line, f".ic v({node})")
            scope.reader.ic.setdefault(scope.node(node), value)
        return
    if word == ".func" and scope.path:  # the subcircuit's own (see Scope.funcs)
        name, names, body = parse_func(line)
        if name in scope.own_funcs:
            raise line.fail(f".func {name} is defined twice in this subcircuit; keep one")
        scope.own_funcs.add(name)
        scope.local_funcs[name] = (names, body)
        return
    if scope.path:
        raise line.fail(
            f"directive {word!r} inside a subcircuit (only .param, .model, .ic, .func and .subckt "
            "may be there); move it outside the '.subckt … .ends'"
        )
    scope.reader.directive(line)


def parse_func(line):
    """``.func name(a, b) = expr`` or ``.func name(a, b) {expr}`` → ``(name, argument
    names, body text)`` (lower-case names; the body's outer braces or quotes removed)."""
    m = re.match(
        r"^\.func\s+([A-Za-z_]\w*)\s*\(([^()]*)\)\s*=?\s*(.+?)\s*$", line.text, re.I | re.S
    )
    if m is None:
        raise line.fail("expected '.func NAME(arg1, arg2, …) = expr' (or '{expr}')")
    name, args, body = m.group(1).lower(), m.group(2), m.group(3)
    names = [a.strip().lower() for a in args.split(",") if a.strip()]
    if body[:1] + body[-1:] in ("{}", "''"):
        body = body[1:-1]
    return name, names, body


def _param(scope: Scope, line: Line, quiet: bool = False) -> None:
    """A ``.param`` line's values into ``scope.params`` (``quiet``: a value that cannot
    be read is left out, its error given when the line is read in order)."""
    pos, kw = split(line)
    if pos[1:]:
        try:
            kw = _one_assignment(line, pos[1:])
        except LineError:
            if quiet:
                return
            raise
    for key, token in kw.items():
        if not scope.path and key in scope.reader.overrides:
            continue  # read(..., params=) wins over the netlist's own value
        if key in scope.fixed:
            continue  # the instance's value wins over the body's (ngspice)
        try:
            scope.params[key] = scope.value(token, line, f".param {key}")
        except LineError:
            if not quiet:
                raise


_ASSIGNMENT = re.compile(r"(?<![<>!=])=(?!=)")  # an '=', not part of ==, <=, >=, !=


def _one_assignment(line: Line, extra: list[str]) -> dict[str, str]:
    """``.param NAME = EXPR`` with an unbraced expression written with blanks
    (``.param tgain = 1. + (TEMPER/27. - 1.) * {fact}``): ngspice reads the whole rest of
    the line as the one expression, a ``{name}`` in it standing for the parameter's value
    (``.param g2 = 3 * 2 + 1`` is 7, ngspice 39). With several assignments on the line
    ngspice's reading is not that (``.param a = 1 + 2, b = 3`` gives a = 1), so such a
    line is refused, naming the fix."""
    body = line.text.split(None, 1)[1] if len(line.text.split()) > 1 else ""
    parts = _ASSIGNMENT.split(body)
    name = parts[0].strip()
    if len(parts) != 2 or not re.fullmatch(r"[A-Za-z_][\w.]*", name):
        raise line.fail(
            f"'.param' expects name=value pairs, got {extra}; write an expression with "
            "blanks in braces (.param x={a + b}) or as the only assignment of its line"
        )
    expr = re.sub(r"\{([^{}]*)\}", r"(\1)", parts[1].strip())  # {fact} is fact's value
    return {name.lower(): "{" + expr + "}"}


def _model(scope: Scope, line: Line) -> None:
    m = re.match(r"\.model\s+(\S+)\s+([A-Za-z_]\w*)\s*\(?(.*?)\)?\s*$", line.text, re.I | re.S)
    if m is None:
        raise line.fail("'.model' expects NAME TYPE(param=value …)")
    name, kind = m.group(1).lower(), m.group(2).upper()
    pos, kw = split(line.with_text(m.group(3)))
    kw.update({flag.lower(): "1" for flag in pos})  # flags such as ltra's 'steplimit'
    first = scope.models.get(name)
    if first is not None and first.scope is scope:
        raise line.fail(f"model {m.group(1)!r} is defined twice (first {first.where})")
    model = Model(name, kind, kw, line, scope)
    scope.models[name] = model
    scope.reader.all_models.append(model)


def _element(scope: Scope, line: Line) -> None:
    pos, kw = split(line)
    if not pos:
        raise line.fail("no element name (an element line starts with its name, e.g. R1)")
    letter = pos[0][0].upper()
    handler = ELEMENTS.get(letter)
    if handler is None:
        if letter in UNSUPPORTED:
            raise unsupported(scope, pos, line)
        raise line.fail(
            f"element {pos[0]!r}: type {letter!r} is not a SPICE element (diracvi reads "
            f"{SUPPORTED}; directives start with '.')"
        )
    key = pos[0].lower()
    if key in scope.names:
        raise line.fail(f"element {pos[0]!r} is defined twice (first {scope.names[key][1]})")
    display = scope.display(pos[0])
    name = display.replace(".", ":")  # (scope.part_name)
    where = line.where
    scope.names[key] = (name, where)
    if not scope.path:  # .probe reads a top-level device's nodes, as ngspice does
        scope.reader.instances[key] = _terminals(scope, pos)
    part, nodes = handler(scope, name, pos, kw, line)
    circuit = scope.reader.circuit
    circuit.origin[name] = f"{where} ({display})"
    if part is None:
        return
    circuit.add(part, **{pin: scope.node(n) for pin, n in nodes.items()})
    scope.reader.display[name] = display


def _terminals(scope: Scope, pos: list[str]) -> list[str]:
    """A top-level element line's nodes in order (circuit-wide names), as ngspice's
    ``.probe`` counts them: two for R C L V I B and D; a MOSFET, JFET, MESFET or BJT's up
    to its model name."""
    letter = pos[0][0].lower()
    if letter in "rclvibd":
        end = 3
    elif letter in "mjzq":
        end = next((j for j, t in enumerate(pos[1:], 1) if t.lower() in scope.models), len(pos))
    else:
        end = 1  # other elements: no pins for .probe
    return [scope.node(n) for n in pos[1:end] if "=" not in n]
