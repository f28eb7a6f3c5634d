r"""Torn N-mass chain: time per step against N, and against a streaming-memory kernel.

For each N (10³ … 10⁶; 10² and 10³ with ``--quick``) the chain ``problems.chain_torn(N,
M)`` with ``M = max(2, N // 100)`` pieces is simulated warm with ``dv.simulate(...,
save_states=False)`` (the automatic solver choice; only energies and constraint
violations are kept per step). The step count is calibrated from two short runs (10
and 40 steps), which separate the fixed cost of a call from the cost per step, so that
the stepping alone takes about ``RUN_TARGET`` (0.5 s; 0.05 s with ``--quick``). Time per
step = min wall time of the whole call ÷ steps (the fixed cost included, and small).

From ``END_TO_END_MIN`` masses (10⁶) a size is measured **end to end** instead, as a
user meets it: in a fresh process with the on-disk compilation cache off, the wall time
of building the problem plus the first ``simulate`` of ``END_TO_END_STEPS`` (1000)
steps, compilation included (target ≤ 120 s), and the process's peak resident memory;
time per step is then one warm repeat of that call ÷ 1000.

The lower bound it is compared with is a *streaming kernel*: a jitted ``lax.scan`` of the
same number of steps whose body is ``y ← a·y + b`` over V float64 values. V is the state
size ``2n`` (q and p; n = N + M − 1 coordinates including the port variables): any step
must at least read and write the state. Where what the run stepped with holds more than
2n float64 values (the affine step map's matrices, or the step solver's state such as
its LU factors: :func:`factor_values`), a second kernel over that many values is timed
too and reported beside it.

The exponent is the least-squares slope of log(time per step) against log N over the
sizes measured. Each size runs in a fresh process, stopped if it takes longer than
``TIMEOUT`` (or what is left of ``BUDGET`` for all sizes) or holds more than
:data:`~diracvi.bench._worker.MAX_RSS_BYTES` of memory; larger sizes are then not tried,
and the table says so. ``--quick`` skips the factor-size kernel.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from ._core import Result, Row, Settings, Target, interleaved, jax_split
from ._worker import WorkerFailed, run_child

NAME = "chain-scaling"
DESCRIPTION = "torn N-mass chain, N = 10³…10⁶: time/step vs N and vs a streaming kernel"

SIZES = (10**3, 10**4, 10**5, 10**6)
QUICK_SIZES = (10**2, 10**3)
RUN_TARGET = {False: 0.5, True: 0.05}  # seconds per timed run
TIMEOUT = {False: 600.0, True: 15.0}  # seconds per size, build and compile included
#: the end-to-end size runs its 1000 steps twice (cold, then warm): on a busy machine
#: that takes longer than a timed size, and its row says where the time went
END_TO_END_TIMEOUT = 1500.0
BUDGET = {False: 2400.0, True: 15.0}  # seconds for all sizes together
END_TO_END_MIN = 10**6
END_TO_END_STEPS = 1000
END_TO_END_TARGET = Target("<=", 120.0)
CALIBRATION_STEPS = 10
CALIBRATION_REPEATS = 3
MAX_STEPS = 100_000
#: a second kernel over the solver's factor values is timed only if they fit in this
FACTOR_KERNEL_BYTES = 1024**3
MIN_TIMEOUT = 5.0  # a size is not started with less time than this left
STREAM_TARGET = Target("<=", 5.0)
EXPONENT_TARGET = Target("<=", 1.1)


def pieces(masses: int) -> int:
    """M = N/100 subsystems (at least 2: an interconnection needs two)."""
    return max(2, masses // 100)


def stream_kernel(values: int, steps: int):
    """A blocking callable: ``steps`` scan iterations of ``y ← 0.5 y + 0.25`` over
    ``values`` float64 numbers (a contraction, so the values stay finite)."""
    import jax
    import jax.numpy as jnp

    x = jnp.linspace(0.0, 1.0, values, dtype=jnp.float64)

    @jax.jit
    def run(y):
        return jax.lax.scan(lambda c, _: (0.5 * c + 0.25, None), y, None, length=steps)[0]

    return lambda: jax.block_until_ready(run(x))


def factor_values(problem) -> int:
    """Float64 values held by what the last ``simulate`` of ``problem`` stepped with.

    That is the cached plan's affine step map (its one-step and block maps, the step
    Jacobian and its inverse) or, on the solver path, the solver's state (e.g. Newton's
    LU factors and |J|), counted from shapes (``jax.eval_shape``: nothing is allocated).
    """
    import jax
    import jax.numpy as jnp

    from ..discretization.equations import StepEquations
    from ..discretization.rules import get_rule
    from ..driver.plan import get_plan

    rule = get_rule("retraction")
    q0, p0 = jnp.asarray(problem.q0), jnp.asarray(problem.p0)
    plan = get_plan(problem.system, rule, "plus", float(problem.dt), None, q0, p0)
    if plan.step_map is not None:
        tree = plan.step_map
    else:
        eqs = StepEquations(problem.system, rule, "plus", jnp.asarray(problem.dt), q0, p0)
        tree = jax.eval_shape(plan.fallback.init, eqs)
    return int(sum(x.size for x in jax.tree.leaves(tree) if jnp.issubdtype(x.dtype, jnp.floating)))


def measure(masses: int, run_target: float, repeats: int, factor_kernel: bool = True) -> dict:
    """One size, in this process: build, calibrate the step count, time interleaved."""
    import diracvi as dv
    from diracvi import problems

    t0 = time.perf_counter()
    problem = problems.chain_torn(masses, pieces(masses))
    build_s = time.perf_counter() - t0
    system = problem.system

    def simulate(steps):
        return dv.simulate(
            system, problem.q0, problem.p0, dt=problem.dt, steps=steps, save_states=False
        )

    def warm_time(steps):
        return float(
            interleaved({"run": lambda: simulate(steps)}, CALIBRATION_REPEATS)["run"].min()
        )

    t0 = time.perf_counter()
    traj = simulate(CALIBRATION_STEPS)
    first_call_s = time.perf_counter() - t0
    # Two step counts separate the fixed cost of a call (checks, transfers) from the cost
    # per step, so the timed run is long enough for the stepping to dominate it.
    short, long = CALIBRATION_STEPS, 4 * CALIBRATION_STEPS
    t_short, t_long = warm_time(short), warm_time(long)
    per_step = (t_long - t_short) / (long - short)
    if per_step <= 0:  # load noise swamped the difference: fall back to the long run
        per_step = t_long / long
    fixed = max(t_short - per_step * short, 0.0)
    steps = int(min(MAX_STEPS, max(long, round(run_target / per_step))))
    if steps <= 2 * long:  # close enough: reuse the compiled 40-step run
        steps = long
    state_values = 2 * system.n
    calls = {"diracvi": lambda: simulate(steps), "stream_state": stream_kernel(state_values, steps)}
    factors = factor_values(problem)
    if factor_kernel and state_values < factors <= FACTOR_KERNEL_BYTES // 8:
        calls["stream_factors"] = stream_kernel(factors, steps)
    times = interleaved(calls, repeats)
    return {
        **_sizes(masses, system, steps),
        "build_s": build_s,
        "first_call_s": first_call_s,
        "calibration": {"fixed_s": fixed, "per_step_s": per_step},
        "solver": traj.solver,
        "state_values": state_values,
        "factor_values": factors,
        "min_s": {name: float(t.min()) for name, t in times.items()},
        "median_s": {name: float(np.median(t)) for name, t in times.items()},
        "repeats": repeats,
    }


def _sizes(masses: int, system, steps: int) -> dict:
    """The size columns every row of the details carries."""
    return {"N": masses, "M": pieces(masses), "n": system.n, "m": system.m, "steps": steps}


def end_to_end(masses: int, steps: int = END_TO_END_STEPS) -> dict:
    """Build + first ``simulate`` of ``steps`` steps (compilation included), then one warm
    repeat of the same call; ``state_values`` as in :func:`measure`."""
    t0 = time.perf_counter()
    import diracvi as dv
    from diracvi import problems

    import_s = time.perf_counter() - t0
    # JAX's own event timings: tracing, lowering and XLA compilation of the first call
    phases = jax_split()
    t0 = time.perf_counter()
    problem = problems.chain_torn(masses, pieces(masses))
    build_s = time.perf_counter() - t0
    system = problem.system

    def simulate():
        return dv.simulate(
            system, problem.q0, problem.p0, dt=problem.dt, steps=steps, save_states=False
        )

    t0 = time.perf_counter()
    traj = simulate()
    first_call_s = time.perf_counter() - t0
    first_phases = {f"{k}_s": v for k, v in phases.items()}
    t0 = time.perf_counter()
    simulate()
    warm_s = time.perf_counter() - t0
    state_values = 2 * system.n
    stream = stream_kernel(state_values, steps)
    stream()  # compile
    stream_s = float(interleaved({"stream": stream}, 3)["stream"].min())
    return {
        **_sizes(masses, system, steps),
        "import_s": import_s,
        "build_s": build_s,
        "first_call_s": first_call_s,
        "end_to_end_s": build_s + first_call_s,
        **first_phases,
        "success": bool(traj.success),
        "solver": traj.solver,
        "state_values": state_values,
        "factor_values": 0,
        "min_s": {"diracvi": warm_s, "stream_state": stream_s},
        "median_s": {"diracvi": warm_s, "stream_state": stream_s},
        "repeats": 1,
    }


def _worker_main() -> None:
    masses, run_target, repeats = int(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
    if masses >= END_TO_END_MIN:
        print(json.dumps(end_to_end(masses)))
        return
    print(json.dumps(measure(masses, run_target, repeats, factor_kernel=sys.argv[4] == "1")))


def _label(masses: int, steps: int | None = None) -> str:
    base = f"chain N={masses:,} (M={pieces(masses)})"
    return base if steps is None else f"{base}, {steps:,} steps"


def _not_run(masses: int, what: str, why) -> Row:
    """The row of a size that was not measured, saying why."""
    return Row(
        NAME,
        f"{_label(masses)}: {what}",
        None,
        None,
        None,
        STREAM_TARGET,
        notes=f"not run: {why}",
        status="not run",
    )


def _end_to_end_row(m: dict) -> Row:
    peak = m["peak_rss_bytes"] / 1024**3
    return Row(
        NAME,
        f"{_label(m['N'], m['steps'])}: end to end (build + compile + steps), fresh process",
        m["end_to_end_s"],
        None,
        m["end_to_end_s"],
        END_TO_END_TARGET,
        solver=m["solver"],
        notes=f"build {m['build_s']:.1f} s, first simulate {m['first_call_s']:.1f} s (of which "
        f"trace {m.get('trace_s', 0.0):.1f} s, lowering {m.get('lower_s', 0.0):.1f} s, XLA "
        f"compile {m.get('compile_s', 0.0):.1f} s; the rest is analysis and the 1000 steps), "
        f"import {m['import_s']:.1f} s not counted; peak memory {peak:.2f} GB; "
        f"ratio = seconds" + ("" if m["success"] else "; the run FAILED"),
    )


def run(settings: Settings) -> Result:
    sizes = QUICK_SIZES if settings.quick else SIZES
    run_target, budget = RUN_TARGET[settings.quick], BUDGET[settings.quick]
    start = time.perf_counter()
    rows, measured, stopped = [], [], None
    for masses in sizes:
        what = "time/step ÷ stream kernel over 2n values"
        limit = END_TO_END_TIMEOUT if masses >= END_TO_END_MIN else TIMEOUT[settings.quick]
        timeout = min(limit, budget - (time.perf_counter() - start))
        if stopped is None and timeout < MIN_TIMEOUT:
            stopped = f"the {budget:.0f} s budget of this benchmark was spent"
        if stopped is not None:
            rows.append(_not_run(masses, what, stopped))
            continue
        code = "from diracvi.bench.chain_scaling import _worker_main; _worker_main()"
        factor_kernel = "0" if settings.quick else "1"
        args = ["-c", code, str(masses), str(run_target), str(settings.long_repeats), factor_kernel]
        try:
            m = run_child(args, timeout=timeout)
        except WorkerFailed as exc:
            stopped = f"N={masses:,} {exc}"
            rows.append(_not_run(masses, what, exc))
            continue
        measured.append(m)
        if "end_to_end_s" in m:
            rows.append(_end_to_end_row(m))
        per_step = {name: t / m["steps"] for name, t in m["min_s"].items()}
        m["per_step_s"] = per_step
        notes = f"2n = {m['state_values']:,} values; min of {m['repeats']}"
        if "stream_factors" in per_step:
            ratio_f = per_step["diracvi"] / per_step["stream_factors"]
            notes += f"; vs kernel over the factors' {m['factor_values']:,} values: {ratio_f:.3g}×"
        elif m["factor_values"] > m["state_values"]:
            notes += f"; the step map or solver state holds {m['factor_values']:,} values"
        rows.append(
            Row(
                NAME,
                f"{_label(masses, m['steps'])}: {what}",
                per_step["diracvi"],
                per_step["stream_state"],
                per_step["diracvi"] / per_step["stream_state"],
                STREAM_TARGET,
                solver=m["solver"],
                notes=notes,
            )
        )
    details = {
        "sizes": measured,
        "run_target_s": run_target,
        "timeout_per_size_s": TIMEOUT[settings.quick],
        "budget_s": budget,
    }
    if len(measured) >= 2:
        n = np.array([m["N"] for m in measured], dtype=np.float64)
        t = np.array([m["per_step_s"]["diracvi"] for m in measured])
        slope = float(np.polyfit(np.log(n), np.log(t), 1)[0])
        details["exponent"] = slope
        span = f"N={measured[0]['N']:,}…{measured[-1]['N']:,}"
        rows.append(
            Row(
                NAME,
                f"chain: fitted exponent of time/step against N ({span})",
                float(t[-1]),
                float(t[0]),
                slope,
                EXPONENT_TARGET,
                solver=", ".join(sorted({m["solver"] for m in measured})),
                notes="diracvi = time/step at the largest N, baseline = at the smallest;"
                " ratio = the exponent" + ("" if len(measured) == len(sizes) else f" ({stopped})"),
            )
        )
    return Result(rows, details)
