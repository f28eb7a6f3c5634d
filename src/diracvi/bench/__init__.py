"""Benchmarks of diracvi against the paper's method and standard tools: ``diracvi bench``.

    diracvi bench [--quick] [--only NAME]... [--json PATH] [--repeats N]

or, from Python, ``report = diracvi.bench.run(Settings(quick=True))``. Every benchmark is
one module exposing ``NAME``, ``DESCRIPTION`` and ``run(settings) -> Result``:

- :mod:`.spring_chain`, :mod:`.rlc` — the paper's §5 examples: diracvi against a NumPy
  per-step dense solve of the same equations, and torn ÷ monolithic (paper's protocol);
- :mod:`.chain_scaling` — a torn N-mass chain, time per step against N and against a
  streaming-memory kernel;
- :mod:`.pendulum` — torn double pendulum against DOP853 at matched accuracy;
- :mod:`.ensemble` — many initial conditions in one call against a Python loop;
- :mod:`.sweep` — 10⁴ RLC circuits over an R × C grid: a loop of ``simulate`` against
  ``dv.sweep`` embedded and on a 2-worker Dask ``LocalCluster``;
- :mod:`.gradients` — gradient ÷ forward cost and reverse-mode memory of traced runs;
- :mod:`.compile_latency` — first-call latency of every built-in problem;
- :mod:`.first_call` — cold first call of mechanisms (four-bar, torn double pendulum,
  Andrews' squeezer) against a jit right-hand side + DOP853, fresh processes;
- :mod:`.cache` — first call in a second process (on-disk compilation cache) ÷ cold;
- :mod:`.closure_chain` — a torn chain of loop-built closures ÷ the same of shared code;
- :mod:`.driven` — a driven RLC circuit on the affine fast path against its autonomous twin;
- :mod:`.work_precision` — error against run time on the spherical pendulum, the double
  pendulum and a four-bar linkage: midpoint and lobatto (orders 2, 4) beside DOP853 on
  the reduced ODE;
- :mod:`.circuits` — SPICE netlists against ngspice at matched accuracy, and the energy
  drift of a lossless LC tank over 10⁶ steps (midpoint against trapezoidal and Gear).

How timings are taken is in :mod:`._core`; method and results are in
``benchmarks/README.md``.
"""

from __future__ import annotations

import time
import traceback
from collections.abc import Callable, Sequence

from . import (
    cache,
    chain_scaling,
    circuits,
    closure_chain,
    compile_latency,
    driven,
    ensemble,
    first_call,
    gradients,
    pendulum,
    rlc,
    spring_chain,
    sweep,
    work_precision,
)
from ._core import BenchmarkError, Result, Row, Settings, load_average, machine_info
from .report import Report

#: name (for ``--only``) → module, in the order they run
BENCHMARKS = {
    mod.NAME: mod
    for mod in (
        spring_chain,
        rlc,
        chain_scaling,
        pendulum,
        ensemble,
        gradients,
        sweep,
        compile_latency,
        first_call,
        cache,
        closure_chain,
        driven,
        work_precision,
        circuits,
    )
}


def run(
    settings: Settings,
    only: Sequence[str] | None = None,
    progress: Callable[[str], None] | None = None,
) -> Report:
    """Run the selected benchmarks (all by default) and collect their rows.

    A benchmark that raises is reported as one failed row (and in ``Report.errors``);
    the others still run. A missed target is not an error.
    """
    from .. import __version__

    names = list(BENCHMARKS) if not only else [n for n in BENCHMARKS if n in set(only)]
    unknown = sorted(set(only or ()) - set(BENCHMARKS))
    if unknown:
        raise ValueError(f"unknown benchmark(s) {unknown}; choose from {list(BENCHMARKS)}.")
    report = Report(settings=settings, machine={**machine_info(), "diracvi": __version__})
    for name in names:
        if progress is not None:
            progress(f"running {name}: {BENCHMARKS[name].DESCRIPTION}")
        start = time.perf_counter()
        try:
            result = BENCHMARKS[name].run(settings)
        except Exception as exc:  # reported in the table; the other benchmarks still run
            message = f"{type(exc).__name__}: {exc}"
            report.errors[name] = message
            report.details[name] = {"traceback": traceback.format_exc()}
            report.rows.append(
                Row(name, f"{name}: failed", None, None, None, notes=message, status="failed")
            )
        else:
            report.rows.extend(result.rows)
            report.details[name] = result.details
        report.durations[name] = time.perf_counter() - start
    report.machine["load_average_end"] = load_average()
    return report


__all__ = ["BENCHMARKS", "BenchmarkError", "Report", "Result", "Row", "Settings", "run"]
