r"""Which form a user callable is written in: autonomous ``f(q, v)`` or driven ``f(q, v, t)``.

Decided once, when a system is built, from the callable's signature (its positional
parameters), so nothing is guessed per call. A callable that accepts both forms (a
defaulted ``t``, ``*args``) is ambiguous and is refused with the fix named.
"""

from __future__ import annotations

import inspect
import types
from collections.abc import Callable

from ..errors import ModelError

_POSITIONAL = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)

#: a defaulted parameter with one of these names, where ``t`` would go, reads as time
TIME_NAMES = ("t", "time")


def takes_time(arg: str, fn: Callable, autonomous: str, driven: str) -> bool | None:
    """``True`` for the driven form, ``False`` for the autonomous one.

    ``autonomous``/``driven`` are the two accepted signatures, e.g. ``"L(q, v)"`` and
    ``"L(q, v, t)"``. The number of *required* positional parameters decides, so the
    closure idiom ``def L(q, v, m=m)`` stays autonomous; a defaulted parameter named
    ``t``/``time`` in the time slot, or ``*args``, leaves it open and is refused.
    Returns ``None`` when the signature cannot be read (the caller then tries the
    autonomous form).
    """
    n_auto = autonomous.count(",") + 1
    try:
        params = _parameters(fn)
    except (TypeError, ValueError):
        return None
    positional = [p for p in params if p.kind in _POSITIONAL]
    variadic = any(p.kind is inspect.Parameter.VAR_POSITIONAL for p in params)
    required = sum(p.default is inspect.Parameter.empty for p in positional)
    if required == n_auto + 1:
        return True
    if required == n_auto:
        slot = positional[n_auto] if len(positional) > n_auto else None
        if not variadic and (slot is None or slot.name not in TIME_NAMES):
            return False
    elif required > n_auto + 1 or not (variadic or len(positional) >= n_auto):
        raise ModelError(
            f"{arg}={_name(fn)} takes {required} required positional argument(s), but it "
            f"must be callable as {autonomous} or as {driven}."
        )
    raise ModelError(
        f"{arg}={_name(fn)} accepts both {autonomous} and {driven} (a defaulted time "
        f"argument or *args), so it is ambiguous whether it depends on time. Fix: write "
        f"it as exactly {autonomous} (autonomous) or {driven} with t required (driven)."
    )


#: the parameters of plain functions by what decides them (a netlist's 10⁴ parts build
#: closures of a few codes; ``inspect.signature`` costs ~0.1 ms each)
_PARAMETERS: dict = {}
_PARAMETERS_LIMIT = 1024


def _parameters(fn: Callable) -> list:
    """``inspect.signature(fn)``'s parameters; for a plain function (not wrapped, no
    ``__signature__``) remembered by its code and which of its arguments have defaults."""
    if (
        type(fn) is not types.FunctionType
        or "__wrapped__" in vars(fn)
        or ("__signature__" in vars(fn))
    ):
        return list(inspect.signature(fn).parameters.values())
    key = (fn.__code__, len(fn.__defaults__ or ()), tuple(fn.__kwdefaults__ or ()))
    hit = _PARAMETERS.get(key)
    if hit is None:
        if len(_PARAMETERS) >= _PARAMETERS_LIMIT:
            _PARAMETERS.clear()
        hit = _PARAMETERS[key] = list(inspect.signature(fn).parameters.values())
    return hit


def _name(fn: Callable) -> str:
    return getattr(fn, "__qualname__", None) or getattr(fn, "__name__", None) or repr(fn)
