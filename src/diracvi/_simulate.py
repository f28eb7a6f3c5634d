r"""``simulate``: march the (+) or (−) discrete Dirac equations with a compiled scan.

One time step solves the implicit step equations (see :mod:`diracvi._equations`) — by
the precomputed affine step map when they are linear, by a step solver otherwise — then
applies the explicit momentum update. A run is a few compiled chunks
(:mod:`diracvi._stepping`); no Python code runs per step. A failed step freezes the
carry, so everything computed before it is returned intact.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import equinox as eqx
import numpy as np

from . import _checkpoint
from ._config import ensure_float64
from ._discretize import RULES, get_rule
from ._equations import SCHEMES
from ._errors import ModelError, StepFailure
from ._plan import Layout, get_plan, layout
from ._solvers import SolveStatus, StepSolver
from ._solvers.affine import AffineSolver
from ._stepping import AFFINE_REJECTED
from ._system import DiracSystem
from ._traced import ADJOINTS, check_traced_options, is_traced, simulate_traced
from ._trajectory import STATUS_MESSAGES, Trajectory
from ._validate import (
    CONCRETE_TYPES,
    check_choice,
    check_float,
    check_positive_float,
    check_positive_int,
    check_state,
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
    """The run so far: host-side arrays of the saved states and the chunk carry."""

    def __init__(self, system: Layout, q0, p0, k: int, save_states: bool, nodal: bool):
        self.system, self.k, self.save_states, self.nodal = system, k, save_states, nodal
        self.index = [np.zeros(1, dtype=np.int64)]
        self.states = [(np.asarray(q0)[None], np.asarray(p0)[None])] if save_states else []
        # the given p0 is the momentum at t0 itself (no impulse lag)
        self.nodal_p = [np.asarray(p0)[None]] if nodal else []
        self.diag: list[tuple] = []  # (energy, violation, iterations[, mu, con])
        self.carry = (q0, p0, q0, np.zeros(system.m))
        self.done = 0
        self.status, self.failure = 0, None
        self.fallback_from: int | None = None
        self.fallback_reason = ""

    def resume(self, saved: Trajectory, in_progress: bool, attrs: dict):
        self.index = [saved.step_index]
        if self.save_states:
            self.states = [(saved.q, saved.p)]
        if self.nodal:
            self.nodal_p = [saved.p_nodal]
        diag = (saved.energy, saved.constraint_violation, saved.newton_iterations)
        if self.save_states:
            diag += (saved.multipliers, saved.constraint_residual)
        self.diag = [diag]
        self.done = saved.steps
        if not in_progress and saved.status:
            self.status = saved.status
            self.failure = (saved.message,)
        if "fallback_from" in attrs:
            self.fallback_from = int(attrs["fallback_from"])
            self.fallback_reason = str(attrs.get("fallback_reason", ""))
        self.carry = tuple(np.asarray(a) for a in saved.final_state)

    def extend(self, carry, fail, saved):
        n_good = saved["n_good"]
        full = n_good == self.k
        whole = len(full) if full.all() else int(np.argmin(full))
        keep = whole + int(whole < len(full) and n_good[whole] > 0)
        steps = np.minimum(n_good[:keep], self.k)
        self.index.append(self.done + np.cumsum(steps))
        self.done += int(steps.sum())
        if self.save_states:
            self.states.append((saved["q"][:keep], saved["p"][:keep]))
        if self.nodal:
            self.nodal_p.append(saved["p_node"][:keep])
        diag = (saved["energy"], saved["violation"], saved["iterations"])
        if self.save_states:
            diag += (saved["mu"], saved["con"])
        self.diag.append(tuple(a[:keep] for a in diag))
        self.carry = carry
        if whole < len(full):
            code, iterations, res_norm, q_bad = fail
            self.status = int(code)
            self.failure = (int(iterations), float(res_norm), q_bad)

    def trajectory(self, t0, sign, h, scheme, discretization, steps, solver) -> Trajectory:
        code, message = self.status, STATUS_MESSAGES[0]
        if code and len(self.failure) == 1:
            message = self.failure[0]
        elif code:
            iterations, res_norm, q_bad = self.failure
            message = _failure_message(
                code,
                self.done,
                t0 + sign * h * self.done,
                iterations,
                res_norm,
                self.system.coords,
                q_bad,
            )
        index = np.concatenate(self.index)
        cols = [np.concatenate(c) for c in zip(*self.diag, strict=True)] if self.diag else []
        m = self.system.m
        if not cols:
            cols = [np.zeros(0), np.zeros(0), np.zeros(0, np.int64)]
            if self.save_states:
                cols += [np.zeros((0, m)), np.zeros((0, m))]
        energy, violation, iterations = cols[:3]
        q = p = mu = con = None
        if self.save_states:
            q = np.concatenate([s[0] for s in self.states])
            p = np.concatenate([s[1] for s in self.states])
            mu, con = (c.reshape(len(energy), m) for c in cols[3:])
        return Trajectory(
            t=t0 + sign * h * index,
            q=q,
            p=p,
            p_nodal=np.concatenate(self.nodal_p) if self.nodal else None,
            multipliers=mu,
            energy=energy,
            constraint_residual=con,
            newton_iterations=iterations,
            constraint_violation=violation,
            step_index=index,
            save_every=self.k,
            final_state=self.carry,
            coords=self.system.coords,
            constraint_names=self.system.constraint_names,
            dt=h,
            scheme=scheme,
            discretization=discretization,
            system_name=self.system.name,
            status=code,
            message=message,
            steps_requested=steps,
            solver=solver,
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
    solver=None,
    save_every: int = 1,
    save_states: bool = True,
    throw: bool = True,
    checkpoint=None,
    checkpoint_every: int | None = None,
    project_initial: bool = False,
    adjoint: str = "checkpoint",
) -> Trajectory:
    r"""Integrate a Lagrange–Dirac system with a discrete Dirac variational integrator.

    ``scheme="plus"`` marches the (+) equations forward from ``(q0, p0)`` at time
    ``t0``; ``scheme="minus"`` marches the (−) equations backward from it, so ``t``
    decreases. ``discretization`` picks the quadrature rule (``"retraction"``, order 1,
    the paper's; ``"midpoint"``, order 2; or ``"lobatto"``, order 4, with one internal
    stage per step). Step ``j`` covers ``[t_j, t_j + h]`` with
    ``t_j = t0 + j·h`` (``t0 − (j+1)·h`` backward); a driven model (``L``, ``F``, ``A``,
    ``b`` or ``g`` taking ``t``) is evaluated at the rule's time node in it.

    ``p0`` is the momentum at ``t0``. ``traj.p`` holds the scheme's momenta, which under
    the midpoint rule lag the true ones by half of each step's constraint impulse;
    ``traj.p_nodal`` holds momenta at the nodes to the rule's order (see
    :class:`Trajectory`).

    ``solver=None`` chooses the stepping method: the precomputed affine step map when
    the step equations are linear (verified on every step, with a fallback to Newton),
    Newton otherwise. Pass ``dv.NewtonSolver(...)``, ``dv.AffineSolver(...)`` or another
    step solver to choose; ``traj.solver`` says what ran.

    ``save_every=k`` keeps every k-th state (``steps`` must be a multiple of k);
    ``save_states=False`` keeps only the diagnostics (energy, constraint violation,
    iterations per saved interval) and the final state, so a long run of a large model
    needs O(n + steps/k) memory.

    Returns a :class:`Trajectory`. If a step fails, raises :class:`StepFailure` carrying the
    partial trajectory (or returns it with ``status != 0`` when ``throw=False``).

    Inconsistent initial data (joined ports at different positions, momenta a degenerate
    Lagrangian does not allow) raise an ``InconsistentInitialDataWarning`` giving the size
    of the violation; ``project_initial=True`` starts from the nearest consistent state.

    ``checkpoint=PATH`` writes the run to PATH (NetCDF, atomically) after every
    ``checkpoint_every`` steps; calling ``simulate`` again with the same arguments resumes
    from the last completed chunk, and the result is bitwise identical to an
    uninterrupted run.

    **Differentiable**: called inside ``jax.jit``, ``jax.grad``, ``jax.jvp``/``jax.jacfwd``
    or ``jax.vmap`` (or with traced ``q0``, ``p0``, ``t0`` or system parameters), the run
    is one pure JAX function and the result a :class:`Trajectory` of JAX arrays (a
    PyTree). Each step is differentiated by the implicit function theorem; ``adjoint``
    chooses the memory of reverse mode: ``"checkpoint"`` (default: the run is stored at
    about √steps points and recomputed in between) or ``"full"`` (every step stored).
    ``checkpoint=`` and ``project_initial=True`` are host-only and refused there;
    ``throw=True`` makes a failed step a runtime error (``equinox.error_if``),
    ``throw=False`` reports it in ``traj.status``. See ``docs/gradients.md``.
    """
    adjoint = check_choice("adjoint", adjoint, ADJOINTS)
    run = check_run(system, scheme, discretization, dt, steps, save_every, solver)
    # the system's own leaves are looked at once per system (its layout), not per call;
    # arguments of plain NumPy / Python types cannot hold a tracer (only the active
    # transformation is then looked up)
    if run.shape.traced or is_traced(*(x for x in (q0, p0, t0) if type(x) not in CONCRETE_TYPES)):
        check_traced_options(checkpoint, project_initial)
        return simulate_traced(
            system,
            q0,
            p0,
            t0,
            run,
            solver,
            save_states=save_states,
            throw=bool(throw),
            adjoint=adjoint,
        )
    h, steps, k, shape = run.h, run.steps, run.save_every, run.shape
    q0 = check_state("q0", q0, shape.n, shape.coords)
    p0 = check_state("p0", p0, shape.n, shape.coords)
    t0 = check_float("t0", t0)
    plan = prepared_plan(system, run, solver, q0, p0, t0)
    # consistent data of a linear model pass with one precomputed product; anything
    # else (and every inconsistent state) goes through the full check
    if not plan.checker.accepts(q0, p0):
        q0, p0 = plan.checker.check(q0, p0, project_initial=bool(project_initial), t0=t0)
    save_states = bool(save_states)
    first = None
    if checkpoint is None:
        # the whole run is one compiled chunk; a run that took every step is returned
        # directly (the march below handles a failure or an affine fallback)
        affine = plan.step_map is not None
        chunk = plan.chunk(affine, k, save_states, steps // k)
        carry = (q0, p0, q0, np.zeros(shape.m))
        flat = chunk.run(chunk.flat_input(h, (t0, 0.0), carry))
        if flat[chunk.layout.code] == 0:
            return _whole_run(plan, run, q0, p0, t0, chunk.layout, flat)
        first = affine, chunk.layout.unpack(flat)
    traj = _march(
        plan, run, system, q0, p0, t0, save_states, solver, checkpoint, checkpoint_every, first
    )
    if traj.status and throw:
        raise StepFailure(traj.message, traj)
    return traj


def _whole_run(plan, run, q0, p0, t0, layout, flat) -> Trajectory:
    """The trajectory of a run whose one chunk took every step: what :class:`_March`
    builds in that case. Times, states and energies are made here; the rest stays in the
    packed output until read (see :class:`_Unpacked`)."""
    scheme, discretization, h, steps, k, shape = run
    rows = flat[: layout.rows_end].reshape(layout.blocks, layout.width)
    cols = layout.columns
    index = np.arange(0, steps + 1, k)
    sign = 1.0 if scheme == "plus" else -1.0
    q = p = None
    if "q" in cols:
        q = np.concatenate((q0[None], rows[:, cols["q"]]))
        p = np.concatenate((p0[None], rows[:, cols["p"]]))
    return Trajectory._of_run(
        _Unpacked(layout, flat, p0),
        t=t0 + sign * h * index,
        q=q,
        p=p,
        energy=rows[:, cols["energy"]].copy(),
        step_index=index,
        save_every=k,
        coords=shape.coords,
        constraint_names=shape.constraint_names,
        dt=h,
        scheme=scheme,
        discretization=discretization,
        system_name=shape.name,
        status=0,
        message=STATUS_MESSAGES[0],
        solver=plan.describe(),
        steps_requested=steps,
    )


#: a Trajectory attribute → its name in a chunk's saved outputs
_SAVED_AS = {
    "multipliers": "mu",
    "constraint_residual": "con",
    "constraint_violation": "violation",
    "_p_nodal": "p_node",
}


class _Unpacked:
    """The fields of a whole run's :class:`Trajectory` that most callers never read,
    made from the packed chunk output on first access (as :class:`_March` makes them)."""

    names = frozenset(
        (
            "final_state",
            "multipliers",
            "constraint_residual",
            "constraint_violation",
            "newton_iterations",
            "_p_nodal",
        )
    )
    __slots__ = ("_flat", "_layout", "_p0", "_parts")

    def __init__(self, layout, flat, p0):
        self._layout, self._flat, self._p0, self._parts = layout, flat, p0, None

    def __call__(self, name: str):
        if self._parts is None:
            self._parts = self._layout.unpack(self._flat)
        carry, _, saved = self._parts
        if name == "final_state":
            return carry
        if name == "newton_iterations":
            return saved["iterations"]
        value = saved.get(_SAVED_AS[name])
        if value is None or name != "_p_nodal":
            return None if value is None else value.copy()
        return np.concatenate((self._p0[None], value))  # the given p0 is the nodal one


def _march(
    plan, run, system, q0, p0, t0, save_states, solver, checkpoint, checkpoint_every, first
) -> Trajectory:
    """Run chunk after chunk: checkpoints, a failed step, the affine map's fallback.
    ``first``: ``(affine, chunk output)`` of the whole run's chunk, already computed."""
    scheme, discretization, h, steps, k, shape = run
    nodal = save_states and plan.nodal_when_saved
    march = _March(shape, q0, p0, k, save_states, nodal)
    path, key, chunk = None, None, steps
    if checkpoint is not None:
        chunk = steps if checkpoint_every is None else check_checkpoint_every(checkpoint_every, k)
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
            save=(k, save_states),
            t0=t0,
        )
        saved = _checkpoint.read(path, key)
        if saved is not None:
            march.resume(*saved)

    sign = 1.0 if scheme == "plus" else -1.0

    def describe():
        return plan.describe(march.fallback_from, march.fallback_reason)

    while march.done < steps and march.status == 0:
        length = min(chunk - march.done % chunk, steps - march.done)
        affine = plan.step_map is not None and march.fallback_from is None
        if first is not None and first[0] == affine:
            carry, fail, saved = first[1]
        else:
            clock = np.array([t0, march.done], dtype=np.float64)
            carry, fail, saved = plan.chunk(affine, k, march.save_states, length // k)(
                plan.h_array, clock, march.carry
            )
        first = None
        if affine and int(fail[0]) == AFFINE_REJECTED:
            # the equations are not affine after all: redo this chunk with the fallback
            at = march.done + int(np.argmin(np.asarray(saved["n_good"]) == k)) * k
            march.fallback_from = march.done
            march.fallback_reason = (
                f"the affine step was off by {float(fail[2]):.1e} relative near step {at}"
            )
            continue
        march.extend(carry, fail, saved)
        if path is not None:
            attrs = {}
            if march.fallback_from is not None:
                attrs = {
                    "fallback_from": march.fallback_from,
                    "fallback_reason": march.fallback_reason,
                }
            _checkpoint.write(
                march.trajectory(t0, sign, h, scheme, discretization, steps, describe()),
                path,
                key,
                in_progress=march.status == 0 and march.done < steps,
                extra=attrs,
            )
    return march.trajectory(t0, sign, h, scheme, discretization, steps, describe())


#: classes found to be DiracSystems (an isinstance check of a Module class costs ~1 µs)
_SYSTEM_TYPES: set[type] = set()


def _is_system(system) -> bool:
    if isinstance(system, DiracSystem):
        _SYSTEM_TYPES.add(type(system))
        return True
    return False


class RunArguments(NamedTuple):
    scheme: str
    discretization: str
    h: float
    steps: int
    save_every: int
    shape: Layout


def check_run(system, scheme, discretization, dt, steps, save_every, solver) -> RunArguments:
    """The arguments ``simulate`` and ``simulate_ensemble`` share, checked."""
    ensure_float64()
    if type(system) not in _SYSTEM_TYPES and not _is_system(system):
        raise ModelError(
            f"system={system!r} is not a diracvi system: build one with "
            "dv.LagrangeDiracSystem(...) or dv.interconnect(...)."
        )
    scheme = check_choice("scheme", scheme, SCHEMES)
    discretization = check_choice("discretization", discretization, tuple(RULES))
    h = check_positive_float("dt", dt)
    steps = check_positive_int("steps", steps)
    k = check_save_every(steps, save_every)
    check_solver(solver)
    return RunArguments(scheme, discretization, h, steps, k, layout(system))


def prepared_plan(system, run: RunArguments, solver, q0, p0, t0=0.0):
    """The cached plan of this configuration (analysed on first use, see :mod:`._plan`)."""
    return get_plan(system, get_rule(run.discretization), run.scheme, run.h, solver, q0, p0, t0)


def check_save_every(steps: int, save_every) -> int:
    k = check_positive_int("save_every", save_every)
    if steps % k:
        raise ModelError(
            f"save_every={k} does not divide steps={steps}: saved states are every k-th "
            f"step and the last one is the end of the run; choose steps={steps - steps % k + k} "
            f"or a save_every that divides {steps}."
        )
    return k


def check_checkpoint_every(checkpoint_every, k: int) -> int:
    every = check_positive_int("checkpoint_every", checkpoint_every)
    if every % k:
        raise ModelError(
            f"checkpoint_every={every} is not a multiple of save_every={k}: a checkpoint "
            f"must end on a saved state; use checkpoint_every={every - every % k + k}."
        )
    return every


def check_solver(solver) -> None:
    if solver is None or isinstance(solver, StepSolver | AffineSolver):
        return
    raise ModelError(
        f"solver={solver!r} is not a diracvi solver: pass None (automatic), "
        "dv.NewtonSolver(...), dv.AffineSolver(...) or dv.PartitionedSolver(...)."
    )


def momenta(system: DiracSystem, q, v, t=0.0):
    r"""Consistent momenta ``p = ∂L/∂v(q, v, t)`` (the continuous Legendre transform)."""
    ensure_float64()
    q = check_state("q", q, system.n, system.coords)
    v = check_state("v", v, system.n, system.coords)
    return np.asarray(_momentum(system, q, v, check_float("t", t)))


@eqx.filter_jit
def _momentum(system, q, v, t):
    # the system is an argument, not part of a jitted bound method: its parameters
    # (lifted constants included) are arrays, which a static function cannot hash
    return system.momentum(q, v, t)
