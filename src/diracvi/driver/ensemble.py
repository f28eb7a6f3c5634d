r"""``simulate_ensemble``: many initial states of one system, advanced in one compiled call.

The chunk program of :func:`~diracvi.simulate` is vmapped over the initial states, so
the affine step map becomes one matrix–matrix product per step for the whole ensemble,
and Newton runs batched. Each member fails (and freezes) on its own; the others go on.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError, StepFailure
from ..model.system import DiracSystem
from ..model.validate import check_float, check_state
from ..status import SolveStatus
from .simulate import check_run, prepared_plan
from .trajectory import Trajectory


class Ensemble:
    """``B`` runs of one system that differ only in their initial state.

    Attributes:
        t: times of the saved states, (S+1,).
        q, p: (B, S+1, n) (``None`` with ``save_states=False``); after a member's
            failure its remaining entries are NaN.
        multipliers, constraint_residual: (B, S, m) or ``None``.
        energy, constraint_violation, newton_iterations: (B, S).
        status: (B,) failure code of each member (0 = every step taken).
        steps: (B,) steps each member took.
        final_q, final_p: (B, n), the last state each member reached.
        solver: the stepping method that ran.

    ``ens[i]`` is member i as a :class:`Trajectory` (with its failure message).
    """

    def __init__(self, **fields):
        self.__dict__.update(fields)

    def __len__(self) -> int:
        return len(self.status)

    @property
    def success(self) -> bool:
        return bool(np.all(self.status == 0))

    @property
    def final_q(self) -> np.ndarray:
        return self.final_state[0]

    @property
    def final_p(self) -> np.ndarray:
        return self.final_state[1]

    def __getitem__(self, i: int) -> Trajectory:
        if not -len(self) <= i < len(self):
            raise IndexError(f"member {i} out of range for an ensemble of {len(self)}")
        saved = int(self.saved[i])
        q = p = mu = con = p_nodal = None
        if self.q is not None:
            q, p = self.q[i, : saved + 1], self.p[i, : saved + 1]
            if getattr(self, "p_nodal", None) is not None:
                p_nodal = self.p_nodal[i, : saved + 1]
            mu, con = self.multipliers[i, :saved], self.constraint_residual[i, :saved]
        code = int(self.status[i])
        message = "success"
        if code:
            steps = int(self.steps[i])
            its, res, q_bad = self.failure[i]
            message = SolveStatus(code).explain(
                step=steps,
                t=self.t0 + self.sign * self.dt * steps,
                iterations=its,
                res_norm=res,
                coords=self.coords,
                q=q_bad,
            )
        return Trajectory(
            t=self.t0 + self.sign * self.dt * self.step_index[i, : saved + 1],
            q=q,
            p=p,
            p_nodal=p_nodal,
            multipliers=mu,
            energy=self.energy[i, :saved],
            constraint_residual=con,
            newton_iterations=self.newton_iterations[i, :saved],
            constraint_violation=self.constraint_violation[i, :saved],
            step_index=self.step_index[i, : saved + 1],
            save_every=self.save_every,
            final_state=tuple(a[i] for a in self.final_state),
            coords=self.coords,
            constraint_names=self.constraint_names,
            dt=self.dt,
            scheme=self.scheme,
            discretization=self.discretization,
            system_name=self.system_name,
            status=code,
            message=message,
            steps_requested=self.steps_requested,
            solver=self.solver,
        )

    def __repr__(self) -> str:
        failed = int(np.sum(self.status != 0))
        return (
            f"Ensemble(system={self.system_name!r}, members={len(self)}, "
            f"steps={self.steps_requested}, dt={self.dt}, solver={self.solver!r}, "
            f"failed={failed})"
        )


def _check_batch(arg, value, n, coords):
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelError(f"{arg} is not a numeric array: pass shape (members, {n}).") from exc
    if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] == 0:
        raise ModelError(
            f"{arg} has shape {arr.shape}; an ensemble needs shape (members, {n}): one row "
            f"per member, one column per coordinate {tuple(coords)}."
        )
    if not np.all(np.isfinite(arr)):
        row = int(np.nonzero(~np.all(np.isfinite(arr), axis=1))[0][0])
        check_state(f"{arg}[{row}]", arr[row], n, coords)  # raises, naming the coordinates
    return arr


def simulate_ensemble(
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
    project_initial: bool = False,
) -> Ensemble:
    r"""Integrate ``B`` initial states ``q0[b], p0[b]`` (arrays of shape (B, n)) at once.

    Arguments are those of :func:`~diracvi.simulate`; the members share the system,
    step and solver, and are advanced together in one compiled call. With
    ``throw=True`` a failed member raises :class:`StepFailure` carrying the ensemble
    (``.trajectory``) after every member has run.
    """
    run = check_run(system, scheme, discretization, dt, steps, save_every, solver)
    scheme, discretization, h, steps, k, shape = run
    q0 = _check_batch("q0", q0, shape.n, shape.coords)
    p0 = _check_batch("p0", p0, shape.n, shape.coords)
    if q0.shape != p0.shape:
        raise ModelError(
            f"q0 has shape {q0.shape} but p0 has shape {p0.shape}: give one momentum row "
            "per position row."
        )
    t0 = check_float("t0", t0)
    plan = prepared_plan(system, run, solver, q0[0], p0[0], t0)
    q0, p0 = plan.checker.check_batch(q0, p0, project_initial=bool(project_initial), t0=t0)
    clock = np.array([t0, 0.0])

    members, m = len(q0), shape.m
    carry0 = (q0, p0, q0, np.zeros((members, m)))
    affine = plan.step_map is not None
    fallback_from = None
    carry, fail, saved = plan.chunk(affine, k, bool(save_states), steps // k, batched=True)(
        plan.h_array, clock, carry0
    )
    if affine and np.any(fail[0] == SolveStatus.AFFINE_REJECTED):
        affine, fallback_from = False, 0
        carry, fail, saved = plan.chunk(False, k, bool(save_states), steps // k, batched=True)(
            plan.h_array, clock, carry0
        )
    n_good = saved["n_good"]  # (B, blocks)
    full = n_good == k
    whole = np.where(full.all(axis=1), full.shape[1], np.argmin(full, axis=1))
    rows = np.arange(members)
    partial = (whole < full.shape[1]) & (n_good[rows, np.minimum(whole, full.shape[1] - 1)] > 0)
    count = whole + partial  # saved records kept per member
    steps_done = np.where(full, k, np.minimum(n_good, k))
    kept = np.arange(full.shape[1])[None, :] < count[:, None]
    step_index = np.concatenate(
        [np.zeros((members, 1), np.int64), np.cumsum(np.where(kept, steps_done, 0), axis=1)],
        axis=1,
    )

    everything = bool(kept.all())

    def mask(a, extra_leading=0):
        if everything:  # no member failed: nothing to blank (and no copy of big arrays)
            return a
        a = np.array(a, dtype=np.float64)
        pad = np.ones((members, extra_leading), bool)
        keep = np.concatenate([pad, kept], axis=1)
        a[~keep] = np.nan  # boolean index over the (member, record) axes
        return a

    q = p = mu = con = p_nodal = None
    if save_states:
        q = mask(np.concatenate([q0[:, None], saved["q"]], axis=1), 1)
        p = mask(np.concatenate([p0[:, None], saved["p"]], axis=1), 1)
        mu, con = mask(saved["mu"]), mask(saved["con"])
        if "p_node" in saved:
            p_nodal = mask(np.concatenate([p0[:, None], saved["p_node"]], axis=1), 1)
    status = np.where(count < full.shape[1], fail[0], 0)
    sign = 1.0 if scheme == "plus" else -1.0
    ensemble = Ensemble(
        t=t0 + sign * h * np.arange(steps // k + 1) * k,
        q=q,
        p=p,
        p_nodal=p_nodal,
        multipliers=mu,
        constraint_residual=con,
        energy=mask(saved["energy"]),
        constraint_violation=mask(saved["violation"]),
        newton_iterations=np.where(kept, saved["iterations"], 0),
        status=status,
        steps=step_index[rows, count],
        saved=count,
        step_index=step_index,
        final_state=carry,
        failure=list(zip(fail[1], fail[2], fail[3], strict=True)),
        coords=shape.coords,
        constraint_names=shape.constraint_names,
        system_name=shape.name,
        dt=h,
        t0=t0,
        sign=sign,
        scheme=scheme,
        discretization=discretization,
        save_every=k,
        steps_requested=steps,
        solver=plan.describe(fallback_from, "the affine check failed for some member")
        if fallback_from is not None
        else plan.describe(),
    )
    if throw and not ensemble.success:
        bad = int(np.argmax(status != 0))
        raise StepFailure(
            f"{int(np.sum(status != 0))} of {members} members failed; the first, member "
            f"{bad}: {ensemble[bad].message}",
            ensemble,
        )
    return ensemble
