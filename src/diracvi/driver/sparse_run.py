"""A run stepped by the circuit-scale sparse affine map (:mod:`..solvers.sparse_affine`):
the host loop's arrays made into a :class:`~diracvi.Trajectory` as the chunked path
makes them (saved states every ``save_every`` steps, diagnostics of each saved step)."""

from __future__ import annotations

import numpy as np

from ..solvers.sparse_affine import NotSparseAffine
from .record import run_fields
from .trajectory import Trajectory


def run_sparse(plan, run, q0, p0, t0, save_states: bool, selection=None):
    """The trajectory, or ``None`` when the map's verification rejected a step (the
    plan then drops the map, and the caller steps with the general solver, which says
    so in ``traj.solver``). ``selection``: a :class:`~.record.Selection`, the run keeps
    only those columns (:meth:`~diracvi.solvers.sparse_affine.SparseAffineMap.run_selected`)."""
    scheme, _, h, steps, k, shape = run
    nodal = save_states and plan.nodal_when_saved
    share = plan.rule.impulse_share()
    q0, p0 = np.asarray(q0), np.asarray(p0)
    try:
        if selection is None:
            out = plan.sparse.run(q0, p0, float(t0), steps, k, save_states, nodal, share)
        else:
            out = plan.sparse.run_selected(
                q0, p0, float(t0), steps, k, selection.q_index, selection.mu_index
            )
    except NotSparseAffine as exc:
        plan.sparse = None
        plan.affine_reason = f"the sparse affine map was rejected: {exc}"
        return None
    n = shape.n
    z, y = out["z"], out["y"]
    q_end, p_end = z[:n], z[n:]
    sign = 1.0 if scheme == "plus" else -1.0
    index = np.arange(0, steps + 1, k, dtype=np.int64)
    if selection is not None:
        fields = {
            **run_fields(plan, run),
            "solver": plan.sparse.describe,
            "coords": selection.coords,
            "constraint_names": selection.rows,
        }
        return Trajectory(
            t=t0 + sign * h * index,
            q=out["q"],
            p=None,
            multipliers=out["mu"],
            energy=None,
            constraint_residual=None,
            newton_iterations=np.zeros(len(index) - 1, dtype=np.int64),
            constraint_violation=None,
            step_index=index,
            final_state=(q_end, p_end, q_end - y[:n], y[n:]),
            **fields,
        )
    return Trajectory(
        t=t0 + sign * h * index,
        q=out["q"],  # (the initial state first, as written by the map's run)
        p=out["p"],
        p_nodal=out["node"],
        multipliers=out["mu"],
        energy=out["energy"],
        constraint_residual=out["con"],
        newton_iterations=np.zeros(len(index) - 1, dtype=np.int64),
        constraint_violation=out["violation"],
        step_index=index,
        final_state=(q_end, p_end, q_end - y[:n], y[n:]),
        **{**run_fields(plan, run), "solver": plan.sparse.describe},
    )
