r"""Is the step solvable? The rank of the step Jacobian ``∂r/∂(q_other, μ)``.

A singular Jacobian means the step equations leave some directions undetermined — a
degenerate Lagrangian whose velocity-free coordinates no constraint fixes (a massless
port left unconnected), or a capacitor loop under the left-point rule. We find it before
stepping, from the SVD of the row- and column-equilibrated Jacobian, and name what is
undetermined (right null space → unknowns) and which equations clash (left null space).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..errors import UnsolvableStepError

#: A system larger than this is not checked densely (O(n³)); issue-level solvers check
#: their own blocks.
DENSE_CHECK_LIMIT = 3000


def _equilibrate(jac: np.ndarray) -> np.ndarray:
    rows = np.max(np.abs(jac), axis=1, keepdims=True)
    jac = jac / np.where(rows > 0, rows, 1.0)
    cols = np.max(np.abs(jac), axis=0, keepdims=True)
    return jac / np.where(cols > 0, cols, 1.0)


def _involved(vectors: np.ndarray, names: Sequence[str]) -> list[str]:
    weight = np.max(np.abs(vectors), axis=1)
    return [name for name, w in zip(names, weight, strict=True) if w > 1e-6]


def null_directions(jac: np.ndarray, rtol: float = 1e-11):
    """``(right, left)`` null-space bases of the equilibrated Jacobian (columns)."""
    scaled = _equilibrate(np.asarray(jac, dtype=np.float64))
    u, s, vt = np.linalg.svd(scaled)
    tol = rtol * max(scaled.shape) * (s[0] if s.size else 1.0)
    rank = int(np.sum(s > tol))
    return vt[rank:].T, u[:, rank:]


def singular_members(jacs: np.ndarray, rtol: float = 1e-11) -> np.ndarray:
    """Which Jacobians of a stack (members, N, N) are rank-deficient or not finite: the
    rank test of :func:`null_directions`, batched (one stacked SVD). A screen: a flagged
    member is then checked by :func:`check_step_jacobian`, which names what is wrong."""
    jacs = np.asarray(jacs, dtype=np.float64)
    finite = np.all(np.isfinite(jacs), axis=(1, 2))
    if jacs.shape[1] >= _LU_FROM and jacs.shape[1] == jacs.shape[2]:
        # large: a stacked SVD is O(members · N³); a sparse LU recognises the clearly
        # regular ones first (as check_step_jacobian does), the SVD decides the rest
        flagged = ~finite
        for i in np.nonzero(finite)[0]:
            if not _clearly_regular(_equilibrate(jacs[i])):
                flagged[i] = null_directions(jacs[i], rtol)[0].shape[1] > 0
        return flagged
    safe = np.where(finite[:, None, None], jacs, 0.0)
    rows = np.max(np.abs(safe), axis=2, keepdims=True)
    scaled = safe / np.where(rows > 0, rows, 1.0)
    cols = np.max(np.abs(scaled), axis=1, keepdims=True)
    scaled = scaled / np.where(cols > 0, cols, 1.0)
    s = np.linalg.svd(scaled, compute_uv=False)
    tol = rtol * max(scaled.shape[1:]) * np.where(s[:, :1] > 0, s[:, :1], 1.0)
    rank = np.sum(s > tol, axis=1)
    return ~finite | (rank < min(scaled.shape[1:]))


#: from this many unknowns on, a clearly regular Jacobian is recognised by a sparse LU
_LU_FROM = 200
#: every pivot of the equilibrated Jacobian's LU at least this large: clearly regular
_CLEAR_PIVOT = 1e-8


def _clearly_regular(scaled: np.ndarray) -> bool:
    """Whether the (equilibrated, entries ≤ 1) Jacobian is regular by a wide margin: its
    sparse LU has every pivot ≥ :data:`_CLEAR_PIVOT`, far above the SVD's rank threshold
    (≈ 1e-11·n). A structural defect (an unconnected port, a capacitor loop) makes a
    pivot vanish to round-off, and then the SVD below names it; a model's step Jacobian
    is sparse, so this costs far less than the SVD (a torn chain of 1000 masses: ≈ 6 s →
    tens of milliseconds). Only a borderline case can slip through: its step then fails
    and the failing step's status says so."""
    from scipy.sparse import csc_matrix
    from scipy.sparse.linalg import splu

    try:
        lu = splu(csc_matrix(scaled))
    except RuntimeError:  # exactly singular
        return False
    return bool(np.min(np.abs(lu.U.diagonal()), initial=np.inf) >= _CLEAR_PIVOT)


#: how far (in the unknowns' own units) :func:`regular_nearby` moves along a null direction
_PROBE_SIZES = (1e-8, 1e-6, 1e-4, 1e-2, 1.0)


def regular_nearby(jacobian_at, x0: np.ndarray, jac: np.ndarray) -> bool:
    """Whether the Jacobian turns regular when the unknowns move along its null direction.

    A structural defect (an unconnected port, a capacitor loop under the left-point rule)
    leaves the Jacobian singular at every point. A *state-dependent* near-singularity does
    not: a floating sub-circuit tied to the rest only by reverse-biased junctions is held
    by their ``G_min`` alone where every diode is off (a conductance ~1e-12 beside ~1e-3:
    rank-deficient to the check's tolerance), and moving its common-mode potential turns
    some junction on. The step solver handles such a point (the LU solve is accurate to
    the conductance ratio), so it is not refused. ``jacobian_at(x)`` is the step Jacobian
    at the unknowns ``x``; ``x0`` the point where ``jac`` was formed."""
    rows = np.max(np.abs(jac), axis=1, keepdims=True)
    scaled = jac / np.where(rows > 0, rows, 1.0)
    cols = np.max(np.abs(scaled), axis=0)
    cols = np.where(cols > 0, cols, 1.0)
    right, _ = null_directions(jac)
    if right.shape[1] == 0:
        return True
    direction = np.sum(right / cols[:, None], axis=1)  # back to the unknowns' units
    direction = direction / max(np.max(np.abs(direction)), 1e-300)
    for size in _PROBE_SIZES:
        for sign in (1.0, -1.0):
            probe = np.asarray(jacobian_at(x0 + sign * size * direction), dtype=np.float64)
            if np.all(np.isfinite(probe)) and null_directions(probe)[0].shape[1] == 0:
                return True
    return False


def check_step_jacobian(
    jac: np.ndarray,
    *,
    unknown_names: Sequence[str],
    equation_names: Sequence[str],
    where: str,
    jacobian_at=None,
    x0=None,
) -> None:
    """Raise :class:`UnsolvableStepError` if the step Jacobian is rank-deficient (and,
    given ``jacobian_at(x)`` and the point ``x0`` of ``jac`` (or a function forming it),
    stays so when the unknowns
    move along the null direction: see :func:`regular_nearby`)."""
    if not np.all(np.isfinite(jac)):
        bad = [equation_names[i] for i in np.nonzero(~np.all(np.isfinite(jac), axis=1))[0]]
        raise UnsolvableStepError(
            f"The step equations are not solvable at this state ({where}): their Jacobian "
            f"is not finite in {bad}. Fix: check the model for divisions by zero or "
            "functions evaluated outside their domain at the initial state."
        )
    if jac.shape[0] >= _LU_FROM and jac.shape[0] == jac.shape[1]:
        if _clearly_regular(_equilibrate(np.asarray(jac, dtype=np.float64))):
            return
    right, left = null_directions(jac)
    if right.shape[1] == 0:
        return
    start = x0() if callable(x0) else x0  # (a callable: formed only when needed)
    if jacobian_at is not None and regular_nearby(jacobian_at, np.asarray(start), jac):
        return
    undetermined = _involved(right, unknown_names)
    clashing = _involved(left, equation_names)
    raise UnsolvableStepError(
        f"The step equations are not solvable at this state ({where}): the step Jacobian "
        f"has {right.shape[1]} null direction(s). Undetermined unknowns: "
        f"{', '.join(undetermined)}. Dependent equations: {', '.join(clashing)}. "
        "This happens when a degenerate Lagrangian (no velocity term for some coordinates) "
        "leaves those coordinates unfixed by the constraints — for example an unconnected "
        "port variable, or a loop of capacitors under the left-point rule. Fix: add or "
        "connect the missing constraint, give the coordinate a velocity term, or try "
        "discretization='midpoint'."
    )
