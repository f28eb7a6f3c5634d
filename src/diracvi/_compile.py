"""How diracvi's programs are compiled: which of them skip XLA's backend optimization.

The analysis done once per plan (the affinity screen and linearizations, the step
Jacobian of the solvability check, the Legendre data of the initial-data check) is a
program executed once or a few times on tiny inputs. For such a program LLVM's
optimization passes cost far more than they could save, so it is compiled at
optimization level 0.

The marching chunks, which run many steps, keep the default, unless
``DIRACVI_FAST_COMPILE=1`` is set: then they are compiled like the run-once programs.
The program (its HLO) is the same; only the machine code is less optimized. Measured on
the torn RLC circuit and the torn double pendulum (``docs/performance.md``), this
halves the compilation of a chunk (2.6 → 1.3 s, 5.9 → 3.7 s) and makes a step up to
about 2× slower, so it pays for short runs of many different models — a test suite, a
first look at a model — and not for long or repeated runs (the on-disk cache then
keeps the slower program for later processes too; it is keyed by the options, so the
two kinds never mix).
"""

from __future__ import annotations

import os

import equinox as eqx
import jax

#: XLA options of a program that runs once
RUN_ONCE_OPTIONS = {
    "xla_backend_optimization_level": 0,
    "xla_llvm_disable_expensive_passes": True,
}

#: set to ``1`` to compile the marching chunks with :data:`RUN_ONCE_OPTIONS` as well
FAST_COMPILE_ENV = "DIRACVI_FAST_COMPILE"


def run_once_jit(fn):
    """``eqx.filter_jit(fn)`` compiled with :data:`RUN_ONCE_OPTIONS`."""
    return eqx.filter_jit(fn, compiler_options=RUN_ONCE_OPTIONS)


def fast_compile() -> bool:
    """Whether ``DIRACVI_FAST_COMPILE`` asks for chunks compiled without optimization."""
    value = os.environ.get(FAST_COMPILE_ENV, "").strip()
    if value in ("", "0"):
        return False
    if value == "1":
        return True
    raise ValueError(
        f"{FAST_COMPILE_ENV}={value!r} is not understood. Fix: set it to 1 (compile the "
        "marching chunks without XLA's backend optimization) or 0 / unset (the default)."
    )


def chunk_jit(fn):
    """``jax.jit(fn)`` for a program that marches many steps: XLA's default optimization,
    or :data:`RUN_ONCE_OPTIONS` under ``DIRACVI_FAST_COMPILE=1`` (see the module doc).
    Like :func:`run_once_jit`, never to be called inside another trace (XLA options of a
    nested ``jit`` are refused)."""
    if fast_compile():
        return jax.jit(fn, compiler_options=RUN_ONCE_OPTIONS)
    return jax.jit(fn)
