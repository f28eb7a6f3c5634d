r"""Differentiable simulation: gradient cost ÷ forward cost, and reverse-mode memory.

Cost: for the paper's RLC (parameters R, L, C; 400 steps, the affine-equivalent linear
path) and the torn double pendulum (the initial state; 1000 midpoint steps, Newton), a
jitted traced run ``J(θ) = Σ q²`` and its jitted reverse-mode gradient
``jax.grad(J)`` are timed warm and interleaved, by the process's CPU time; the ratio
gradient ÷ forward is the cost of a gradient in forward runs (goal ≤ 3, issue 30). Both
use the default ``adjoint="checkpoint"``. CPU time, not wall time: on a shared machine
a call of a few milliseconds is preempted in most repeats, a longer one (the gradient)
in more of them than a shorter one, so the minimum wall time of ten repeats measured
the load: the RLC's ratio read 10.5 by wall time at load 8–14 where the same programs
took 2.2–2.6 by CPU time (benchmarks/README.md, 2026-11-29). On an idle machine the
two agree.

Memory: a torn double pendulum run of 10⁵ midpoint steps differentiated in reverse mode with
``adjoint="checkpoint"`` and with ``adjoint="full"``, each in a fresh process that
reports the resident memory its run adds (peak RSS during the run, reset after
compilation through ``/proc/self/clear_refs``, minus the RSS before it) and XLA's
working memory of the compiled gradient (``memory_analysis().temp_size_in_bytes``).
``--quick`` uses 10⁴ steps.
"""

from __future__ import annotations

import time

import numpy as np

from ._core import Result, Row, Settings, Target, interleaved
from ._core import summary as time_summary
from ._worker import WorkerFailed, run_child

NAME = "gradients"
DESCRIPTION = "gradient ÷ forward cost (RLC, torn double pendulum); reverse-mode memory"

COST_TARGET = Target("<=", 3.0)
MEMORY_STEPS = {False: 100_000, True: 10_000}
TIMEOUT = {False: 600.0, True: 120.0}
WORKER = (
    "import json, sys; from diracvi.bench.gradients import child; "
    "print(json.dumps(child(sys.argv[1], int(sys.argv[2]))))"
)


def _rlc_case(steps):
    import jax.numpy as jnp

    import diracvi as dv

    def loss(theta):
        r, ell, cap = theta[0], theta[1], theta[2]

        def lagrangian(q, v):
            return 0.5 * ell * v[1] ** 2 - q[2] ** 2 / (2.0 * cap)

        def force(q, v):
            return jnp.stack([-r * v[0], 0.0 * v[1], 0.0 * v[2]])

        system = dv.LagrangeDiracSystem(
            ("qR", "qL", "qC"),
            lagrangian,
            constraints=np.array([[1.0, -1.0, -1.0]]),
            force=force,
        )
        p0 = jnp.array([0.0, 7.5, 0.0])
        return jnp.sum(dv.simulate(system, jnp.zeros(3), p0, dt=0.1, steps=steps).q ** 2)

    return loss, jnp.array([1.0, 0.75, 3.0])


def _pendulum_case(steps):
    import jax.numpy as jnp

    import diracvi as dv

    from .. import problems

    problem = problems.double_pendulum_torn()

    def loss(q0):
        traj = dv.simulate(
            problem.system, q0, problem.p0, dt=problem.dt, steps=steps, discretization="midpoint"
        )
        return jnp.sum(traj.q**2)

    return loss, jnp.asarray(problem.q0)


def _cost_row(label, loss, arg, repeats):
    import jax

    forward = jax.jit(loss)
    gradient = jax.jit(jax.grad(loss))
    times = interleaved(
        {
            "forward": lambda: jax.block_until_ready(forward(arg)),
            "gradient": lambda: jax.block_until_ready(gradient(arg)),
        },
        repeats,
        clock=time.process_time,
    )
    f, g = float(np.min(times["forward"])), float(np.min(times["gradient"]))
    row = Row(
        NAME,
        f"{label}: reverse-mode gradient ÷ forward run (CPU time)",
        g,
        f,
        g / f,
        COST_TARGET,
        unit="s",
        notes=f"the process's CPU time, min of {repeats}, interleaved",
    )
    return row, {k: time_summary(v) for k, v in times.items()}


def child(adjoint: str, steps: int) -> dict:
    """Peak memory of one reverse-mode gradient over ``steps`` torn double pendulum steps."""
    import resource
    import time

    import jax
    import jax.numpy as jnp

    import diracvi as dv

    from .. import problems

    problem = problems.double_pendulum_torn()

    def loss(q0):
        traj = dv.simulate(
            problem.system,
            q0,
            problem.p0,
            dt=problem.dt,
            steps=steps,
            discretization="midpoint",
            adjoint=adjoint,
        )
        return jnp.sum(traj.q**2)

    q0 = jnp.asarray(problem.q0)
    compiled = jax.jit(jax.grad(loss)).lower(q0).compile()
    analysis = compiled.memory_analysis()
    temp = None if analysis is None else int(analysis.temp_size_in_bytes)
    before = _rss("VmRSS")
    reset = _reset_peak()
    start = time.perf_counter()
    value = float(jax.block_until_ready(compiled(q0))[0])
    seconds = time.perf_counter() - start
    peak = _rss("VmHWM") if reset else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return {
        "adjoint": adjoint,
        "steps": steps,
        "peak_bytes": peak,
        "rss_before_run_bytes": before,
        "run_increase_bytes": peak - before,
        "xla_temp_bytes": temp,
        "peak_reset": reset,
        "grad": value,
        "s": seconds,
    }


def _rss(field: str) -> int:
    """A memory line of /proc/self/status, in bytes."""
    with open("/proc/self/status") as status:
        for line in status:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    return 0


def _reset_peak() -> bool:
    """Reset the process's peak RSS (Linux: write 5 to /proc/self/clear_refs), so the
    peak measured is that of the run, not of compilation."""
    try:
        with open("/proc/self/clear_refs", "w") as refs:
            refs.write("5")
        return True
    except OSError:
        return False


def run(settings: Settings) -> Result:
    quick = settings.quick
    repeats = 3 if quick else 10
    rows, details = [], {}
    for label, case, steps in (
        ("RLC (R, L, C)", _rlc_case, 100 if quick else 400),
        ("torn double pendulum (q0)", _pendulum_case, 200 if quick else 1000),
    ):
        loss, arg = case(steps)
        row, times = _cost_row(f"{label}, {steps} steps", loss, arg, repeats)
        rows.append(row)
        details[label] = {"steps": steps, **times}
    steps = MEMORY_STEPS[quick]
    peaks = {}
    for adjoint in ("checkpoint", "full"):
        try:
            out = run_child(["-c", WORKER, adjoint, str(steps)], timeout=TIMEOUT[quick])
            peaks[adjoint] = out
        except WorkerFailed as exc:
            peaks[adjoint] = {"failed": str(exc)}
    details["memory"] = peaks
    mb = 1024**2
    for key, what in (
        ("run_increase_bytes", "resident memory added by the run (MB)"),
        ("xla_temp_bytes", "XLA working memory of the compiled gradient (MB)"),
    ):
        ck, full = (peaks[a].get(key) for a in ("checkpoint", "full"))
        rows.append(
            Row(
                NAME,
                f"torn double pendulum, {steps} steps, reverse-mode gradient: {what}, "
                "checkpointed vs full storage (ratio full ÷ checkpointed)",
                None if ck is None else ck / mb,
                None if full is None else full / mb,
                None if not ck or full is None else full / ck,
                None,
                unit="MB",
            )
        )
    return Result(rows, details)
