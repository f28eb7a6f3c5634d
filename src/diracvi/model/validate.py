"""Checks shared by the public entry points; each raises ModelError naming argument,
value and fix."""

from __future__ import annotations

import math
import numbers
from collections import Counter
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError


def _short(value, limit: int = 80) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def check_name(arg: str, value) -> str:
    if not isinstance(value, str) or not value or "." in value or value != value.strip():
        raise ModelError(
            f"{arg}={_short(value)} is not a valid name: use a non-empty string without "
            "dots or surrounding spaces (dots separate subsystem and coordinate names)."
        )
    return value


def check_names(arg: str, values) -> tuple[str, ...]:
    if isinstance(values, str) or not isinstance(values, Sequence):
        raise ModelError(
            f"{arg}={_short(values)} must be a sequence of names, e.g. {arg}=('x', 'y')."
        )
    names = tuple(values)
    if not names:
        raise ModelError(f"{arg}=() is empty: a system needs at least one coordinate.")
    for name in names:
        if not isinstance(name, str) or not name or name != name.strip():
            raise ModelError(
                f"{arg} contains {_short(name)}, which is not a valid name: use non-empty "
                "strings without surrounding spaces."
            )
    duplicates = sorted(n for n, c in Counter(names).items() if c > 1)  # O(n), not O(n²)
    if duplicates:
        raise ModelError(f"{arg} repeats {duplicates}: every name must be unique.")
    return names


def check_callable(arg: str, value) -> Callable:
    if not callable(value):
        raise ModelError(
            f"{arg}={_short(value)} is not callable: pass a function of the documented "
            "signature that JAX can trace."
        )
    return value


#: output shapes of ``equinox.Module`` callables by structure (see :func:`eval_shape`)
_SHAPES: dict = {}
_SHAPES_LIMIT = 256


def _structure(fn, shapes, signature):
    """A key under which ``fn``'s traced output shape is known, or ``None``: an
    ``equinox.Module`` callable's output shape depends only on its static part and the
    shapes of its arrays, so systems rebuilt with new parameter values (a sweep builds
    one per member) need not be traced again."""
    import equinox as eqx

    if not isinstance(fn, eqx.Module):
        return None
    arrays, rest = eqx.partition(fn, eqx.is_array)
    leaves, treedef = jax.tree.flatten(arrays)
    key = (rest, treedef, tuple((np.shape(a), np.dtype(a.dtype).str) for a in leaves))
    key += (tuple(shapes), signature)
    try:
        hash(key)
    except TypeError:
        return None
    return key


def eval_shape(arg: str, fn: Callable, *shapes: tuple[int, ...], signature: str):
    """Trace ``fn`` abstractly on float64 zeros of the given shapes; wrap any failure."""
    key = _structure(fn, shapes, signature)
    if key is not None and key in _SHAPES:
        return _SHAPES[key]
    out = _eval_shape(arg, fn, *shapes, signature=signature)
    if key is not None:
        if len(_SHAPES) >= _SHAPES_LIMIT:
            _SHAPES.clear()
        _SHAPES[key] = out
    return out


def _eval_shape(arg: str, fn: Callable, *shapes: tuple[int, ...], signature: str):
    specs = [jax.ShapeDtypeStruct(s, jnp.float64) for s in shapes]
    try:
        out = jax.eval_shape(fn, *specs)
    except Exception as exc:
        raise ModelError(
            f"{arg} failed when JAX traced it as {signature} with arrays of shape "
            f"{', '.join(str(s) for s in shapes)}: {type(exc).__name__}: {exc}. "
            "Fix: write it with jax.numpy operations on the given 1-D arrays (no Python "
            "control flow on their values, no NumPy-only functions)."
        ) from exc
    if not hasattr(out, "shape") or not hasattr(out, "dtype"):
        raise ModelError(
            f"{arg} returned {_short(out)} (a {type(out).__name__}) when called as "
            f"{signature}: it must return a JAX array."
        )
    if not jnp.issubdtype(out.dtype, jnp.floating):
        raise ModelError(
            f"{arg} returned dtype {out.dtype} when called as {signature}: it must return "
            "real floating-point values (do not cast to int, bool or complex)."
        )
    return out


#: types whose values are never (and never contain) a JAX tracer: a warm call passing
#: them skips the PyTree walk (the common case costs a set lookup, not microseconds)
CONCRETE_TYPES = frozenset({float, int, np.ndarray, np.float64})


def reject_tracer(arg: str, value) -> None:
    """A JAX tracer where a concrete value is needed (``dt``, or an initial state given to
    a host-only entry point) is refused by name."""
    if type(value) in CONCRETE_TYPES:
        return
    if isinstance(value, jax.core.Tracer) or any(
        isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(value)
    ):
        raise ModelError(
            f"{arg} is a JAX tracer, but {arg} must be a concrete value: it fixes the "
            "compiled program (dt and steps are not differentiable). dv.simulate itself "
            "may be traced — q0, p0, t0 and the system's parameters can be jit-, grad- and "
            f"vmap-transformed — so pass {arg} as a plain Python number or NumPy array "
            "(close over it instead of passing it through the transformation)."
        )


def check_state(arg: str, value, n: int, coords: Sequence[str]) -> np.ndarray:
    # The common case first: a float64 vector of the right length with a finite x·x
    # (a NaN or an infinity makes it non-finite; a finite vector whose square overflows
    # only sends the call to the full check below, which decides).
    if (
        type(value) is np.ndarray
        and value.dtype == np.float64
        and value.shape == (n,)
        and math.isfinite(value @ value)
    ):
        return value
    reject_tracer(arg, value)
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelError(
            f"{arg}={_short(value)} is not a numeric array: pass {n} numbers, one per "
            f"coordinate {tuple(coords)}."
        ) from exc
    if arr.shape != (n,):
        raise ModelError(
            f"{arg} has shape {arr.shape} but the system has {n} coordinates "
            f"{tuple(coords)}: pass a 1-D array of length {n} in that order."
        )
    if not np.all(np.isfinite(arr)):
        bad = [c for c, x in zip(coords, arr, strict=True) if not math.isfinite(x)]
        raise ModelError(
            f"{arg} is not finite at {bad} (value {_short(arr.tolist())}): initial data "
            "must be finite numbers."
        )
    return arr


def check_positive_float(arg: str, value) -> float:
    if type(value) is float and 0.0 < value < math.inf:  # the common case, as below
        return value
    reject_tracer(arg, value)
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ModelError(f"{arg}={_short(value)} must be a positive real number, e.g. {arg}=0.01.")
    value = float(value)
    if not math.isfinite(value) or value <= 0.0:
        raise ModelError(f"{arg}={value!r} must be a finite number > 0, e.g. {arg}=0.01.")
    return value


def check_float(arg: str, value) -> float:
    """A finite real number (a time, say)."""
    if type(value) is float and math.isfinite(value):  # the common case, as below
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Real | np.ndarray | np.generic):
        raise ModelError(f"{arg}={_short(value)} must be a real number, e.g. {arg}=0.0.")
    try:
        value = float(value)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{arg}={_short(value)} must be a single real number.") from exc
    if not math.isfinite(value):
        raise ModelError(f"{arg}={value!r} must be finite, e.g. {arg}=0.0.")
    return value


def check_positive_int(arg: str, value) -> int:
    if type(value) is int and value > 0:  # the common case, as below (bool is not int)
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or int(value) <= 0:
        raise ModelError(f"{arg}={_short(value)} must be a whole number ≥ 1, e.g. {arg}=1000.")
    return int(value)


def check_choice(arg: str, value, choices: Sequence[str]) -> str:
    if value not in choices:
        raise ModelError(
            f"{arg}={_short(value)} is not one of {tuple(choices)}: pick one of those."
        )
    return value


def check_forms_array(arg: str, value, width: int | None = None, coords=None) -> np.ndarray:
    """A constant one-form matrix: finite float64 of shape (m, width); a row is promoted."""
    try:
        forms = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelError(
            f"{arg}={_short(value)} is neither callable nor a numeric array: pass a function "
            "q -> (m, n) or a constant (m, n) array whose rows are one-forms."
        ) from exc
    if forms.ndim == 1:
        forms = forms[None, :]
    if forms.ndim != 2 or (width is not None and forms.shape[1] != width):
        where = f" but there are {width} coordinates {tuple(coords or ())}" if width else ""
        raise ModelError(
            f"{arg} has shape {forms.shape}{where}: pass an (m, {width or 'n'}) array, one "
            "row per one-form" + (", columns in that order." if width else ".")
        )
    if not np.all(np.isfinite(forms)):
        raise ModelError(f"{arg} contains NaN or Inf: one-forms must be finite.")
    return forms
