r"""Compiled programs kept on disk under a key computed before tracing.

JAX's persistent compilation cache (:mod:`diracvi.runtime.cache`) saves XLA's compilation, but
it is keyed by the lowered program, so every process still traces and lowers each
program to find its key. For a small torn model that is most of a second process's first
call (the torn double pendulum: about 1 s of tracing and lowering out of 1.3–1.5 s). Here
a program is instead keyed by what it is *made of* (:mod:`diracvi.runtime.fingerprint`), and
its compiled executable (``jax.experimental.serialize_executable``) is kept next to
JAX's cache, so a later process loads it without tracing anything. A call whose
arguments the key cannot represent (:class:`~diracvi.runtime.fingerprint.Unstorable`) is
traced and compiled as before, and JAX's own cache still applies to it.

Loading runs a pickle from the cache directory: it is trusted as JAX's cache is (it is
the user's own). The store is bounded (:data:`LIMIT_BYTES`, least recently used first)
and lives in the ``programs`` folder of the active cache directory, so ``diracvi cache
info|clear`` count and clear it too; with the cache off (``DIRACVI_CACHE_DIR=""``) it is
off as well.
"""

from __future__ import annotations

import functools
import logging
import os
import pickle
import time
import weakref
from collections import OrderedDict
from pathlib import Path

import equinox as eqx
import jax
import numpy as np

from . import cache as _cache
from . import mappings as _mappings
from .fingerprint import Unstorable, canonical, key

log = logging.getLogger(__name__)

#: the store's size bound: least recently used executables are deleted beyond it
LIMIT_BYTES = 2 * 1024**3
#: a temporary file this old is a write that never finished (its process was killed)
STALE_SECONDS = 3600.0
#: compiled programs a StoredJit keeps in memory (by signature, least recently used out)
MEMORY_LIMIT = 256

#: key → executable already loaded or compiled in this process (least recently used out,
#: beyond MEMORY_LIMIT). A model read again from the same netlist is a new object with
#: new StoredJits, but its programs have the same keys: without this each was loaded from
#: disk again, ≈ 0.1 s a program (the bridge rectifier's four: a warm `spice.run` of a
#: fresh `spice.read` 0.24 CPU s against 0.062 on the deck read once).
_LOADED: OrderedDict = OrderedDict()
#: every StoredJit alive, so that :func:`_drop_programs` reaches the programs each holds
_INSTANCES: weakref.WeakSet = weakref.WeakSet()


def _recall(key_: str):
    """The executable of ``key_`` this process already holds, or ``None``."""
    try:  # (threads of a sweep may evict it between the two: then it is not here)
        compiled = _LOADED[key_]
        _LOADED.move_to_end(key_)
    except KeyError:
        return None
    return compiled


def _keep(key_: str, compiled) -> None:
    try:
        _LOADED[key_] = compiled
        _LOADED.move_to_end(key_)
        while len(_LOADED) > MEMORY_LIMIT:
            _LOADED.popitem(last=False)
    except KeyError:  # another thread evicted it first
        pass


def _drop_programs() -> None:
    """Forget every executable this process holds (they are loaded or compiled again when
    next called): the memory mappings' relief (:mod:`diracvi.runtime.mappings`)."""
    _LOADED.clear()
    for stored in list(_INSTANCES):
        stored._programs.clear()
        stored._by_object.clear()


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
        self._make_plain = plain or self._filter_jit
        self._plain = None
        functools.update_wrapper(self, fn)
        _INSTANCES.add(self)

    def _filter_jit(self):
        """``eqx.filter_jit(fn)`` with the options; inside another trace (a part's
        parameter traced in a closure, which the arguments do not show: a netlist read in a
        traced fit) without them — JAX refuses XLA options on a nested ``jit``, and the
        enclosing program's own apply there."""
        with_options = eqx.filter_jit(self._fn, compiler_options=self._options() or None)
        nested = eqx.filter_jit(self._fn)

        def call(*args, **kwargs):
            try:
                return with_options(*args, **kwargs)
            except ValueError as err:
                if "compiler_options" not in str(err):
                    raise
                return nested(*args, **kwargs)

        return call

    def plain(self, *args, **kwargs):
        """The call as it is without the store (made at its first use)."""
        if self._plain is None:
            # a model's first plain call compiles (the store off, an unstorable call): its
            # executables will take mappings too (not inside another trace: JAX's caches
            # are in use there)
            if not any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((args, kwargs))):
                _mappings.relieve(_drop_programs)
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
            try:
                self._programs.move_to_end(signature)
            except KeyError:  # dropped by another thread's relief meanwhile
                pass
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

    def _key(self, args, kwargs):
        """The store's key of a call, or ``None`` where the key cannot represent it."""
        try:
            arguments = canonical((args, kwargs))
            if self._context is not None:
                arguments += "|" + canonical(self._context, values=True)
        except Unstorable as why:
            log.debug("%s not stored: %s", self._identity, why)
            return None
        # the options as requested: what this jaxlib accepts of them follows from its
        # version (in the key), and asking it would compile a probe
        requested = self._options_key if self._options_key is not None else self._options()
        return key(self._identity, arguments, requested)

    def _resolve(self, args, kwargs, leaves, treedef):
        """Load or compile (and store) the program of a new signature; ``False`` if the
        key cannot represent it or tracing fails (``eqx.filter_jit`` then reports)."""
        key_ = self._key(args, kwargs)
        if key_ is None:
            return False
        compiled = _recall(key_)
        if compiled is None:
            # a new executable is about to take its mappings: make room first
            _mappings.relieve(_drop_programs)
            compiled = load(key_)
        if compiled is not None:
            _keep(key_, compiled)
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
        _keep(key_, compiled)
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
