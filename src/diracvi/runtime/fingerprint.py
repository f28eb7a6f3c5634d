r"""What a compiled program is made of, printed before it is traced: the program store's key.

    key = sha256(diracvi's source, versions of jax, jaxlib, NumPy and equinox, backend,
                 host CPU, XLA flags, numeric settings of diracvi's modules,
                 compiler options, the function's name, its arguments printed canonically)

The arguments are printed by :func:`canonical`: containers and diracvi's own Modules
field by field (or what their ``__stored__()`` returns), numbers and strings by value,
arrays by shape and dtype (passed to the program as arguments; by value where they are
baked in), a user function as its lifted jaxpr (:class:`~diracvi.runtime.program.Program`,
whose key is the printed program), a diracvi function by its qualified name (its code
is in the source hash). Whatever it cannot print faithfully — a user's Python function
kept whole, a class of the user's, a program holding opaque callables, a traced value —
raises :class:`Unstorable`. The key is sound in the sense that matters: two calls with
the same key trace to the same program (:mod:`diracvi.runtime.store` keeps their executables).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import hashlib
import importlib.metadata
import itertools
import os
import platform
import sys
import types
from functools import partial
from pathlib import Path

import equinox as eqx
import jax
import numpy as np

from .program import Program

FORMAT = 1
_PACKAGE = __name__.split(".")[0]  # "diracvi"
#: libraries whose functions may appear in a key by name (their versions are in it)
_LIBRARIES = ("jax", "jaxlib", "numpy", "equinox", "optimistix", "lineax", "builtins", "math")


#: types whose repr is their value (a tuple of them is printed in one go)
_PLAIN = frozenset({str, int, float, bool, type(None)})


class Unstorable(Exception):
    """An argument the key cannot represent faithfully (the call compiles as before)."""


def _ours(module: str | None) -> bool:
    return module is not None and (module == _PACKAGE or module.startswith(_PACKAGE + "."))


def _library(module: str | None) -> bool:
    return module is not None and module.split(".")[0] in _LIBRARIES


def _named(obj) -> str:
    """A function or class that is what its qualified name says (no closure, no locals)."""
    module, name = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
    if name is None or "<" in name or not (_ours(module) or _library(module)):
        # "<locals>", "<lambda>": the name does not say which function it is
        raise Unstorable(f"{obj!r} is not a function of diracvi or of a library")
    if getattr(obj, "__closure__", None):
        raise Unstorable(f"{module}.{name} has a closure")
    return f"{module}.{name}"


def _array(obj, values: bool) -> str:
    if isinstance(obj, jax.core.Tracer):
        raise Unstorable("a traced value")
    weak = "w" if getattr(obj, "weak_type", False) else ""
    text = f"A{weak}{np.dtype(obj.dtype).str}{tuple(obj.shape)}"
    if values:  # (only then a copy to the host)
        text += ":" + hashlib.sha256(np.ascontiguousarray(obj).tobytes()).hexdigest()
    return text


def canonical(obj, *, values: bool = False) -> str:
    """A text that determines ``obj`` as far as a traced program can see it (arrays by
    shape and dtype, by value as well if ``values``); :class:`Unstorable` if there is
    something it cannot represent."""
    out: list[str] = []
    _canon(obj, values, out)
    return "".join(out)


def _canon(obj, values: bool, out: list) -> None:
    # one handler per type, chosen once: a large model has 10⁵ nodes to print
    kind = type(obj)
    handler = _HANDLERS.get(kind)
    if handler is None:
        handler = _HANDLERS[kind] = _handler(obj)
    handler(obj, values, out)


def _handler(obj):
    """The printer of objects of ``type(obj)`` (the checks depend only on the type)."""
    kind = type(obj)
    if _ours(kind.__module__) and hasattr(kind, "__stored__"):  # prints a stand-in
        return lambda a, values, out: _canon(a.__stored__(), values, out)
    if eqx.is_array(obj):  # before the scalars: a NumPy scalar is an array here
        return lambda a, values, out: out.append(_array(a, values) + ";")
    if kind in _PLAIN or isinstance(obj, bool | int | float | complex | str | bytes):
        return lambda a, values, out: out.append(f"{type(a).__name__}:{a!r};")
    if isinstance(obj, Program):
        return _program
    if isinstance(obj, tuple | list):
        # a NamedTuple or StaticTuple: its class first
        prefix = "" if kind in (tuple, list) else _named(kind)
        return partial(_sequence, prefix + kind.__name__)
    if isinstance(obj, dict):
        return _mapping
    if isinstance(obj, enum.Enum):
        return lambda a, values, out: out.append(f"{_named(type(a))}.{a.name};")
    if isinstance(obj, np.dtype):
        return lambda a, values, out: out.append(f"dtype:{a.str};")
    if isinstance(obj, jax.ShapeDtypeStruct):
        return _spec
    if isinstance(obj, functools.partial):
        return _partial
    if isinstance(obj, types.MethodType):
        return _method
    if isinstance(obj, type) or (callable(obj) and not dataclasses.is_dataclass(obj)):
        return lambda a, values, out: out.append(_named(a) + ";")
    if dataclasses.is_dataclass(obj) and _ours(kind.__module__):
        # diracvi's Modules and dataclasses: their class (its code is in the source
        # hash), then every field in declaration order; a static field is part of the
        # program, so an array in one is printed by value
        fields = tuple(
            (f.name, bool(f.metadata.get("static", False))) for f in dataclasses.fields(obj)
        )
        return partial(_fields, _named(kind), fields)
    return _refuse


def _program(obj, values, out):
    if obj.keep:  # opaque callables print by name only: not a faithful key
        raise Unstorable(f"{obj!r} holds opaque callables")
    digest = hashlib.sha256(obj.key.encode()).hexdigest()
    out.append(f"P{digest}{obj.arg_shapes};")


def _sequence(prefix, obj, values, out):
    kinds = set(map(type, obj))  # (C loops: a large model's tables have 10⁵ entries)
    if kinds <= _PLAIN:  # names, sizes: one repr
        out.append(f"{prefix}{tuple(obj)!r};")
        return
    if kinds == {tuple} and set(map(type, itertools.chain.from_iterable(obj))) <= _PLAIN:
        # a table of plain tuples (rows per subsystem): one repr, which is faithful for
        # these types and tells the nesting apart from the case above by its brackets
        out.append(f"{prefix}T{tuple(obj)!r};")
        return
    out.append(prefix + "(")
    for item in obj:
        _canon(item, values, out)
    out.append(")")


def _mapping(obj, values, out):
    out.append("{")
    for key in sorted(obj, key=repr):
        _canon(key, values, out)
        _canon(obj[key], values, out)
    out.append("}")


def _spec(obj, values, out):
    if obj.sharding is not None:
        raise Unstorable("a ShapeDtypeStruct with a sharding")
    out.append(f"S{np.dtype(obj.dtype).str}{obj.shape}{obj.weak_type};")


def _partial(obj, values, out):
    out.append("partial(")
    _canon(obj.func, values, out)
    _canon(obj.args, values, out)
    _canon(obj.keywords, values, out)
    out.append(")")


def _method(obj, values, out):
    out.append("method(")
    _canon(obj.__self__, values, out)
    out.append(_named(obj.__func__) + ")")


def _fields(prefix, fields, obj, values, out):
    out.append(prefix + "(")
    stored = vars(obj)
    for name, static in fields:
        out.append(name + "=")
        value = stored[name] if name in stored else getattr(obj, name)
        _canon(value, values or static, out)
    out.append(")")


def _refuse(obj, values, out):
    raise Unstorable(f"an object of type {type(obj).__qualname__}")


#: printers by type (see _handler)
_HANDLERS: dict = {}


def _source_digest() -> str:
    """sha256 of every Python file of the diracvi package (path and content)."""
    root = Path(__file__).parent.parent  # the package, not this subpackage
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _host() -> str:
    """The CPU an executable was compiled for (its features decide the machine code)."""
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return f"{platform.machine()} {platform.processor()}"
    lines = [line for line in text.splitlines() if line.startswith(("model name", "flags"))]
    return platform.machine() + " " + " ".join(sorted(set(lines)))


def _version(distribution: str) -> str:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return "absent"


@functools.cache
def _environment() -> str:
    """The parts of the key that cannot change within a process."""
    import jaxlib

    device = jax.devices()[0]
    return "|".join(
        [
            f"format {FORMAT}",
            _source_digest(),
            f"python {sys.version_info[:2]}",
            f"jax {jax.__version__} jaxlib {jaxlib.__version__} numpy {np.__version__}",
            # what traces diracvi's programs besides JAX (equinox's partition, for one)
            " ".join(f"{name} {_version(name)}" for name in ("equinox", "optimistix", "lineax")),
            f"{device.platform} {device.device_kind} {device.client.platform_version}",
            hashlib.sha256(_host().encode()).hexdigest(),
            os.environ.get("XLA_FLAGS", ""),
        ]
    )


#: JAX settings that change what a program traces or lowers to
_JAX_SETTINGS = (
    "jax_enable_x64",
    "jax_default_matmul_precision",
    "jax_numpy_rank_promotion",
    "jax_numpy_dtype_promotion",
    "jax_debug_nans",
    "jax_debug_infs",
    "jax_default_prng_impl",
)


def _settings() -> str:
    """Settings that may change while a process runs: JAX's, and the numbers and strings
    at the top level of diracvi's modules (tuning constants a caller may set)."""
    parts = [f"{name}={getattr(jax.config, name, None)!r}" for name in _JAX_SETTINGS]
    for name, module in sorted(sys.modules.items()):
        if not _ours(name) or module is None:
            continue
        for attr, value in sorted(vars(module).items()):
            if not attr.startswith("__") and isinstance(value, bool | int | float | str):
                parts.append(f"{name}.{attr}={value!r}")
    return "\n".join(parts)


def key(identity: str, arguments: str, options: dict) -> str:
    """The store's key of a program (hex sha256)."""
    text = "\n".join(
        [_environment(), _settings(), repr(sorted(options.items())), identity, arguments]
    )
    return hashlib.sha256(text.encode()).hexdigest()
