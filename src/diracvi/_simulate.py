r"""``simulate``: march the (+) or (−) discrete Dirac equations with a compiled scan.

One time step solves the implicit step equations (see :mod:`diracvi._equations`) with
Newton's method, then applies the explicit momentum update. The whole run is one
``jax.lax.scan`` under ``jit``: no Python code runs per step. A failed step freezes the
carry, so everything computed before it is returned intact.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import _checkpoint, _consistency
from ._config import ensure_float64
from ._discretize import RULES, QuadratureRule, get_rule
from ._equations import SCHEMES, StepEquations, ordered, residual, split
from ._errors import ModelError, StepFailure
from ._solvers import NewtonSolver, SolveStatus, StepSolver
from ._solvers.solvability import DENSE_CHECK_LIMIT, check_step_jacobian
from ._system import DiracSystem
from ._trajectory import STATUS_MESSAGES, Trajectory
from ._validate import check_choice, check_positive_float, check_positive_int, check_state


def _step(system: DiracSystem, rule: QuadratureRule, scheme: str, solver: StepSolver, h):
    """One step ``(q, p) → (q_other, p_other)`` plus its diagnostics."""

    def step(carry):
        q, p, q_prev, mu_prev, state = carry
        eqs = StepEquations(system, rule, scheme, h, q, p)
        guess = jnp.concatenate([2.0 * q - q_prev, mu_prev])
        res = solver.solve(eqs, guess, state)
        q_other, mu = split(system, res.x)
        p_other = eqs.momentum(res.x)
        qk, qk1 = ordered(scheme, q, q_other)
        energy = system.energy(rule.node(qk, qk1), (qk1 - qk) / h)
        con = system.discrete_constraints(rule, scheme, qk, qk1, h)
        finite = jnp.all(jnp.isfinite(q_other)) & jnp.all(jnp.isfinite(p_other))
        status = jnp.where((res.status == 0) & ~finite, SolveStatus.NONFINITE, res.status)
        diag = (energy, con, res.iterations, res.residual_norm, status)
        return (q_other, p_other, mu, res.state), diag

    return step


@eqx.filter_jit
def _run(system, rule, scheme, solver, steps, carry, h):
    """``steps`` steps from ``carry = (q, p, q_prev, μ_prev)``; returns (carry, outputs).

    The solver state (a cached factorization) starts afresh in every chunk, so a resumed
    run repeats the arithmetic of an uninterrupted one exactly.
    """
    step = _step(system, rule, scheme, solver, h)
    nan = jnp.nan
    state0 = solver.init(StepEquations(system, rule, scheme, h, carry[0], carry[1]))

    def body(carry, _):
        q, p, q_prev, mu_prev, state, failed = carry

        def advance(_):
            return step((q, p, q_prev, mu_prev, state))

        def frozen(_):
            zeros = jnp.zeros(system.m)
            diag = (jnp.asarray(nan), zeros + nan, jnp.asarray(0), jnp.asarray(nan), -1)
            return (q, p, mu_prev, state), jax.tree.map(jnp.asarray, diag)

        (q1, p1, mu, state1), diag = jax.lax.cond(failed, frozen, advance, None)
        status = diag[4]
        ok = status == 0
        new_carry = (
            jnp.where(ok, q1, q),
            jnp.where(ok, p1, p),
            jnp.where(ok, q, q_prev),
            jnp.where(ok, mu, mu_prev),
            state1,
            failed | ~ok,
        )
        return new_carry, (q1, p1, mu, *diag)

    final, out = jax.lax.scan(body, (*carry, state0, jnp.asarray(False)), None, length=steps)
    return final[:4], out


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


class _March:
    """The run so far: host-side arrays of the completed steps and the scan carry."""

    def __init__(self, system, q0, p0):
        self.system = system
        self.q, self.p = [np.asarray(q0)[None]], [np.asarray(p0)[None]]
        # per-step outputs kept: multipliers, energy, constraint residual, Newton iterations
        self.rest: list[list[np.ndarray]] = [[] for _ in range(4)]
        self._carry = (q0, p0, q0, jnp.zeros(system.m))
        self.status, self.failure = 0, None

    @property
    def done(self) -> int:
        return sum(len(x) for x in self.q) - 1

    def carry(self):
        return self._carry

    def resume(self, saved: Trajectory, in_progress: bool):
        self.q, self.p = [saved.q], [saved.p]
        self.rest = [
            [saved.multipliers],
            [saved.energy],
            [saved.constraint_residual],
            [saved.newton_iterations],
        ]
        if not in_progress and saved.status:
            self.status = saved.status
            self.failure = (saved.message,)
        prev_q = saved.q[-2] if saved.steps else saved.q[0]
        prev_mu = saved.multipliers[-1] if saved.steps else np.zeros(self.system.m)
        self._carry = tuple(jnp.asarray(a) for a in (saved.q[-1], saved.p[-1], prev_q, prev_mu))

    def extend(self, carry, out):
        q_new, p_new, mu, energy, con, iterations, res_norm, status = (np.asarray(a) for a in out)
        failed = np.nonzero(status != 0)[0]
        keep = len(status) if failed.size == 0 else int(failed[0])
        self.q.append(q_new[:keep])
        self.p.append(p_new[:keep])
        for store, arr in zip(self.rest, (mu, energy, con, iterations), strict=True):
            store.append(arr[:keep])
        self._carry = carry
        if failed.size:
            self.status = int(status[keep])
            self.failure = (int(iterations[keep]), float(res_norm[keep]), q_new[keep])

    def trajectory(self, t0, sign, h, scheme, discretization, steps) -> Trajectory:
        done = self.done
        code, message = self.status, STATUS_MESSAGES[0]
        if code and len(self.failure) == 1:
            message = self.failure[0]
        elif code:
            iterations, res_norm, q_bad = self.failure
            message = _failure_message(
                code, done, t0 + sign * h * done, iterations, res_norm, self.system.coords, q_bad
            )
        mu, energy, con, iterations = (np.concatenate(x) for x in self.rest)
        return Trajectory(
            t=t0 + sign * h * np.arange(done + 1),
            q=np.concatenate(self.q),
            p=np.concatenate(self.p),
            multipliers=mu.reshape(done, self.system.m),
            energy=energy,
            constraint_residual=con.reshape(done, self.system.m),
            newton_iterations=iterations,
            coords=self.system.coords,
            constraint_names=self.system.constraint_names,
            dt=h,
            scheme=scheme,
            discretization=discretization,
            system_name=getattr(self.system, "name", "system"),
            status=code,
            message=message,
            steps_requested=steps,
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
    solver: StepSolver | None = None,
    throw: bool = True,
    checkpoint=None,
    checkpoint_every: int | None = None,
    project_initial: bool = False,
) -> Trajectory:
    r"""Integrate a Lagrange–Dirac system with a discrete Dirac variational integrator.

    ``scheme="plus"`` marches the (+) equations forward from ``(q0, p0)`` at time
    ``t0``; ``scheme="minus"`` marches the (−) equations backward from it, so ``t``
    decreases. ``discretization`` picks the quadrature rule (``"retraction"``, order 1,
    the paper's; or ``"midpoint"``, order 2).

    Returns a :class:`Trajectory`. If a step fails, raises :class:`StepFailure` carrying the
    partial trajectory (or returns it with ``status != 0`` when ``throw=False``).

    Inconsistent initial data (joined ports at different positions, momenta a degenerate
    Lagrangian does not allow) raise an ``InconsistentInitialDataWarning`` giving the size
    of the violation; ``project_initial=True`` starts from the nearest consistent state.

    ``checkpoint=PATH`` writes the run to PATH (NetCDF, atomically) after every
    ``checkpoint_every`` steps; calling ``simulate`` again with the same arguments resumes
    from the last completed chunk, and the result is bitwise identical to an
    uninterrupted run.
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
    if not isinstance(solver, StepSolver):
        raise ModelError(f"solver={solver!r} must be a dv.NewtonSolver(...).")
    rule = get_rule(discretization)
    h_arr = jnp.asarray(h)
    q0, p0 = _consistency.check(system, q0, p0, project_initial=bool(project_initial))
    check_solvable(system, rule, scheme, q0, p0, h_arr)

    run_chunk = partial(_run, system, rule, scheme, solver)
    march = _March(system, q0, p0)
    path, key, chunk = None, None, steps
    if checkpoint is not None:
        chunk = (
            steps
            if checkpoint_every is None
            else check_positive_int("checkpoint_every", checkpoint_every)
        )
        path = Path(checkpoint)
        key = _checkpoint.fingerprint(
            system,
            q0,
            p0,
            dt=h,
            steps=steps,
            scheme=scheme,
            discretization=discretization,
            solver=solver,
            chunk=chunk,
        )
        saved = _checkpoint.read(path, key)
        if saved is not None:
            march.resume(*saved)

    sign = 1.0 if scheme == "plus" else -1.0
    while march.done < steps and march.status == 0:
        length = min(chunk - march.done % chunk, steps - march.done)
        carry, out = run_chunk(length, march.carry(), h_arr)
        march.extend(carry, out)
        if path is not None:
            _checkpoint.write(
                march.trajectory(t0, sign, h, scheme, discretization, steps),
                path,
                key,
                in_progress=march.status == 0 and march.done < steps,
            )
    traj = march.trajectory(t0, sign, h, scheme, discretization, steps)
    if traj.status and throw:
        raise StepFailure(traj.message, traj)
    return traj


def momenta(system: DiracSystem, q, v):
    r"""Consistent momenta ``p = ∂L/∂v(q, v)`` (the continuous Legendre transform)."""
    ensure_float64()
    q = check_state("q", q, system.n, system.coords)
    v = check_state("v", v, system.n, system.coords)
    return np.asarray(jax.jit(system.momentum)(q, v))
