r"""Compiled programs kept on disk under a key computed before tracing.

JAX's persistent compilation cache (:mod:`diracvi._cache`) saves XLA's compilation, but
it is keyed by the lowered program, so every process still traces and lowers each
program to find its key. For a small torn model that is most of a second process's first
call (the torn double pendulum: about 1 s of tracing and lowering out of 1.3–1.5 s). Here
a program is instead keyed by what it is *made of*, and its compiled executable
(``jax.experimental.serialize_executable``) is kept next to JAX's cache, so a later
process loads it without tracing anything:

    key = sha256(diracvi's source, versions of jax, jaxlib, NumPy and equinox, backend,
                 host CPU, XLA flags, numeric settings of diracvi's modules,
                 compiler options, the function's name, its arguments printed canonically)

The arguments are printed by :func:`canonical`: containers and diracvi's own Modules
field by field (or what their ``__stored__()`` returns), numbers and strings by value,
arrays by shape and dtype (passed to the program as arguments; by value where they are
baked in), a user function as its lifted jaxpr (:class:`~diracvi._program.Program`,
whose key is the printed program), a diracvi function by its qualified name (its code
is in the source hash). Whatever it cannot print faithfully — a user's Python function
kept whole, a class of the user's, a program holding opaque callables, a traced value —
raises :class:`Unstorable`, and that call is traced and compiled as before (JAX's own
cache still applies). The key is thus
sound in the sense that matters: two calls with the same key trace to the same program.

Loading runs a pickle from the cache directory: it is trusted as JAX's cache is (it is
the user's own). The store is bounded (:data:`LIMIT_BYTES`, least recently used first)
and lives in the ``programs`` folder of the active cache directory, so ``diracvi cache
info|clear`` count and clear it too; with the cache off (``DIRACVI_CACHE_DIR=""``) it is
off as well.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import hashlib
import importlib.metadata
import logging
import os
import pickle
import platform
import sys
import time
import types
import weakref
from collections import OrderedDict
from functools import partial
from pathlib import Path

import equinox as eqx
import jax
import numpy as np

from . import _cache
from ._program import Program

log = logging.getLogger(__name__)

#: the store's size bound: least recently used executables are deleted beyond it
LIMIT_BYTES = 2 * 1024**3
#: a temporary file this old is a write that never finished (its process was killed)
STALE_SECONDS = 3600.0
#: compiled programs a StoredJit keeps in memory (by signature, least recently used out)
MEMORY_LIMIT = 256
#: bumped whenever the file format or the key's construction changes
FORMAT = 1
_PACKAGE = __name__.rpartition(".")[0]  # "diracvi"
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
    a = np.asarray(obj)
    weak = "w" if getattr(obj, "weak_type", False) else ""
    text = f"A{weak}{a.dtype.str}{a.shape}"
    if values:
        text += ":" + hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest()
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
    if all(type(item) in _PLAIN for item in obj):  # names, sizes: one repr
        out.append(f"{prefix}{tuple(obj)!r};")
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
    root = Path(__file__).parent
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


def folder() -> Path | None:
    """Where executables are kept, or ``None`` with the cache off."""
    active = _cache.active_dir()
    return None if active is None else active / _cache.PROGRAMS


@functools.cache
def _runtime_ready() -> bool:
    """Prepare what lowering would have prepared before an executable runs: JAX binds
    LAPACK (the CPU's LU, QR, SVD kernels) only when it lowers a program that calls it,
    and a loaded executable that calls an unbound kernel crashes the process. Without a
    known way to bind it, the store stays off."""
    try:
        from jax._src.lax import linalg

        linalg.initialize_lapack()
    except Exception:  # a JAX whose internals moved: trace and compile as before
        log.debug("LAPACK could not be prepared: the program store is off")
        return False
    return True


def enabled() -> bool:
    """Whether calls go through the store (the cache is on, jit is not disabled)."""
    return _cache.active_dir() is not None and not jax.config.jax_disable_jit and _runtime_ready()


def load(key_: str):
    """The stored executable of ``key_`` (a :class:`jax.stages.Compiled`), or ``None``."""
    from jax.experimental import serialize_executable

    where = folder()
    if where is None:
        return None
    path = where / f"{key_}.exe"
    try:
        payload, in_tree, out_tree = pickle.loads(path.read_bytes())
        compiled = serialize_executable.deserialize_and_load(payload, in_tree, out_tree)
    except FileNotFoundError:
        return None
    except Exception as error:  # a damaged or foreign file: compile anew, overwrite it
        log.debug("stored program %s unreadable (%s): compiling", key_, error)
        return None
    try:
        os.utime(path)  # its use, for the least-recently-used bound
    except OSError:
        pass
    log.debug("stored program hit %s", key_)
    return compiled


def save(key_: str, compiled) -> None:
    """Write ``compiled`` under ``key_`` (atomically), then keep the store bounded. A
    program that cannot be serialized or written is simply not stored."""
    from jax.experimental import serialize_executable

    where = folder()
    if where is None:
        return
    try:
        data = pickle.dumps(serialize_executable.serialize(compiled))
        where.mkdir(parents=True, exist_ok=True)
        temporary = where / f".{key_}.{os.getpid()}.tmp"
        temporary.write_bytes(data)
        os.replace(temporary, where / f"{key_}.exe")
    except Exception as error:  # e.g. an output tree that does not pickle, a full disk
        log.debug("program %s not stored (%s)", key_, error)
        return
    log.debug("stored program written %s", key_)
    prune(where, LIMIT_BYTES)


def prune(where: Path, limit: int) -> int:
    """Delete the least recently used executables until the store is within ``limit``
    bytes; returns how many were deleted. Another process may be deleting too: a file
    that is already gone is skipped."""
    for path in where.glob(".*.tmp"):  # a write that a killed process left behind
        try:
            if time.time() - path.stat().st_mtime > STALE_SECONDS:
                path.unlink(missing_ok=True)
        except OSError:
            pass
    entries = []
    for path in where.glob("*.exe"):
        try:
            stat = path.stat()
        except OSError:
            continue
        entries.append((stat.st_mtime, stat.st_size, path))
    total = sum(size for _, size, _ in entries)
    removed = 0
    for _, size, path in sorted(entries, key=lambda e: e[0]):
        if total <= limit:
            break
        path.unlink(missing_ok=True)
        total -= size
        removed += 1
    return removed


class StoredJit:
    """``eqx.filter_jit(fn)`` whose compiled programs are kept in the store.

    Array leaves of the arguments are the program's inputs; every other leaf is static
    (as for ``eqx.filter_jit``). ``identity`` names the function in the key; ``context``
    is whatever else ``fn`` closes over, printed with array values (baked-in constants).
    Within a process, a program is looked up by the arguments' structure, static leaves
    and array shapes (as ``jax.jit`` does); only a new signature prints the key.
    A call that is traced, or whose arguments the key cannot represent, goes to
    ``plain()`` (default ``eqx.filter_jit(fn)``) as before. ``options``: a function
    returning the XLA compiler options (called at the first compilation);
    ``options_key``: what stands for them in the key, if not their value.
    """

    def __init__(self, fn, identity: str, options, *, options_key=None, context=None, plain=None):
        self._fn, self._identity, self._options = fn, identity, options
        self._options_key, self._context = options_key, context
        self._programs: OrderedDict = OrderedDict()  # signature → program (or False)
        # (id of a first argument, shapes of the others) → (its weakref, program, its
        # array leaves): a repeated call on one model skips flattening it
        self._by_object: OrderedDict = OrderedDict()
        self._make_plain = plain or (
            lambda: eqx.filter_jit(self._fn, compiler_options=self._options() or None)
        )
        self._plain = None
        functools.update_wrapper(self, fn)

    def plain(self, *args, **kwargs):
        """The call as it is without the store (made at its first use)."""
        if self._plain is None:
            self._plain = self._make_plain()
        return self._plain(*args, **kwargs)

    def __call__(self, *args, **kwargs):
        program, leaves = self.program(*args, **kwargs)
        if program is None:
            return self.plain(*args, **kwargs)
        return program(*(leaf for leaf in leaves if eqx.is_array(leaf)))

    def program(self, *args, **kwargs):
        """``(compiled, leaves)``: the compiled program of this signature (taking the
        array leaves, in order) and the arguments' leaves; ``(None, leaves)`` when the
        call must go through ``eqx.filter_jit``."""
        fast = _object_key(args, kwargs)
        if fast is not None:  # the same model again, with NumPy arrays of known shapes
            hit = self._by_object.get(fast)
            if hit is not None and hit[0]() is args[0] and enabled():
                return hit[1], [*hit[2], *args[1:]]
        leaves, treedef = jax.tree.flatten((args, kwargs))
        if not enabled() or any(isinstance(leaf, jax.core.Tracer) for leaf in leaves):
            return None, leaves
        signature = (treedef, *(_signature(leaf) for leaf in leaves))
        try:
            program = self._programs.get(signature)
        except TypeError:  # an unhashable static leaf: eqx.filter_jit will say so
            return None, leaves
        if program is None:
            program = self._resolve(args, kwargs, leaves, treedef)
            self._programs[signature] = program
            if len(self._programs) > MEMORY_LIMIT:  # the least recently used goes
                self._programs.popitem(last=False)
        else:
            self._programs.move_to_end(signature)
        if program and fast is not None:
            self._remember(fast, args[0], program)
        return (program or None), leaves

    def _remember(self, fast, first, program) -> None:
        """Keep ``program`` for calls on the object ``first`` (held weakly: a dead
        object's id may be reused) with array leaves taken now: a frozen Module's leaves
        are the same arrays at every call, so only its id needs checking later."""
        try:
            ref = weakref.ref(first)
        except TypeError:
            return
        arrays = [leaf for leaf in jax.tree.leaves(first) if eqx.is_array(leaf)]
        self._by_object[fast] = (ref, program, arrays)
        if len(self._by_object) > MEMORY_LIMIT:
            self._by_object.popitem(last=False)

    def _resolve(self, args, kwargs, leaves, treedef):
        """Load or compile (and store) the program of a new signature; ``False`` if the
        key cannot represent it or tracing fails (``eqx.filter_jit`` then reports)."""
        try:
            arguments = canonical((args, kwargs))
            if self._context is not None:
                arguments += "|" + canonical(self._context, values=True)
        except Unstorable as why:
            log.debug("%s not stored: %s", self._identity, why)
            return False
        # the options as requested: what this jaxlib accepts of them follows from its
        # version (in the key), and asking it would compile a probe
        requested = self._options_key if self._options_key is not None else self._options()
        key_ = key(self._identity, arguments, requested)
        compiled = load(key_)
        if compiled is not None:
            return compiled
        options = self._options()
        dynamic = [i for i, leaf in enumerate(leaves) if eqx.is_array(leaf)]

        def on_arrays(*arrays):
            full = list(leaves)
            for i, array in zip(dynamic, arrays, strict=True):
                full[i] = array
            a, k = jax.tree.unflatten(treedef, full)
            return self._fn(*a, **k)

        # named after the function: JAX's logs and profiles show it so
        on_arrays.__name__ = on_arrays.__qualname__ = getattr(self._fn, "__name__", "program")
        try:
            lowered = jax.jit(on_arrays, compiler_options=options or None).lower(
                *(leaves[i] for i in dynamic)
            )
        except Exception:  # the model's own error: raised again by the plain path
            return False
        compiled, fresh = compile_fresh(lowered)
        if fresh:
            save(key_, compiled)
        return compiled


#: JAX's persistent-cache hits so far in this process (see compile_fresh)
_JAX_CACHE_HITS = [0]
_LISTENING = [False]


def _count_hit(event: str, **_) -> None:
    if event == "/jax/compilation_cache/cache_hits":
        _JAX_CACHE_HITS[0] += 1


def compile_fresh(lowered):
    """``(compiled, fresh)``: ``lowered`` compiled by XLA itself, not read from JAX's
    persistent cache, and whether that held.

    An executable that JAX read from its cache serializes without the code of some of its
    functions (measured with jaxlib 0.10: loading it again fails with "Function
    compare_reduce_fusion not found"), so only a freshly compiled one may be stored. JAX's
    cache is therefore bypassed while the store compiles — the store keeps the program
    from then on — through JAX's internal switch; where that switch is missing, a cache
    hit (counted through ``jax.monitoring``) makes ``fresh`` false and the program is
    not stored."""
    if not _LISTENING[0]:
        jax.monitoring.register_event_listener(_count_hit)
        _LISTENING[0] = True
    hits = _JAX_CACHE_HITS[0]
    try:
        from jax._src import compilation_cache

        compilation_cache.is_cache_used(jax.devices()[0].client)  # settles its memo
        saved = compilation_cache._cache_used
    except Exception:  # JAX's internals moved: compile through the cache, check hits
        compiled = lowered.compile()
    else:
        compilation_cache._cache_used = False
        try:
            compiled = lowered.compile()
        finally:
            compilation_cache._cache_used = saved
    return compiled, _JAX_CACHE_HITS[0] == hits


def _object_key(args, kwargs):
    """The key of a call ``f(model, *arrays)`` with NumPy arrays only after the model, or
    ``None`` for any other call (which is looked up by its full signature)."""
    if kwargs or not args or eqx.is_array(args[0]):
        return None
    rest = args[1:]
    if not all(isinstance(a, np.ndarray | np.generic) for a in rest):
        return None
    return (id(args[0]), *((a.shape, a.dtype.str) for a in rest))


def _signature(leaf):
    if eqx.is_array(leaf):
        return (np.shape(leaf), leaf.dtype, getattr(leaf, "weak_type", False))
    return leaf
