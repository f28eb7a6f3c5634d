"""The paper's timing protocol: the minimum wall time over many runs of a whole simulation.

What one "run" is, exactly: a warm call ``dv.simulate(system, q0, p0, dt=..., steps=...)``
end to end — argument checks, the first-step solvability check (a compiled Jacobian and
its SVD), the compiled ``lax.scan`` over every step, copying the results to NumPy and
building the :class:`~diracvi.Trajectory`. "Warm" means the system was simulated once
before timing, so JIT compilation is excluded (as Matlab's is in the paper). Like
:mod:`timeit`, the garbage collector is paused while timing; the minimum is reported
because it is the least disturbed by the rest of the machine.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable

import numpy as np

from .._simulate import simulate

TIMING_PROTOCOL = (
    "min over N runs of a warm (already compiled) dv.simulate(system, q0, p0, dt, steps) "
    "call, end to end: argument checks, first-step solvability check, the compiled "
    "lax.scan over all steps, transfer to NumPy and Trajectory construction; garbage "
    "collector paused (as timeit does); time.perf_counter."
)


def time_calls(fn: Callable[[], object], repeats: int, tick: Callable[[], None] | None = None):
    """Wall times of ``repeats`` calls of ``fn`` after one untimed warm-up call (seconds)."""
    fn()
    times = np.empty(repeats)
    enabled = gc.isenabled()
    gc.disable()
    try:
        for i in range(repeats):
            start = time.perf_counter()
            fn()
            times[i] = time.perf_counter() - start
            if tick is not None:
                tick()
    finally:
        if enabled:
            gc.enable()
    return times


def time_simulation(system, q0, p0, *, dt, steps, repeats, tick=None) -> dict[str, float]:
    """``{min_s, median_s, repeats}`` for a full ``simulate`` of ``system`` (see module doc)."""
    times = time_calls(lambda: simulate(system, q0, p0, dt=dt, steps=steps), repeats, tick=tick)
    return {"min_s": float(times.min()), "median_s": float(np.median(times)), "repeats": repeats}
