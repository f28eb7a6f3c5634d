"""What every benchmark shares: settings, result rows, interleaved timing, machine facts.

Timing protocol (all benchmarks): a call is timed only *warm*, after one untimed call
that compiles it; ``time.perf_counter`` around the whole call; the garbage collector is
paused while timing (as :mod:`timeit` does); the minimum over repeats is reported,
because it is the run least disturbed by the rest of the machine. The two (or more)
sides of a ratio are timed *interleaved* in one process — A, B, A, B, … with the order
rotated every round — so a change in machine load hits both sides alike.
"""

from __future__ import annotations

import gc
import os
import platform
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np


class BenchmarkError(RuntimeError):
    """A benchmark could not measure what it claims to (e.g. its baseline disagrees)."""


@dataclass(frozen=True)
class Settings:
    """Sizes and repeat counts of one ``diracvi bench`` run.

    ``repeats`` is the repeat count of the paper's protocol (the interconnected /
    monolithic ratios: 1000 in the paper); the other timings are of longer calls and use
    fewer repeats, derived here so that one flag scales the whole run.
    """

    quick: bool = False
    repeats: int | None = None

    @property
    def paper_repeats(self) -> int:
        """Repeats of the torn / monolithic / hand-built timings (the paper's protocol)."""
        return self.repeats if self.repeats is not None else (10 if self.quick else 1000)

    @property
    def numpy_repeats(self) -> int:
        """Repeats of diracvi against the NumPy baseline (each NumPy run is ~10 ms+)."""
        return min(self.paper_repeats, 10 if self.quick else 200)

    @property
    def long_repeats(self) -> int:
        """Repeats of calls that take ~0.1–2 s (scaling, pendulum, ensemble)."""
        return min(self.paper_repeats, 3 if self.quick else 5)


@dataclass(frozen=True)
class Target:
    """An acceptance bound on a row's ratio: ``ratio ≥ value``, ``≤ value`` or in a range."""

    op: str  # ">=", "<=" or "in"
    value: float
    high: float | None = None

    def met(self, ratio: float | None) -> bool | None:
        if ratio is None or not np.isfinite(ratio):
            return None
        if self.op == ">=":
            return bool(ratio >= self.value)
        if self.op == "<=":
            return bool(ratio <= self.value)
        return bool(self.value <= ratio <= self.high)

    def __str__(self) -> str:
        if self.op == ">=":
            return f"≥ {self.value:g}"
        if self.op == "<=":
            return f"≤ {self.value:g}"
        return f"{self.value:g} – {self.high:g}"


@dataclass
class Row:
    """One line of the table.

    ``diracvi`` and ``baseline`` are values in ``unit`` (``"s"`` for times, ``""``
    for dimensionless numbers such as errors); ``ratio`` is what ``target`` judges, and
    ``label`` says which way it is taken (e.g. "NumPy ÷ diracvi").
    """

    benchmark: str
    label: str
    diracvi: float | None
    baseline: float | None
    ratio: float | None
    target: Target | None = None
    solver: str = ""
    unit: str = "s"
    notes: str = ""
    status: str = ""  # "" measured, "not run" (did not fit its limits), "failed" (an error)

    @property
    def met(self) -> bool | None:
        """Whether the ratio meets the target (None: no target); a row not measured fails."""
        if self.target is None:
            return None
        if self.status:
            return False
        return self.target.met(self.ratio)

    def to_json(self) -> dict:
        return {
            "benchmark": self.benchmark,
            "label": self.label,
            "diracvi": self.diracvi,
            "baseline": self.baseline,
            "unit": self.unit,
            "ratio": self.ratio,
            "target": None if self.target is None else str(self.target),
            "met": self.met,
            "solver": self.solver,
            "notes": self.notes,
            "status": self.status or "measured",
        }


@dataclass
class Result:
    """What one benchmark returns: its rows and the numbers behind them (for the JSON)."""

    rows: list[Row]
    details: dict = field(default_factory=dict)


def jax_split() -> dict[str, float]:
    """A dict that JAX's own event timings keep adding to from here on: seconds of
    ``trace`` (jaxpr tracing), ``lower`` (to MLIR) and ``compile`` (XLA's backend)."""
    import jax

    split = {"trace": 0.0, "lower": 0.0, "compile": 0.0}
    names = {
        "/jax/core/compile/jaxpr_trace_duration": "trace",
        "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
        "/jax/core/compile/backend_compile_duration": "compile",
    }

    def listen(event, duration, **_):
        if event in names:
            split[names[event]] += duration

    jax.monitoring.register_event_duration_secs_listener(listen)
    return split


def interleaved(
    calls: dict[str, Callable[[], object]],
    repeats: int,
    clock: Callable[[], float] = time.perf_counter,
) -> dict[str, np.ndarray]:
    """Times (s) of ``repeats`` warm calls of each entry of ``calls``, interleaved: wall
    times by default, or as ``clock`` reads them (``time.process_time``: the process's
    CPU time, which a call preempted by other processes does not accumulate).

    Every call is made once untimed first (compilation, caches). Then round ``i`` times
    each call once, starting from entry ``i mod len(calls)``, so no side always runs
    first or right after another. The callables must block until their result exists
    (``dv.simulate`` returns NumPy arrays; wrap JAX results in ``jax.block_until_ready``).
    """
    names = list(calls)
    for name in names:
        calls[name]()
    times = {name: np.empty(repeats) for name in names}
    enabled = gc.isenabled()
    gc.disable()
    try:
        for i in range(repeats):
            start = i % len(names)
            for name in names[start:] + names[:start]:
                t0 = clock()
                calls[name]()
                times[name][i] = clock() - t0
    finally:
        if enabled:
            gc.enable()
    return times


def simulate_problem(problem, discretization: str):
    """``dv.simulate`` of a built-in problem (:mod:`diracvi.problems`) at its own step,
    length and initial state under ``discretization``: the call the benchmarks time."""
    import diracvi as dv

    return dv.simulate(
        problem.system,
        problem.q0,
        problem.p0,
        dt=problem.dt,
        steps=problem.steps,
        discretization=discretization,
    )


def summary(times: np.ndarray) -> dict:
    """``{min_s, median_s, repeats}`` of a sample of times."""
    return {
        "min_s": float(np.min(times)),
        "median_s": float(np.median(times)),
        "repeats": int(times.size),
    }


def relative_difference(a, b) -> float:
    """``max |a − b| / max |b|`` (absolute where ``b`` is identically zero)."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise BenchmarkError(f"shapes differ: {a.shape} vs {b.shape}")
    scale = float(np.max(np.abs(b), initial=0.0))
    diff = float(np.max(np.abs(a - b), initial=0.0))
    return diff / scale if scale > 0 else diff


def fmt_seconds(value: float | None) -> str:
    if value is None or not np.isfinite(value):
        return "—"
    for unit, factor in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6)):
        if value >= factor:
            return f"{value / factor:.3g} {unit}"
    return f"{value / 1e-9:.3g} ns"


def fmt_value(value: float | None, unit: str) -> str:
    """A row's diracvi/baseline cell: a wall time, or a number in scientific notation."""
    if value is None:
        return "—"
    if unit == "s":
        return fmt_seconds(value)
    text = f"{value:.3g}" if 1e-2 <= abs(value) < 1e4 else f"{value:.2e}"
    return f"{text} {unit}".strip()


def fmt_ratio(value: float | None) -> str:
    if value is None or not np.isfinite(value):
        return "—"
    if value >= 100:
        return f"{value:,.0f}"
    return f"{value:.3g}" if value >= 10 else f"{value:.3f}"


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def load_average() -> list[float] | None:
    """The 1-, 5- and 15-minute load averages (None where the OS has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def source_commit() -> str | None:
    """The git commit of the diracvi source being run (None for an installed copy)."""
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(
            ["git", "describe", "--always", "--dirty"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=10,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    if out.returncode != 0:
        return None
    return out.stdout.strip() or None


def machine_info() -> dict:
    """CPU, core count, library versions, date and load: what a timing depends on."""
    import jax
    import scipy

    from ..runtime.dispatch import mode

    return {
        "commit": source_commit(),
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "jax_backend": jax.default_backend(),
        "cpu_dispatch": mode(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "load_average": load_average(),
    }
