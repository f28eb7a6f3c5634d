r"""What a host run keeps: the chunk-by-chunk record and a whole run's trajectory.

:class:`March` accumulates the saved states and diagnostics of consecutive compiled
chunks (checkpoints, a failed step, the affine map's fallback); :func:`whole_run` turns
the packed output of a run that took every step in one chunk into a
:class:`~diracvi.driver.trajectory.Trajectory` at once, leaving what most callers never read in
the packed buffer until it is read (:class:`_Unpacked`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..errors import ModelError
from ..status import SolveStatus
from .trajectory import Trajectory

if TYPE_CHECKING:
    from .plan import Layout


class March:
    """The run so far: host-side arrays of the saved states and the chunk carry."""

    def __init__(
        self, system: Layout, q0, p0, k: int, save_states: bool, nodal: bool, stages=False
    ):
        self.system, self.k, self.save_states, self.nodal = system, k, save_states, nodal
        self.stages: list | None = [] if stages else None  # each chunk's stage records
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
        if self.stages is not None:
            self.stages.append(saved["stage"][:keep])
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
        code, message = self.status, SolveStatus.SUCCESS.summary
        if code and len(self.failure) == 1:
            message = self.failure[0]
        elif code:
            iterations, res_norm, q_bad = self.failure
            message = SolveStatus(code).explain(
                step=self.done,
                t=t0 + sign * h * self.done,
                iterations=iterations,
                res_norm=res_norm,
                coords=self.system.coords,
                q=q_bad,
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
            stage_record=np.concatenate(self.stages) if self.stages else None,
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


def run_fields(plan, run) -> dict:
    """The attributes of a whole run's :class:`Trajectory` that depend on the
    configuration only (made once per configuration by the warm-call path)."""
    scheme, discretization, h, steps, k, shape = run
    return dict(
        save_every=k,
        coords=shape.coords,
        constraint_names=shape.constraint_names,
        dt=h,
        scheme=scheme,
        discretization=discretization,
        system_name=shape.name,
        status=0,
        message=SolveStatus.SUCCESS.summary,
        solver=plan.describe(),
        steps_requested=steps,
    )


def whole_run(fields: dict, run, t0, layout, flat, x) -> Trajectory:
    """The trajectory of a run whose one chunk took every step: what :class:`March`
    builds in that case, every array left in the packed output ``flat`` (and the initial
    state in the chunk's input ``x``, a private copy) until it is read (see
    :class:`_Unpacked`). ``fields``: :func:`run_fields`."""
    return Trajectory._of_run(_Unpacked(layout, flat, x, t0, run), fields)


#: a Trajectory attribute → its name in a chunk's saved outputs
_SAVED_AS = {
    "multipliers": "mu",
    "constraint_residual": "con",
    "constraint_violation": "violation",
    "_p_nodal": "p_node",
    "_stage_record": "stage",
}


class _Unpacked:
    """The arrays of a whole run's :class:`Trajectory`, made from the packed chunk output
    on first access (as :class:`March` makes them): a warm call builds none of them."""

    names = frozenset(
        (
            "t",
            "q",
            "p",
            "energy",
            "step_index",
            "final_state",
            "multipliers",
            "constraint_residual",
            "constraint_violation",
            "newton_iterations",
            "_p_nodal",
            "_stage_record",
        )
    )
    __slots__ = ("_flat", "_layout", "_parts", "_run", "_t0", "_x")

    def __init__(self, layout, flat, x, t0, run):
        self._layout, self._flat, self._x, self._t0, self._run = layout, flat, x, t0, run
        self._parts = None

    def _initial(self, which: int):
        """``q0`` (0) or ``p0`` (1) from the chunk's input ``(h, t0, index, q, p, …)``."""
        n = self._layout.n
        return self._x[3 + which * n : 3 + (which + 1) * n]

    def __call__(self, name: str):
        layout, run = self._layout, self._run
        if name in ("t", "step_index"):
            index = np.arange(0, run.steps + 1, run.save_every)
            if name == "step_index":
                return index
            sign = 1.0 if run.scheme == "plus" else -1.0
            return self._t0 + sign * run.h * index
        if name == "energy":
            return layout.table(self._flat)[:, layout.columns["energy"]].copy()
        if name in ("q", "p"):
            col = layout.columns.get(name)
            if col is None:  # a run without saved states
                return None
            rows = layout.table(self._flat)
            return np.concatenate((self._initial(name == "p")[None], rows[:, col]))
        if self._parts is None:
            self._parts = layout.unpack(self._flat)
        carry, _, saved = self._parts
        if name == "final_state":
            return carry
        if name == "newton_iterations":
            return saved["iterations"]
        value = saved.get(_SAVED_AS[name])
        if value is None or name != "_p_nodal":
            return None if value is None else value.copy()
        return np.concatenate((self._initial(1)[None], value))  # the given p0 is the nodal one


class Selection(NamedTuple):
    """The columns a run keeps, ``simulate(..., save_only=names)``: positions of the
    coordinates ``coords`` (indices ``q_index``) and multipliers of the constraint rows
    ``rows`` (indices ``mu_index``), each in the order named."""

    coords: tuple
    rows: tuple
    q_index: np.ndarray
    mu_index: np.ndarray


def select_columns(save_only, coords, constraint_names) -> Selection:
    """``save_only`` (names of coordinates and of constraint rows) checked against the
    system's ``coords`` and ``constraint_names``."""
    if isinstance(save_only, str) or not hasattr(save_only, "__iter__"):
        raise ModelError(
            f"save_only={save_only!r}: a sequence of names (coordinates such as "
            f"{coords[:2]!r}, constraint rows such as {constraint_names[:2]!r}). Fix: pass "
            "a list or tuple, e.g. save_only=[name]."
        )
    names = tuple(save_only)
    if not names:
        raise ModelError(
            "save_only=(): no column to keep. Fix: name at least one coordinate or "
            "constraint row, or pass save_states=False for the final state alone."
        )
    q_of = {c: j for j, c in enumerate(coords)}
    mu_of = {c: j for j, c in enumerate(constraint_names)}
    unknown = [x for x in names if x not in q_of and x not in mu_of]
    if unknown:
        raise ModelError(
            f"save_only: {unknown[:5]!r} {'is' if len(unknown) == 1 else 'are'} neither a "
            f"coordinate nor a constraint row of the system (coordinates "
            f"{coords[:4]!r}…, rows {constraint_names[:4]!r}…). Fix: use names from "
            "system.coords and system.constraint_names."
        )
    if len(set(names)) != len(names):
        raise ModelError(f"save_only: a name appears twice in {names!r}; name each once.")
    chosen_q = tuple(x for x in names if x in q_of)
    chosen_mu = tuple(x for x in names if x not in q_of)
    return Selection(
        chosen_q,
        chosen_mu,
        np.array([q_of[x] for x in chosen_q], dtype=np.int64),
        np.array([mu_of[x] for x in chosen_mu], dtype=np.int64),
    )


def narrowed(traj: Trajectory, sel: Selection) -> Trajectory:
    """A whole trajectory cut to the chosen columns (the paths that form every state:
    the same values as they saved; see :class:`Selection`)."""
    return Trajectory(
        t=traj.t,
        q=traj.q[:, sel.q_index],
        p=None,
        multipliers=traj.multipliers[:, sel.mu_index],
        energy=None,
        constraint_residual=None,
        newton_iterations=traj.newton_iterations,
        constraint_violation=None,
        step_index=traj.step_index,
        final_state=traj.final_state,
        coords=sel.coords,
        constraint_names=sel.rows,
        save_every=traj.save_every,
        dt=traj.dt,
        scheme=traj.scheme,
        discretization=traj.discretization,
        system_name=traj.system_name,
        status=traj.status,
        message=traj.message,
        solver=traj.solver,
        steps_requested=traj.steps_requested,
    )
