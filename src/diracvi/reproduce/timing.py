"""The paper's timing protocol: the minimum wall time over many runs of a whole simulation.

What one "run" is, exactly: a warm call ``dv.simulate(system, q0, p0, dt=..., steps=...)``
end to end — argument checks, the first-step solvability check (a compiled Jacobian and
its SVD), the compiled ``lax.scan`` over every step, copying the results to NumPy and
building the :class:`~diracvi.Trajectory`. "Warm" means the system was simulated once
before timing, so JIT compilation is excluded (as Matlab's is in the paper). Like
:mod:`timeit`, the garbage collector is paused while timing; the minimum is reported
because it is the least disturbed by the rest of the machine.

Models that are compared (torn ÷ hand-built) are timed *interleaved*: round ``i`` runs
each model once, starting from model ``i mod k``, so a burst of load from another
process falls on all of them alike instead of on whichever block ran at the time.
"""

from __future__ import annotations

import gc
import time

import numpy as np

from ..driver.simulate import simulate

TIMING_PROTOCOL = (
    "min over N runs of a warm (already compiled) dv.simulate(system, q0, p0, dt, steps) "
    "call, end to end: argument checks, first-step solvability check, the compiled "
    "lax.scan over all steps, transfer to NumPy and Trajectory construction; the models "
    "compared are timed interleaved (one run of each per round, the first one rotating); "
    "garbage collector paused (as timeit does); time.perf_counter."
)


def time_simulations(models: dict, *, dt, steps, repeats, tick=None) -> dict[str, dict]:
    """``{label: {min_s, median_s, repeats}}`` for ``models = {label: (system, q0, p0)}``,
    timed interleaved (see module doc); ``tick`` is called after every round."""
    labels = list(models)
    calls = {
        label: (lambda s=s, q=q, p=p: simulate(s, q, p, dt=dt, steps=steps))
        for label, (s, q, p) in models.items()
    }
    for label in labels:
        calls[label]()
    times = {label: np.empty(repeats) for label in labels}
    enabled = gc.isenabled()
    gc.disable()
    try:
        for i in range(repeats):
            first = i % len(labels)
            for label in labels[first:] + labels[:first]:
                start = time.perf_counter()
                calls[label]()
                times[label][i] = time.perf_counter() - start
            if tick is not None:
                tick()
    finally:
        if enabled:
            gc.enable()
    return {
        label: {"min_s": float(t.min()), "median_s": float(np.median(t)), "repeats": repeats}
        for label, t in times.items()
    }
