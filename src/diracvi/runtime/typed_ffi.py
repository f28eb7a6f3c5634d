"""LAPACK and other FFI custom calls lowered as typed FFI calls (``api_version = 4``).

JAX lowers a typed-FFI custom call (``jax.ffi``: LAPACK's ``lapack_dgetrf_ffi`` of
``lu_factor``, ``lapack_dtrsm_ffi`` of the triangular solves, ``gtsv``, ``gesdd`` …)
with a dictionary of attributes as ``api_version = 1`` and the dictionary in the
unregistered attribute ``mhlo.backend_config`` (``jax._src.interpreters.mlir.custom_call``:
StableHLO's builder took only a string ``backend_config`` when that was written). XLA
is left to read that pair as ``API_VERSION_TYPED_FFI`` when it converts StableHLO to
HLO. In jaxlib 0.10.2 it does not always: with the process restricted to one CPU
(``taskset -c 0``, or ``os.sched_setaffinity``) the marching program of the midpoint
spring chain (Newton with a fresh LAPACK LU per iteration) came out of the conversion
with some functions translated without the MHLO legalization (no canonicalization:
``broadcast`` where the two-CPU run has ``reshape``) and their three LAPACK calls as
untyped custom calls, which the CPU runtime refuses::

    NOT_FOUND: No registered implementation for untyped custom call to
    lapack_dgetrf_ffi for Host

The StableHLO handed to XLA was byte-identical with one and two CPUs, and compiling
that module file alone through the CPU client failed with one CPU and succeeded with
two (``docs/reliability.md``, "2026-12-02: LAPACK calls untyped on one CPU"); small
programs with the same LU inside ``while`` and ``cond`` did not show it.

The workaround states the version in the module itself: every custom call that JAX's
caller asked to lower as ``api_version >= 4`` with a dictionary is rewritten, right
after JAX builds it, to ``api_version = 4`` with the dictionary as its
``backend_config`` (the form StableHLO defines for typed FFI), so no conversion path
has to guess. The HLO that XLA compiles is the same as on two CPUs: the spring chain's
1000 steps came out bit for bit equal with and without the rewrite, and with it the
one-CPU run compiles. :func:`install` wraps JAX's ``custom_call`` builder once per
process; a JAX without that builder, or whose builder already emits the typed form, is
left as it is.
"""

from __future__ import annotations

import functools

#: marks the wrapper, so a second :func:`install` does not wrap it again
_MARK = "_diracvi_typed_ffi"


def _typed(op, api_version, backend_config, i32_attr):
    """Rewrite ``op`` (a ``stablehlo.custom_call`` just built) to the typed-FFI form when
    its caller asked for ``api_version >= 4`` with a dictionary that JAX moved to
    ``mhlo.backend_config`` under ``api_version = 1``."""
    if api_version is None or api_version < 4 or not isinstance(backend_config, dict):
        return op
    attributes = op.operation.attributes
    if "mhlo.backend_config" not in attributes:
        return op  # this JAX emits the typed form itself
    attributes["backend_config"] = attributes["mhlo.backend_config"]
    del attributes["mhlo.backend_config"]
    attributes["api_version"] = i32_attr(4)
    return op


def install() -> bool:
    """Wrap JAX's custom-call builder so typed-FFI calls carry ``api_version = 4``.
    Returns whether the wrapper is in place (False: a JAX without the builder)."""
    try:
        from jax._src.interpreters import mlir
    except ImportError:
        return False
    builder = getattr(mlir, "custom_call", None)
    i32_attr = getattr(mlir, "i32_attr", None)
    if builder is None or i32_attr is None:
        return False
    if getattr(builder, _MARK, False):
        return True

    @functools.wraps(builder)
    def custom_call(*args, **kwargs):
        op = builder(*args, **kwargs)
        return _typed(op, kwargs.get("api_version"), kwargs.get("backend_config"), i32_attr)

    setattr(custom_call, _MARK, True)
    mlir.custom_call = custom_call
    return True


def installed() -> bool:
    """Whether JAX's custom-call builder is the wrapper of :func:`install`."""
    from jax._src.interpreters import mlir

    return bool(getattr(getattr(mlir, "custom_call", None), _MARK, False))
