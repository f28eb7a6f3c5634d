"""How diracvi's programs are compiled: which of them skip XLA's backend optimization.

The analysis done once per plan (the affinity screen and linearizations, the step
Jacobian of the solvability check, the Legendre data of the initial-data check) is a
program executed once or a few times on tiny inputs. For such a program LLVM's
optimization passes cost far more than they could save, so it is compiled at
optimization level 0, and with XLA's older CPU code generator for fusions
(``xla_cpu_use_fusion_emitters=False``), which compiles diracvi's programs 2–3× faster
than the MLIR-based fusion emitters that are XLA's default (measured: a torn double
pendulum's 1000-step chunk at level 0 in 1.43 → 0.61 s, the torn RLC's in
0.46 → 0.22 s); a jaxlib that no longer knows the option compiles without it.

The variable-step loop of a netlist keeps XLA's default optimization but takes the older
fusion code generator (:func:`loop_options`: half the compilation, the same step speed).
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

import functools

import jax

from .switches import env_switch

#: XLA options of a program that runs once (with :data:`_OLDER_FUSION_CODEGEN` where known)
_LOW_OPTIMIZATION = {
    "xla_backend_optimization_level": 0,
    "xla_llvm_disable_expensive_passes": True,
}
_OLDER_FUSION_CODEGEN = {"xla_cpu_use_fusion_emitters": False}
#: what a run-once program asks for (:func:`run_once_options`: what this jaxlib accepts)
RUN_ONCE_REQUESTED = {**_LOW_OPTIMIZATION, **_OLDER_FUSION_CODEGEN}


@functools.cache
def _older_fusion_known() -> bool:
    """Whether this jaxlib accepts :data:`_OLDER_FUSION_CODEGEN` (probed once per process
    by compiling a one-operation program: an unknown option is an error at compile time)."""
    try:
        jax.jit(lambda x: x + 1.0, compiler_options=_OLDER_FUSION_CODEGEN).lower(0.0).compile()
    except Exception:  # any refusal (an unknown option): compile without it
        return False
    return True


def run_once_options() -> dict:
    """XLA options of a program that runs once: no LLVM optimization, and XLA's older
    fusion code generator if this jaxlib has the option."""
    return {**_LOW_OPTIMIZATION, **(_OLDER_FUSION_CODEGEN if _older_fusion_known() else {})}


#: what a compiled variable-step loop asks for (:func:`loop_options`)
LOOP_REQUESTED = dict(_OLDER_FUSION_CODEGEN)


def loop_options() -> dict:
    """XLA options of the variable-step loop (:mod:`diracvi.driver.adaptive`): XLA's
    default optimization with the older fusion code generator, where known. Measured on
    small decks (a first run, CPU seconds): ng_rc 6.45 → 3.16, liec_halfwave 7.5 → 3.9,
    xy_rlc 6.1 → 3.8 to compile, and the compiled loop as fast within the noise of a
    shared machine (28 against 35 ms, 101 against 85 ms for 236 and 1292 steps); at
    optimization level 0 as well it compiled in 2.7 s but stepped 3× slower."""
    return dict(_OLDER_FUSION_CODEGEN) if _older_fusion_known() else {}


#: set to ``1`` to compile the marching chunks with :func:`run_once_options` as well
FAST_COMPILE_ENV = "DIRACVI_FAST_COMPILE"


def run_once_jit(fn, identity: str | None = None, context=None):
    """``eqx.filter_jit(fn)`` compiled with :func:`run_once_options`, its programs kept in
    the on-disk store (:mod:`diracvi.runtime.store`): a later process loads them untraced.
    ``identity`` names ``fn`` in the key (default: its module and name) and ``context``
    is what it closes over. Nothing is traced or compiled before the first call, so
    importing diracvi neither probes the options nor starts XLA."""
    from .store import StoredJit

    return StoredJit(
        fn,
        identity or f"{fn.__module__}.{fn.__qualname__}",
        run_once_options,
        options_key=RUN_ONCE_REQUESTED,
        context=context,
    )


def stored_chunk_jit(fn, identity: str, context):
    """``jax.jit(fn)`` for a program that marches many steps — XLA's default optimization,
    or :func:`run_once_options` under ``DIRACVI_FAST_COMPILE=1`` (see the module doc) —
    its programs kept in the store under ``identity`` and ``context`` (what ``fn``
    closes over). The setting is read once, so the store's key and the plain path agree.
    Never to be called inside another trace (XLA options of a nested ``jit`` are refused)."""
    from .store import StoredJit

    fast = fast_compile()
    return StoredJit(
        fn,
        identity,
        run_once_options if fast else dict,
        options_key=RUN_ONCE_REQUESTED if fast else {},
        context=context,
        plain=lambda: jax.jit(fn, compiler_options=run_once_options() if fast else None),
    )


def stored_loop_jit(fn, identity: str):
    """``jax.jit(fn)`` compiled with :func:`loop_options` — or :func:`run_once_options`
    under ``DIRACVI_FAST_COMPILE=1``, as the chunks are — its programs kept in the store
    under ``identity``: a program that runs long enough for XLA's optimization to pay
    (the variable-step loop; the operating point's Newton past its first calls)."""
    from .store import StoredJit

    fast = fast_compile()
    return StoredJit(
        fn,
        identity,
        run_once_options if fast else loop_options,
        options_key=RUN_ONCE_REQUESTED if fast else LOOP_REQUESTED,
    )


def fast_compile() -> bool:
    """Whether ``DIRACVI_FAST_COMPILE`` asks for chunks compiled without optimization."""
    return env_switch(
        FAST_COMPILE_ENV,
        on="compile the marching chunks without XLA's backend optimization",
        off="the default",
    )
