"""SPICE numbers (``4.7k``, ``1meg``, ``10uF``) and ``.param`` expressions, evaluated safely.

Expressions are parsed with :mod:`ast` and evaluated by walking the tree: numbers,
parameter names, ``+ − * / ** ^``, parentheses and a fixed set of functions — never
``eval``.
"""

from __future__ import annotations

import ast
import functools
import keyword
import math
import operator
import re
from decimal import Decimal

import jax
import jax.numpy as jnp

SCALE = {
    "f": 1e-15,
    "p": 1e-12,
    "n": 1e-9,
    "u": 1e-6,
    "m": 1e-3,
    "k": 1e3,
    "meg": 1e6,
    "g": 1e9,
    "t": 1e12,
    "mil": 25.4e-6,
}
_NUMBER = re.compile(
    r"^([+-]?(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?)(meg|mil|[fpnumkgt])?([a-z]*)$", re.IGNORECASE
)
# a number with a suffix inside an expression (not part of a name such as k1)
_IN_EXPR = re.compile(
    r"(?<![A-Za-z_\d.])((?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?)(meg|mil|[fpnumkgt])[a-z]*",
    re.IGNORECASE,
)
FUNCTIONS = {
    "sqrt": math.sqrt,
    "exp": math.exp,
    "log": math.log,
    "ln": math.log,
    "log10": math.log10,
    "sin": math.sin,
    "cos": math.cos,
    "tan": math.tan,
    "atan": math.atan,
    "abs": abs,
    # numparam's first argument defaults to 1.0 (xpressn.c): max(x) is max(1, x)
    "min": lambda *a: min((1.0, *a) if len(a) == 1 else a),
    "max": lambda *a: max((1.0, *a) if len(a) == 1 else a),
    "pow": math.pow,
}
_BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}


class ExpressionError(ValueError):
    """A number or expression that cannot be read (the parser adds the line)."""


@functools.lru_cache(maxsize=4096)  # (a netlist repeats its values: 10⁵ × "1u" in a ladder)
def number(token: str) -> float | None:
    """``4.7k`` → 4700.0; trailing letters after a scale (``1kOhm``) are ignored as in
    SPICE (note ``1F`` is one femto-unit, as SPICE reads it). ``None`` if not a number."""
    m = _NUMBER.match(_micro(token))
    if m is None:
        return None
    return _scaled(m.group(1), m.group(2))


def _micro(text: str) -> str:
    """ngspice reads the micro sign (µ U+00B5, μ U+03BC) as ``u``."""
    return text.replace("\u00b5", "u").replace("\u03bc", "u")


def _scaled(mantissa: str, suffix: str | None) -> float:
    """Mantissa × scale in exact decimal arithmetic, then rounded once (10u == 1e-5)."""
    if not suffix:
        return float(mantissa)
    return float(Decimal(mantissa) * Decimal(repr(SCALE[suffix.lower()])))


#: jax.numpy names of FUNCTIONS that differ (a traced argument is evaluated by jax.numpy)
_JNP = {"ln": "log", "pow": "power", "atan": "arctan", "min": "minimum", "max": "maximum"}


def _traced(x) -> bool:
    return isinstance(x, jax.core.Tracer)


#: ngspice's default circuit and nominal temperature (°C): ``TEMPER`` without ``.temp``
#: (the reader puts the circuit temperature in the parameters as ``temper``)
NOMINAL_TEMPERATURE = 27.0
#: 0 °C in kelvin (ngspice's CONSTCtoK)
KELVIN = 273.15


def evaluate(text: str, params: dict[str, float], funcs: dict | None = None) -> float:
    """Evaluate a SPICE expression over ``params`` (names case-insensitive) and the
    ``.func`` user functions ``funcs`` (lower-case name → ``(argument names, body
    text)``; a call ``f(x, y)`` is the body evaluated with its arguments bound to the
    values of ``x`` and ``y``, as ngspice evaluates a ``.func`` in a ``.param``)."""
    tree = _tree(text)
    funcs = {k.lower(): v for k, v in (funcs or {}).items()}
    value = _walk(tree.body, {k.lower(): v for k, v in params.items()}, text, funcs)
    if _traced(value):  # a parameter being differentiated (read(..., params=)): unchecked
        return value
    if not math.isfinite(value):
        raise ExpressionError(f"expression {text!r} is not finite ({value})")
    return float(value)


#: Python's keywords, which are names in SPICE (``.param is = 0``): renamed for ``ast``
_KEYWORDS = re.compile(
    r"(?<![\w.])(" + "|".join(sorted(keyword.kwlist, key=len, reverse=True)) + r")(?![\w.])",
    re.IGNORECASE,
)
_KEYWORD_PREFIX = "_spice_name_"


@functools.lru_cache(maxsize=4096)
def _tree(text: str):
    """The parsed expression ``text`` (remembered: a subcircuit's ``W={2*w}`` is one
    text for 10⁴ instances, each of its own ``w``; ``_walk`` only reads the tree)."""
    source = _IN_EXPR.sub(lambda m: repr(_scaled(m.group(1), m.group(2))), _micro(text.strip()))
    source = _KEYWORDS.sub(lambda m: _KEYWORD_PREFIX + m.group(1), source.replace("^", "**"))
    try:
        return ast.parse(source, mode="eval")
    except SyntaxError:
        raise ExpressionError(f"cannot parse expression {text!r}") from None


#: how deep ``.func`` calls may nest (deeper is a function calling itself)
_FUNC_DEPTH = 20


def _walk(node, params, text, funcs=None, depth=0):
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
        return float(node.value)
    if isinstance(node, ast.Name):
        key = node.id.lower().removeprefix(_KEYWORD_PREFIX)
        if key in params:
            return params[key]
        if key == "pi":
            return math.pi
        if (
            key == "temper"
        ):  # no reader: ngspice's default temperature (a netlist sets it in params)
            return NOMINAL_TEMPERATURE
        raise ExpressionError(f"unknown parameter {node.id!r} in {text!r} (define it with .param)")
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        x = _walk(node.operand, params, text, funcs, depth)
        return -x if isinstance(node.op, ast.USub) else x
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        a = _walk(node.left, params, text, funcs, depth)
        b = _walk(node.right, params, text, funcs, depth)
        try:
            return _BINARY[type(node.op)](a, b)
        except (ZeroDivisionError, OverflowError) as exc:
            raise ExpressionError(f"{text!r}: {exc}") from None
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
        if funcs and node.func.id.lower() in funcs:
            return _user(node, params, text, funcs, depth)
        fn = FUNCTIONS.get(node.func.id.lower())
        if fn is None:
            raise ExpressionError(
                f"unknown function {node.func.id!r} in {text!r}; known: {sorted(FUNCTIONS)} "
                "(or define it with .func)"
            )
        args = [_walk(a, params, text, funcs, depth) for a in node.args]
        if any(_traced(a) for a in args):
            return getattr(jnp, _JNP.get(node.func.id.lower(), node.func.id.lower()))(*args)
        try:
            return float(fn(*args))
        except (TypeError, ValueError, OverflowError) as exc:
            raise ExpressionError(f"{text!r}: {node.func.id}: {exc}") from None
    raise ExpressionError(f"unsupported syntax in expression {text!r}")


def _user(node, params, text, funcs, depth):
    """A ``.func`` call: its body over ``params`` with the arguments' values bound."""
    name = node.func.id.lower()
    names, body = funcs[name]
    if len(node.args) != len(names):
        raise ExpressionError(
            f".func {name} takes {len(names)} arguments, {len(node.args)} given in {text!r}"
        )
    if depth >= _FUNC_DEPTH:
        raise ExpressionError(f".func {name} calls itself (in {text!r})")
    args = [_walk(a, params, text, funcs, depth) for a in node.args]
    bound = {**params, **{a.lower(): x for a, x in zip(names, args, strict=True)}}
    return _walk(_tree(body).body, bound, body, funcs, depth + 1)
