r"""``simulate``: march the (+) or (−) discrete Dirac equations with a compiled scan.

One time step solves the implicit step equations (see :mod:`diracvi._equations`) with
Newton's method, then applies the explicit momentum update. The whole run is one
``jax.lax.scan`` under ``jit``: no Python code runs per step. A failed step freezes the
carry, so everything computed before it is returned intact.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._config import ensure_float64
from ._discretize import RULES, QuadratureRule, get_rule
from ._equations import SCHEMES, new_momentum, ordered, residual, split
from ._errors import ModelError, StepFailure
from ._solvers.newton import NewtonSolver, SolveStatus
from ._solvers.solvability import DENSE_CHECK_LIMIT, check_step_jacobian
from ._system import DiracSystem
from ._trajectory import STATUS_MESSAGES, Trajectory
from ._validate import check_choice, check_positive_float, check_positive_int, check_state


def _step(system: DiracSystem, rule: QuadratureRule, scheme: str, solver: NewtonSolver, h):
    """One step ``(q, p) → (q_other, p_other)`` plus its diagnostics."""

    def step(carry):
        q, p, q_prev, mu_prev = carry
        guess = jnp.concatenate([2.0 * q - q_prev, mu_prev])
        scale = jnp.max(jnp.abs(q), initial=0.0)
        x, status, iterations, res_norm = solver.solve(
            lambda x: residual(system, rule, scheme, h, q, p, x), guess, scale
        )
        q_other, mu = split(system, x)
        p_other = new_momentum(system, rule, scheme, h, q, x)
        qk, qk1 = ordered(scheme, q, q_other)
        energy = system.energy(rule.node(qk, qk1), (qk1 - qk) / h)
        con = system.discrete_constraints(rule, scheme, qk, qk1, h)
        finite = jnp.all(jnp.isfinite(q_other)) & jnp.all(jnp.isfinite(p_other))
        status = jnp.where((status == 0) & ~finite, SolveStatus.NONFINITE, status)
        return (q_other, p_other, mu), (energy, con, iterations, res_norm, status)

    return step


@eqx.filter_jit
def _run(system, rule, scheme, solver, steps, q0, p0, h):
    step = _step(system, rule, scheme, solver, h)
    nan = jnp.nan

    def body(carry, _):
        q, p, q_prev, mu_prev, failed = carry

        def advance(_):
            (q1, p1, mu), diag = step((q, p, q_prev, mu_prev))
            return (q1, p1, mu), diag

        def frozen(_):
            zeros = jnp.zeros(system.m)
            diag = (jnp.asarray(nan), zeros + nan, jnp.asarray(0), jnp.asarray(nan), -1)
            return (q, p, mu_prev), jax.tree.map(jnp.asarray, diag)

        (q1, p1, mu), diag = jax.lax.cond(failed, frozen, advance, None)
        status = diag[4]
        ok = status == 0
        new_carry = (
            jnp.where(ok, q1, q),
            jnp.where(ok, p1, p),
            jnp.where(ok, q, q_prev),
            jnp.where(ok, mu, mu_prev),
            failed | ~ok,
        )
        return new_carry, (q1, p1, mu, *diag)

    init = (q0, p0, q0, jnp.zeros(system.m), jnp.asarray(False))
    _, out = jax.lax.scan(body, init, None, length=steps)
    return out


@eqx.filter_jit
def _step_jacobian(system, rule, scheme, q0, p0, h):
    x0 = jnp.concatenate([q0, jnp.zeros(system.m)])
    return jax.jacfwd(lambda x: residual(system, rule, scheme, h, q0, p0, x))(x0)


def check_solvable(system, rule, scheme, q0, p0, h) -> None:
    """Raise :class:`UnsolvableStepError` if the first step's Jacobian is singular."""
    if system.n + system.m > DENSE_CHECK_LIMIT:
        return
    jac = np.asarray(_step_jacobian(system, rule, scheme, q0, p0, h))
    other = "q_{k+1}" if scheme == "plus" else "q_k"
    check_step_jacobian(
        jac,
        unknown_names=[f"{other}[{c}]" for c in system.coords]
        + [f"μ[{c}]" for c in system.constraint_names],
        equation_names=[f"momentum balance of {c}" for c in system.coords]
        + [f"constraint {c}" for c in system.constraint_names],
        where=f"the first ({scheme}) step of {getattr(system, 'name', 'the system')!r}",
    )


def _failure_message(status, step, t, iterations, res_norm, coords, q) -> str:
    where = f"at step {step} (t = {t:.6g})"
    if status == SolveStatus.MAX_ITERATIONS:
        return (
            f"Newton did not converge {where} after {iterations} iterations; residual "
            f"‖r‖∞ = {res_norm:.3e}. Try a smaller dt, check that the initial data are "
            "consistent, or raise NewtonSolver(max_steps=...)."
        )
    if status == SolveStatus.SINGULAR:
        return (
            f"The step equations are not solvable {where}: the step Jacobian became singular "
            "(the linear solve returned non-finite values). The constraints or the "
            "Lagrangian degenerate at this state; try a smaller dt or check the model."
        )
    bad = [c for c, x in zip(coords, q, strict=True) if not np.isfinite(x)]
    return (
        f"NaN or Inf appeared {where}" + (f" in {bad}" if bad else "") + ": the model "
        "returned non-finite values (a division by zero, a singular mass matrix, or a "
        "blow-up). Try a smaller dt; check L, the constraints and the force at this state."
    )


def simulate(
    system: DiracSystem,
    q0,
    p0,
    *,
    dt,
    steps,
    scheme: str = "plus",
    discretization: str = "retraction",
    t0: float = 0.0,
    solver: NewtonSolver | None = None,
    throw: bool = True,
) -> Trajectory:
    r"""Integrate a Lagrange–Dirac system with a discrete Dirac variational integrator.

    ``scheme="plus"`` marches the (+) equations forward from ``(q0, p0)`` at time
    ``t0``; ``scheme="minus"`` marches the (−) equations backward from it, so ``t``
    decreases. ``discretization`` picks the quadrature rule (``"retraction"``, order 1,
    the paper's; or ``"midpoint"``, order 2).

    Returns a :class:`Trajectory`. If a step fails, raises :class:`StepFailure` carrying the
    partial trajectory (or returns it with ``status != 0`` when ``throw=False``).
    """
    ensure_float64()
    if not isinstance(system, DiracSystem):
        raise ModelError(
            f"system={system!r} is not a diracvi system: build one with "
            "dv.LagrangeDiracSystem(...) or dv.interconnect(...)."
        )
    scheme = check_choice("scheme", scheme, SCHEMES)
    discretization = check_choice("discretization", discretization, tuple(RULES))
    h = check_positive_float("dt", dt)
    steps = check_positive_int("steps", steps)
    q0 = check_state("q0", q0, system.n, system.coords)
    p0 = check_state("p0", p0, system.n, system.coords)
    solver = NewtonSolver() if solver is None else solver
    if not isinstance(solver, NewtonSolver):
        raise ModelError(f"solver={solver!r} must be a dv.NewtonSolver(...).")
    rule = get_rule(discretization)
    h_arr = jnp.asarray(h)
    check_solvable(system, rule, scheme, q0, p0, h_arr)

    out = _run(system, rule, scheme, solver, steps, q0, p0, h_arr)
    q_new, p_new, mu, energy, con, iterations, res_norm, status = (np.asarray(a) for a in out)
    failed = np.nonzero(status != 0)[0]
    done = steps if failed.size == 0 else int(failed[0])
    sign = 1.0 if scheme == "plus" else -1.0
    t = t0 + sign * h * np.arange(done + 1)
    code, message = 0, STATUS_MESSAGES[0]
    if failed.size:
        code = int(status[done])
        message = _failure_message(
            code,
            done,
            t0 + sign * h * done,
            int(iterations[done]),
            float(res_norm[done]),
            system.coords,
            q_new[done],
        )
    traj = Trajectory(
        t=t,
        q=np.concatenate([np.asarray(q0)[None], q_new[:done]]),
        p=np.concatenate([np.asarray(p0)[None], p_new[:done]]),
        multipliers=mu[:done],
        energy=energy[:done],
        constraint_residual=con[:done],
        newton_iterations=iterations[:done],
        coords=system.coords,
        constraint_names=system.constraint_names,
        dt=h,
        scheme=scheme,
        discretization=discretization,
        system_name=getattr(system, "name", "system"),
        status=code,
        message=message,
        steps_requested=steps,
    )
    if code and throw:
        raise StepFailure(message, traj)
    return traj


def momenta(system: DiracSystem, q, v):
    r"""Consistent momenta ``p = ∂L/∂v(q, v)`` (the continuous Legendre transform)."""
    ensure_float64()
    q = check_state("q", q, system.n, system.coords)
    v = check_state("v", v, system.n, system.coords)
    return np.asarray(jax.jit(system.momentum)(q, v))
