"""How programs that run once are compiled: without XLA's backend optimization.

The analysis done once per plan (the affinity screen and linearizations, the step
Jacobian of the solvability check, the Legendre data of the initial-data check) is a
program executed once or a few times on tiny inputs. For such a program LLVM's
optimization passes cost far more than they could save, so it is compiled at
optimization level 0. The marching chunks, which run many steps, keep the default.
"""

from __future__ import annotations

import equinox as eqx

#: XLA options of a program that runs once
RUN_ONCE_OPTIONS = {
    "xla_backend_optimization_level": 0,
    "xla_llvm_disable_expensive_passes": True,
}


def run_once_jit(fn):
    """``eqx.filter_jit(fn)`` compiled with :data:`RUN_ONCE_OPTIONS`."""
    return eqx.filter_jit(fn, compiler_options=RUN_ONCE_OPTIONS)
