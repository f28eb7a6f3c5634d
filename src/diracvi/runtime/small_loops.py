"""Small loops compiled as one kernel: XLA's CPU ``small while loop`` threshold raised.

XLA's CPU runtime runs a program as *thunks* — a fused kernel, a copy, a LAPACK call, a
``while`` whose body is a thunk sequence of its own — dispatched one by one, each pass of
a body allocating its executor state and scheduling by a dependency graph. For the
variable-step loop of a small circuit that dispatch is the cost, not the arithmetic:
≈ 550 thunks a try on the bridge rectifier at ≈ 125 ns each (``docs/performance.md``,
"Counting thunks"). But a ``while`` loop whose body accesses fewer bytes than the backend
option ``xla_cpu_small_while_loop_byte_threshold`` (1024 by default) and holds no custom
call is compiled differently (``small_while_loop_hoisting_pass``): as one ``call`` emitted
by XLA's older IR emitter into straight machine code, the whole loop one thunk. The
option is a backend "extra option" that a compile call cannot set (JAX's
``compiler_options`` cannot fill the map it lives in), only the ``XLA_FLAGS`` the process
starts XLA with: ``--xla_backend_extra_options=xla_cpu_small_while_loop_byte_threshold=N``.

So importing diracvi adds that flag with :data:`THRESHOLD` to ``XLA_FLAGS``, as it switches
float64 on and dispatch to the calling thread (:mod:`.dispatch`). The dense Newton of a
small model factors its Jacobian in plain operations for this
(:mod:`diracvi.solvers.small_lu`: LAPACK's ``getrf``/``trsm`` are custom calls), and the
bridge rectifier's whole variable-step loop then runs as one kernel: 0.23 → 0.07 CPU s a
warm call, at the price of a longer first compilation (5.1 → 9–10 CPU s; ``docs/performance.md``,
"The loop as one kernel"). It is process-wide, and XLA reads ``XLA_FLAGS`` once,
when the process's first computation starts it: a process that ran a JAX computation before
importing diracvi, or whose ``XLA_FLAGS`` already set ``xla_backend_extra_options``, keeps
what it had (:func:`in_force` says which). ``DIRACVI_SMALL_LOOPS=0`` leaves ``XLA_FLAGS``
alone. Programs compiled either way are stored apart: ``XLA_FLAGS`` is part of every stored
program's key (:mod:`.fingerprint`).
"""

from __future__ import annotations

import os

from .switches import env_switch

#: ``0`` leaves ``XLA_FLAGS`` as it is; unset or ``1``: the small-loop threshold is raised
ENV = "DIRACVI_SMALL_LOOPS"
_KEY = "xla_cpu_small_while_loop_byte_threshold"
#: bytes a loop body may access (one pass, XLA's cost analysis) and still be one kernel:
#: the bridge rectifier's variable-step loop (12 coordinates) needs between 1e5 and 1e6;
#: a loop holding a LAPACK call (a model over ``small_lu.SMALL`` unknowns) never is one
THRESHOLD = 1 << 22
_FLAG = f"--xla_backend_extra_options={_KEY}={THRESHOLD}"

#: whether this import added the flag (None: not yet configured)
_ADDED: bool | None = None


def _wanted() -> bool:
    return env_switch(
        ENV,
        on="compile small loops as one kernel, the default",
        off="leave XLA_FLAGS as it is",
        default=True,
    )


def _backends_started() -> bool:
    from jax._src import xla_bridge

    started = getattr(xla_bridge, "backends_are_initialized", None)
    return bool(started is not None and started())


def configure() -> None:
    """Add the threshold's flag to ``XLA_FLAGS`` unless :data:`ENV` is ``0``, XLA has
    started already, or ``XLA_FLAGS`` sets backend extra options of its own."""
    global _ADDED
    flags = os.environ.get("XLA_FLAGS", "")
    if not _wanted() or _backends_started() or "xla_backend_extra_options" in flags:
        _ADDED = False
        return
    os.environ["XLA_FLAGS"] = f"{flags} {_FLAG}".strip()
    _ADDED = True


def in_force() -> bool:
    """Whether this process's XLA compiles loops up to :data:`THRESHOLD` bytes as one
    kernel: the flag added at import, or already in ``XLA_FLAGS`` with this threshold."""
    return bool(_ADDED) or f"{_KEY}={THRESHOLD}" in os.environ.get("XLA_FLAGS", "")


configure()
