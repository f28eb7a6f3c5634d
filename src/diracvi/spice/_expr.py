r"""ngspice's expression language of behavioural sources (``B``, ``E``/``G`` ``VALUE=``).

    expr    := cond [ '?' expr ':' expr ]                  (right-associative)
    cond    := and  { '||' and }
    and     := eq   { '&&' eq }
    eq      := rel  { ('==' | '!=' | '<>') rel }
    rel     := sum  { ('<' | '<=' | '>' | '>=') sum }
    sum     := prod { ('+' | '-') prod }
    prod    := unary { ('*' | '/') unary }
    unary   := ('-' | '+' | '!') unary | power
    power   := atom { ('^' | '**') powarg }                 (left-associative)
    powarg  := ('-' | '+') powarg | atom
    atom    := number | name | name '(' args ')' | v(n) | v(n1, n2) | i(Vname) | '(' expr ')'

The precedences are ngspice's, measured with ``ngspice -b`` (ngspice-39; the probes are
``tests/test_spice_expr.py``'s table): ``-2^2 = -4``, ``2^3^2 = 64``, ``0 == 0 > -1``
is ``0 == (0 > -1) = 0``, ``1 || 1 && 0 = 1``, ``!1 + 1 = 1``; a comparison, ``&&``,
``||`` and ``!`` give 1 or 0 and read any nonzero value as true. As in ngspice,
``x^y``, ``x**y`` and ``pow(x, y)`` are ``|x|^y`` (``(-2)^3 = 8``), ``pwr(x, y)`` is
``sgn(x)|x|^y``, ``log`` is the natural logarithm, ``u(0) = ½``.

:func:`parse` turns text into a tree of tuples (each with its column, for the messages);
:func:`compile_expression` resolves names (parameters, ``.func`` functions, nodes and
currents) and returns a function of ``(node voltages, controlling currents, t, ddt
values)`` built from ``jax.numpy`` — differentiable, traceable, never ``eval``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import jax.numpy as jnp

from ._values import NOMINAL_TEMPERATURE, _micro, _scaled


class ExprError(ValueError):
    """An expression that cannot be read: the message names the column and the fix."""


_NUM = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.$#]*")
_SUFFIX = re.compile(r"(meg|mil|[fpnumkgt])?[a-z]*", re.IGNORECASE)
_OPS = ("**", "==", "!=", "<>", "<=", ">=", "&&", "||", "+", "-", "*", "/", "^", "<", ">",
        "!", "?", ":", "(", ")", ",")  # fmt: skip
_PROBE = re.compile(r"([vViI])\s*\(([^()]*)\)")


@dataclass
class Token:
    kind: str  # "num", "name", "op", "probe", "end"
    text: str
    col: int
    value: object = None


def tokenize(text: str) -> list[Token]:
    """Tokens of ``text``; ``v(…)``/``i(…)`` are read whole (node names such as ``4A``
    or ``x1.n2`` are not expressions)."""
    text = _micro(text)
    out, k, quoted = [], 0, False
    while k < len(text):
        c = text[k]
        if c.isspace():
            k += 1
            continue
        if c == "'":  # ngspice's numparam puts a quoted expression's value here: '(…)'
            out.append(Token("op", ")" if quoted else "(", k))
            quoted = not quoted
            k += 1
            continue
        probe = _PROBE.match(text, k)
        if probe and (not out or out[-1].kind != "name"):
            args = [a.strip() for a in probe.group(2).split(",")]
            out.append(Token("probe", probe.group(0), k, (probe.group(1).lower(), args)))
            k = probe.end()
            continue
        m = _NUM.match(text, k)
        if m:
            s = _SUFFIX.match(text, m.end())
            suffix = s.group(1)
            value = _scaled(m.group(0), suffix.lower() if suffix else None)
            out.append(Token("num", text[k : s.end()], k, value))
            k = s.end()
            continue
        m = _NAME.match(text, k)
        if m:
            out.append(Token("name", m.group(0), k))
            k = m.end()
            continue
        op = next((o for o in _OPS if text.startswith(o, k)), None)
        if op is None:
            raise ExprError(f"unexpected character {c!r} at column {k + 1}")
        out.append(Token("op", op, k))
        k += len(op)
    if quoted:
        raise ExprError("a quote ' is not closed (write 'expression')")
    out.append(Token("end", "", len(text)))
    return out


_BINARY_LEVELS = (
    ("||",),
    ("&&",),
    ("==", "!=", "<>"),
    ("<", "<=", ">", ">="),
    ("+", "-"),
    ("*", "/"),
)


class _Parser:
    def __init__(self, text: str):
        self.text = text
        self.toks = tokenize(text)
        self.k = 0

    @property
    def tok(self) -> Token:
        return self.toks[self.k]

    def fail(self, why: str, tok: Token | None = None) -> ExprError:
        tok = tok or self.tok
        shown = repr(tok.text) if tok.kind != "end" else "the end"
        return ExprError(f"{why} at {shown} (column {tok.col + 1})")

    def take(self, op: str) -> bool:
        if self.tok.kind == "op" and self.tok.text == op:
            self.k += 1
            return True
        return False

    def expect(self, op: str, fix: str) -> None:
        if not self.take(op):
            raise self.fail(f"expected {op!r} ({fix})")

    def whole(self):
        if self.tok.kind == "end":
            raise self.fail("empty expression")
        node = self.expr()
        if self.tok.kind != "end":
            raise self.fail("unexpected token (an operator missing before it?)")
        return node

    def expr(self):
        cond = self.binary(0)
        if self.tok.kind == "op" and self.tok.text == "?":
            col = self.tok.col
            self.k += 1
            a = self.expr()
            self.expect(":", "a conditional reads 'c ? a : b'")
            b = self.expr()
            return ("?", col, cond, a, b)
        return cond

    def binary(self, level: int):
        if level == len(_BINARY_LEVELS):
            return self.unary()
        node = self.binary(level + 1)
        while self.tok.kind == "op" and self.tok.text in _BINARY_LEVELS[level]:
            op, col = self.tok.text, self.tok.col
            self.k += 1
            node = ("bin", col, "!=" if op == "<>" else op, node, self.binary(level + 1))
        return node

    def unary(self):
        tok = self.tok
        if tok.kind == "op" and tok.text in "-+!":
            self.k += 1
            return ("un", tok.col, tok.text, self.unary())
        return self.power()

    def power(self):
        node = self.atom()
        while self.tok.kind == "op" and self.tok.text in ("^", "**"):
            col = self.tok.col
            self.k += 1
            node = ("bin", col, "^", node, self.powarg())
        return node

    def powarg(self):
        tok = self.tok
        if tok.kind == "op" and tok.text in "-+":
            self.k += 1
            return ("un", tok.col, tok.text, self.powarg())
        return self.atom()

    def atom(self):
        tok = self.tok
        if tok.kind == "num":
            self.k += 1
            return ("num", tok.col, tok.value)
        if tok.kind == "probe":
            self.k += 1
            kind, args = tok.value
            if any(not a for a in args) or len(args) > (2 if kind == "v" else 1):
                form = "v(node) or v(node1, node2)" if kind == "v" else "i(Vname)"
                raise self.fail(f"write {form}", tok)
            return (kind, tok.col, *args)
        if tok.kind == "name":
            self.k += 1
            if self.take("("):
                args = []
                if not self.take(")"):
                    args.append(self.expr())
                    while self.take(","):
                        args.append(self.expr())
                    self.expect(")", f"close the arguments of {tok.text}(")
                return ("call", tok.col, tok.text.lower(), args)
            return ("name", tok.col, tok.text)
        if self.take("("):
            node = self.expr()
            self.expect(")", "close the parenthesis")
            return node
        raise self.fail("expected a number, a name, v(…), i(…) or '('")


def parse(text: str):
    """The tree of ``text`` (:class:`ExprError` on a syntax error)."""
    return _Parser(text).whole()


# ------------------------------------------------------------------ functions
def _pow(x, y):  # ngspice: |x|^y
    return jnp.power(jnp.abs(x), y)


def _step(x):  # ngspice's u(): 1, ½ at 0, 0
    return jnp.where(x > 0, 1.0, jnp.where(x < 0, 0.0, 0.5))


FUNCTIONS = {
    "abs": (1, jnp.abs),
    "sqrt": (1, jnp.sqrt),
    "exp": (1, jnp.exp),
    "ln": (1, jnp.log),
    "log": (1, jnp.log),
    "log10": (1, jnp.log10),
    "sin": (1, jnp.sin),
    "cos": (1, jnp.cos),
    "tan": (1, jnp.tan),
    "atan": (1, jnp.arctan),
    "asin": (1, jnp.arcsin),
    "acos": (1, jnp.arccos),
    "sinh": (1, jnp.sinh),
    "cosh": (1, jnp.cosh),
    "tanh": (1, jnp.tanh),
    "floor": (1, jnp.floor),
    "ceil": (1, jnp.ceil),
    "sgn": (1, jnp.sign),
    "u": (1, _step),
    "uramp": (1, lambda x: jnp.maximum(x, 0.0)),
    "min": (2, jnp.minimum),
    "max": (2, jnp.maximum),
    "pow": (2, _pow),
    "pwr": (2, lambda x, y: jnp.sign(x) * jnp.power(jnp.abs(x), y)),
    "limit": (3, lambda x, a, b: jnp.clip(x, jnp.minimum(a, b), jnp.maximum(a, b))),
    # numparam's name for 'c ? a : b' (both branches are evaluated, as in ngspice)
    "ternary_fcn": (3, lambda c, a, b: jnp.where(c != 0, a, b)),
}
#: ngspice's ``PTfudge_factor``: GMIN·1e-20 = 1e-32 at its default GMIN (``ifeval.c``)
FUDGE = 1e-32


def _divide(a, b):
    """``a / (b ± 1e-32)``, the sign of ``b`` (+ at 0), as ngspice's ``PTdivide``
    divides in a B expression. A divisor of magnitude above ~1e-16 is unchanged (1e-32 is
    below half its ulp); at 0 the value is a·1e32, not NaN or ±inf: a behavioural
    resistor ``r={V(x)}`` whose node ``x`` is 0 in a step's first guess (its capacitor
    charged by UIC) is finite there, as in ngspice, and its Newton iteration can start."""
    return a / (b + jnp.where(b >= 0, FUDGE, -FUDGE))


_BIN = {
    "+": jnp.add,
    "-": jnp.subtract,
    "*": jnp.multiply,
    "/": _divide,
    "^": _pow,
    "==": lambda a, b: jnp.where(a == b, 1.0, 0.0),
    "!=": lambda a, b: jnp.where(a != b, 1.0, 0.0),
    "<": lambda a, b: jnp.where(a < b, 1.0, 0.0),
    "<=": lambda a, b: jnp.where(a <= b, 1.0, 0.0),
    ">": lambda a, b: jnp.where(a > b, 1.0, 0.0),
    ">=": lambda a, b: jnp.where(a >= b, 1.0, 0.0),
    "&&": lambda a, b: jnp.where((a != 0) & (b != 0), 1.0, 0.0),
    "||": lambda a, b: jnp.where((a != 0) | (b != 0), 1.0, 0.0),
}
#: names ngspice's B source knows that diracvi does not evaluate, with the reason
_REFUSED = {
    "hertz": "the AC-analysis frequency (diracvi runs transients only)",
}
DISCONTINUOUS = (
    "u",
    "sgn",
    "floor",
    "ceil",
    "ternary_fcn",
    "<",
    "<=",
    ">",
    ">=",
    "==",
    "!=",
    "&&",
    "||",
    "!",
)


# ------------------------------------------------------------------ compile
@dataclass
class Compiled:
    """A compiled expression.

    ``fn(v, i, t, d)``: the value, with ``v`` the voltages of :attr:`pairs` (``v[k] =
    φ(pairs[k][0]) − φ(pairs[k][1])``), ``i`` the currents of :attr:`currents`, ``t``
    the time and ``d`` the values of ``ddt(derivatives[k])``; :attr:`derivatives` are
    the arguments of ``ddt`` as functions ``g(v, i, t)``.
    """

    text: str
    fn: object
    pairs: list = field(default_factory=list)  # (node, node or "0") as written
    currents: list = field(default_factory=list)  # source names as written
    derivatives: list = field(default_factory=list)
    uses_time: bool = False
    discontinuous: list = field(default_factory=list)  # operators/functions with jumps
    numparam: bool = False  # read as ngspice's numparam reads a .param/.measure PARAM


def compile_expression(
    text: str, params: dict, funcs: dict | None = None, numparam: bool = False
) -> Compiled:
    """Parse ``text`` and resolve its names: ``params`` (lower-case name → number),
    ``funcs`` (lower-case name → ``(argument names, body text)`` of ``.func``). Every
    unknown name is listed in one :class:`ExprError`. ``numparam``: the expression is
    one ngspice evaluates with numparam (a ``.measure … PARAM=``), where ``min(x)`` and
    ``max(x)`` with one argument are ``min(1, x)`` and ``max(1, x)`` (its first argument
    defaults to 1.0, ``xpressn.c``; a B source's one-argument ``max`` crashes ngspice 39)."""
    tree = parse(text)
    out = Compiled(text, None, numparam=numparam)
    problems: list[str] = []
    funcs = {k.lower(): v for k, v in (funcs or {}).items()}
    params = {k.lower(): v for k, v in params.items()}
    fn = _build(tree, out, params, funcs, {}, problems, in_ddt=False, depth=0)
    if problems:
        raise ExprError("; ".join(dict.fromkeys(problems)))
    out.fn = fn
    return out


def _index(items: list, key) -> int:
    if key not in items:
        items.append(key)
    return items.index(key)


def _build(node, out, params, funcs, local, problems, in_ddt, depth):
    """``node`` → a function ``f(v, i, t, d)`` (unknown names go to ``problems``)."""

    def sub(n, *, ddt=in_ddt, loc=local, dep=depth):
        return _build(n, out, params, funcs, loc, problems, ddt, dep)

    kind, col = node[0], node[1]
    if kind == "num":
        x = node[2]
        return lambda v, i, t, d: x
    if kind == "v":
        a, b = node[2], node[3] if len(node) > 3 else "0"
        k = _index(out.pairs, (a, b))
        return lambda v, i, t, d: v[k]
    if kind == "i":
        k = _index(out.currents, node[2])
        return lambda v, i, t, d: i[k]
    if kind == "name":
        key = node[2].lower()
        if key in local:
            f = local[key]
            return f
        if key == "time":
            out.uses_time = True
            return lambda v, i, t, d: t
        if key in params:
            x = params[key]
            return lambda v, i, t, d: x
        if key == "pi":
            return lambda v, i, t, d: math.pi
        if key == "temper":  # no reader: 27 °C (a netlist puts its .temp in params)
            return lambda v, i, t, d: NOMINAL_TEMPERATURE
        if key in _REFUSED:
            problems.append(f"{node[2]!r} (column {col + 1}) is {_REFUSED[key]}")
        else:
            problems.append(
                f"unknown name {node[2]!r} at column {col + 1} (define it with .param, or "
                "write v(node) / i(Vname))"
            )
        return lambda v, i, t, d: 0.0
    if kind == "un":
        f = sub(node[3])
        if node[2] == "-":
            return lambda v, i, t, d: -f(v, i, t, d)
        if node[2] == "!":
            out.discontinuous.append("!")
            return lambda v, i, t, d: jnp.where(f(v, i, t, d) == 0, 1.0, 0.0)
        return f
    if kind == "bin":
        op = node[2]
        f, g = sub(node[3]), sub(node[4])
        h = _BIN[op]
        if op in DISCONTINUOUS:
            out.discontinuous.append(op)
        return lambda v, i, t, d: h(f(v, i, t, d), g(v, i, t, d))
    if kind == "?":
        c, a, b = sub(node[2]), sub(node[3]), sub(node[4])
        out.discontinuous.append("?:")
        return lambda v, i, t, d: jnp.where(c(v, i, t, d) != 0, a(v, i, t, d), b(v, i, t, d))
    if kind == "call":
        return _call(node, out, params, funcs, local, problems, in_ddt, depth, sub)
    raise AssertionError(node)  # pragma: no cover - the parser makes no other node


def _call(node, out, params, funcs, local, problems, in_ddt, depth, sub):
    col, name, args = node[1], node[2], node[3]
    if name == "ddt":
        if len(args) != 1:
            problems.append(f"ddt takes one argument (column {col + 1})")
            return lambda v, i, t, d: 0.0
        if in_ddt:
            problems.append(f"ddt inside ddt (column {col + 1}) is not supported")
            return lambda v, i, t, d: 0.0
        g = sub(args[0], ddt=True)
        k = len(out.derivatives)
        out.derivatives.append(lambda v, i, t, g=g: g(v, i, t, None))
        return lambda v, i, t, d: d[k]
    if name == "idt":
        problems.append(
            f"idt (column {col + 1}) is not supported; integrate with a capacitor (a "
            "current into C gives its voltage) or a G source into a capacitor"
        )
        return lambda v, i, t, d: 0.0
    if name in funcs:
        names, body = funcs[name]
        if len(args) != len(names):
            problems.append(
                f".func {name} takes {len(names)} arguments, {len(args)} given (column {col + 1})"
            )
            return lambda v, i, t, d: 0.0
        if depth > 20:
            problems.append(f".func {name} calls itself (column {col + 1})")
            return lambda v, i, t, d: 0.0
        try:
            tree = parse(body)
        except ExprError as exc:
            problems.append(f".func {name}: {exc}")
            return lambda v, i, t, d: 0.0
        bound = {**local, **{a.lower(): sub(x) for a, x in zip(names, args, strict=True)}}
        return sub(tree, loc=bound, dep=depth + 1)
    spec = FUNCTIONS.get(name)
    if spec is None:
        problems.append(
            f"unknown function {name!r} at column {col + 1} (known: "
            f"{', '.join(sorted([*FUNCTIONS, 'ddt']))}, or define it with .func)"
        )
        return lambda v, i, t, d: 0.0
    arity, fn = spec
    if out.numparam and name in ("min", "max") and len(args) == 1:
        args = [("num", col, 1.0), *args]  # numparam's default first argument
    if len(args) != arity:
        problems.append(f"{name} takes {arity} argument(s), {len(args)} given (column {col + 1})")
        return lambda v, i, t, d: 0.0
    if name in DISCONTINUOUS:
        out.discontinuous.append(name)
    fs = [sub(a) for a in args]
    return lambda v, i, t, d: fn(*(f(v, i, t, d) for f in fs))


def evaluate_constant(
    text: str, params: dict, funcs: dict | None = None, numparam: bool = False
) -> float:
    """The value of an expression without nodes, currents, time or ddt (for tests,
    constant sources and ``.if`` conditions; ``numparam`` as in :func:`compile_expression`)."""
    c = compile_expression(text, params, funcs, numparam)
    if c.pairs or c.currents or c.derivatives or c.uses_time:
        raise ExprError(f"{text!r} is not a constant")
    return float(c.fn(jnp.zeros(0), jnp.zeros(0), 0.0, ()))
