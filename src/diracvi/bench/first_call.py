r"""Cold first call of a nonlinear mechanism against the scipy route, each in a fresh process.

For the four-bar linkage, the torn double pendulum and Andrews' squeezing mechanism
(``diracvi.problems``), with midpoint and lobatto: a fresh Python process imports
diracvi, builds the problem and times its first ``dv.simulate`` (tracing, compiling,
every check and the run; no disk cache). Another fresh process times what a scipy user
writes for the same model (:func:`scipy_route`): the index-1 ODE

    M(q) q̈ = ∂L/∂q − (∂²L/∂v∂q) q̇ + F(q, q̇, t) − G(q)ᵀ λ,     G(q) q̈ = −(G(q) q̇)_q q̇,

(``M = ∂²L/∂v²``, ``G = ∂g/∂q``; the torn double pendulum's reduced ``(θ₁, θ₂)`` model
has no ``g``) with a ``jax.jit`` right-hand side built by autodiff from the model's own
``L``, ``F`` and ``g``, integrated by SciPy's DOP853 at ``rtol = atol = 1e-10``. Both
clocks start after the imports and the problem's construction. Ratio: diracvi ÷ scipy in CPU seconds
(user + system of the process: on a shared machine the wall clock moves with the others'
load, the CPU time much less; the walls are in the notes), targets: midpoint ≤ 2, lobatto
≤ 3 (issue 30); the notes also give the two answers' difference at the horizon (the rule's
own error: midpoint is of order 2).
"""

from __future__ import annotations

import os
import time

import numpy as np

from ._core import Result, Row, Settings, Target, simulate_problem
from ._worker import WorkerFailed, run_child

NAME = "first-call"
DESCRIPTION = "cold first simulate of mechanisms (fresh process) ÷ jit + DOP853 scipy route"

#: (problem, rule) pairs; --quick: Andrews only (the issue's mechanism)
CASES = tuple(
    (name, rule)
    for name in ("four-bar", "double-pendulum-torn", "andrews")
    for rule in ("midpoint", "lobatto")
)
QUICK_CASES = (("andrews", "midpoint"), ("andrews", "lobatto"))
TARGETS = {"midpoint": Target("<=", 2.0), "lobatto": Target("<=", 3.0)}
RTOL = ATOL = 1e-10
TIMEOUT = 300.0

WORKER = """
import json, sys
from diracvi.bench.first_call import measure
print(json.dumps(measure(*sys.argv[1:])))
"""


def _cpu() -> float:
    t = os.times()
    return t.user + t.system


def reduced_model(problem):
    """The model the scipy route integrates: ``(system, q0, p0, pick)`` — the problem's
    own system, or a torn problem's hand-built reduced one; ``pick`` maps a diracvi state
    of ``problem.system`` to the reduced coordinates (indices)."""
    if problem.reduced is None:
        return problem.system, problem.q0, problem.p0, np.arange(problem.system.n)
    coords = problem.system.coords
    pick = np.array([coords.index(torn) for torn in problem.shared])
    reduced = problem.reduced
    return reduced.system, reduced.q0, reduced.p0, pick


def index1_rhs(system):
    """``(t, y) ↦ ẏ`` of the index-1 ODE of the module docstring, ``y = (q, q̇)``, jitted
    (JAX autodiff of the model's ``L``, ``F`` and ``g``)."""
    import jax
    import jax.numpy as jnp

    n = system.n

    def rhs(t, y):
        q, v = y[:n], y[n:]
        lag = lambda q, v: system.lagrangian(q, v, t)  # noqa: E731
        mass = jax.hessian(lag, argnums=1)(q, v)
        dl_dq = jax.grad(lag, argnums=0)(q, v)
        mixed = jax.jacfwd(jax.grad(lag, argnums=1), argnums=0)(q, v) @ v
        rhs_v = dl_dq - mixed + system.force(q, v, t)
        g = lambda q: system.position_constraints(q, t)  # noqa: E731
        k = g(q).shape[0]
        if k == 0:
            return jnp.concatenate([v, jnp.linalg.solve(mass, rhs_v)])
        jac = jax.jacfwd(g)(q)
        curvature = jax.jacfwd(lambda q: jax.jacfwd(g)(q) @ v)(q) @ v
        kkt = jnp.block([[mass, jac.T], [jac, jnp.zeros((k, k))]])
        acc = jnp.linalg.solve(kkt, jnp.concatenate([rhs_v, -curvature]))[:n]
        return jnp.concatenate([v, acc])

    return jax.jit(rhs)


def scipy_route(problem, t_end: float) -> np.ndarray:
    """The reduced model's ``q`` at ``t_end`` by DOP853 on :func:`index1_rhs`, from the
    problem's initial state (``q̇₀ = M(q₀)⁻¹ p₀``)."""
    import jax
    import scipy.integrate

    system, q0, p0, _ = reduced_model(problem)
    rhs = index1_rhs(system)
    mass = jax.hessian(lambda v: system.lagrangian(q0, v, problem.t0))(np.zeros(system.n))
    v0 = np.linalg.solve(np.asarray(mass), p0)
    sol = scipy.integrate.solve_ivp(
        lambda t, y: np.asarray(rhs(t, y)),
        (problem.t0, t_end),
        np.concatenate([q0, v0]),
        method="DOP853",
        rtol=RTOL,
        atol=ATOL,
    )
    if not sol.success:
        raise RuntimeError(f"scipy route: solve_ivp failed: {sol.message}")
    return sol.y[: system.n, -1]


def measure(side: str, name: str, rule: str) -> dict:
    """In a fresh process: the first call of ``side`` (``diracvi`` or ``scipy``) on the
    problem ``name`` (wall and CPU s) and its ``q`` at the horizon (reduced coordinates)."""
    from diracvi import problems

    problem = problems.get(name)
    _, _, _, pick = reduced_model(problem)
    t_end = problem.t0 + problem.dt * problem.steps
    import scipy.integrate  # noqa: F401  (imported before the clock, as diracvi is)

    wall, cpu = time.perf_counter(), _cpu()
    if side == "diracvi":
        traj = simulate_problem(problem, rule)
        q_end = np.asarray(traj.q[-1])[pick]
    else:
        q_end = scipy_route(problem, t_end)
    return {
        "wall_s": time.perf_counter() - wall,
        "cpu_s": _cpu() - cpu,
        "q_end": q_end.tolist(),
        "steps": problem.steps,
    }


def run(settings: Settings) -> Result:
    cases = QUICK_CASES if settings.quick else CASES
    rows, measured, scipy = [], [], {}
    for name, rule in cases:
        label = f"first call: {name} ({rule}) ÷ scipy route"
        try:
            if name not in scipy:
                scipy[name] = run_child(["-c", WORKER, "scipy", name, rule], timeout=TIMEOUT)
            base = scipy[name]
            m = run_child(["-c", WORKER, "diracvi", name, rule], timeout=TIMEOUT)
        except WorkerFailed as exc:
            rows.append(
                Row(NAME, label, None, None, None, notes=f"not run: {exc}", status="not run")
            )
            continue
        differ = float(np.max(np.abs(np.subtract(m["q_end"], base["q_end"]))))
        measured.append({"problem": name, "rule": rule, "diracvi": m, "scipy": base})
        rows.append(
            Row(
                NAME,
                f"{label} ({m['steps']} steps)",
                m["cpu_s"],
                base["cpu_s"],
                m["cpu_s"] / base["cpu_s"],
                target=TARGETS[rule],
                notes=(
                    f"fresh processes, CPU s; wall {m['wall_s']:.2f} ÷ {base['wall_s']:.2f} s; "
                    f"q at the horizon differ by {differ:.1e}"
                ),
            )
        )
    return Result(rows, {"cases": measured, "rtol": RTOL, "atol": ATOL})
