"""CPU programs run on the calling thread (JAX's synchronous CPU dispatch).

By default JAX hands every CPU program to a worker thread of its CPU client and returns
at once (asynchronous dispatch), so Python can go on while the program runs. diracvi
reads every result right away (``simulate`` returns NumPy arrays), so nothing overlaps:
each call pays the hand-off to the worker thread and the wake-up of the waiting one. On
a virtual machine, where waking an idle virtual CPU goes through the hypervisor, that
hand-off costs more than the program itself: the paper's 1000-step spring chain program
took 156–230 µs per call with asynchronous dispatch and 83–106 µs on the calling thread
on this project's 2-core CI machine (``benchmarks/chunk_program.py``; round 6 of
``benchmarks/README.md``). Asynchronous, but with the process pinned to one CPU
(``taskset -c 0``), it took 105–114 µs: the cost is the hand-off between CPUs, not the
program.

So importing diracvi switches JAX's ``jax_cpu_enable_async_dispatch`` off, as it switches
float64 on. It is a process-wide setting that JAX reads once, when it creates its CPU
client; a process that ran a JAX computation before importing diracvi keeps the
asynchronous default (:func:`synchronous` says which is in force). Set
``DIRACVI_CPU_ASYNC_DISPATCH=1`` to keep JAX's asynchronous default, e.g. for a program
of your own that overlaps host work with long CPU computations. GPU and TPU dispatch
are not affected.
"""

from __future__ import annotations

import jax

from .switches import env_switch

#: ``1`` keeps JAX's asynchronous CPU dispatch; unset or ``0``: programs run on the caller
ASYNC_ENV = "DIRACVI_CPU_ASYNC_DISPATCH"
_OPTION = "jax_cpu_enable_async_dispatch"


def keep_async() -> bool:
    """Whether :data:`ASYNC_ENV` asks for JAX's asynchronous CPU dispatch."""
    return env_switch(
        ASYNC_ENV,
        on="keep JAX's asynchronous CPU dispatch",
        off="run diracvi's CPU programs on the calling thread, the default",
    )


#: the option's value when diracvi was imported, if JAX's CPU client existed already then
#: (it was created with that value; changing the option later does not reach it)
_ASYNC_AT_IMPORT: bool | None = None


def _option():
    """JAX's flag object for the option (None in a JAX without it)."""
    from jax._src import xla_bridge

    return getattr(xla_bridge, "_CPU_ENABLE_ASYNC_DISPATCH", None)


def configure() -> None:
    """Switch asynchronous CPU dispatch off unless :data:`ASYNC_ENV` keeps it. A JAX
    without the option (renamed or removed) is left as it is."""
    global _ASYNC_AT_IMPORT
    from jax._src import xla_bridge

    flag = _option()
    if flag is None:
        return
    initialized = getattr(xla_bridge, "backends_are_initialized", None)
    if initialized is not None and initialized():
        _ASYNC_AT_IMPORT = bool(flag.value)
    if not keep_async():
        jax.config.update(_OPTION, False)


def synchronous() -> bool | None:
    """Whether this process's CPU programs run on the calling thread (None: a JAX
    without the option). Read from the option, or from its value at import when JAX's
    CPU client existed before diracvi was imported."""
    flag = _option()
    if flag is None:
        return None
    if _ASYNC_AT_IMPORT is not None:
        return not _ASYNC_AT_IMPORT
    return not flag.value


def mode() -> str:
    """``"synchronous"``, ``"asynchronous"`` or ``"unknown"``: :func:`synchronous` as the
    benchmark and reproduction reports print it beside their timings."""
    return {True: "synchronous", False: "asynchronous", None: "unknown"}[synchronous()]


configure()
