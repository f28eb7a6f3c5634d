r"""Pointwise subspace algebra in float64 NumPy: bases, kernels, distances, comparisons.

Every subspace is stored as an orthonormal basis *of rows*. Ranks are decided by the
singular values against ``RANK_RTOL · max(1, σ_max)``: the data here (one-form matrices,
bases of Dirac structures) are O(1), so an absolute floor keeps tiny-but-nonzero matrices
from being promoted to full rank by round-off.
"""

from __future__ import annotations

import numpy as np

#: relative singular-value threshold for numerical rank
RANK_RTOL = 1e-10


def _threshold(s: np.ndarray, rtol: float) -> float:
    return rtol * max(1.0, float(s[0]) if s.size else 0.0)


def rank(mat, rtol: float = RANK_RTOL) -> int:
    """Numerical rank of ``mat``."""
    mat = np.atleast_2d(np.asarray(mat, dtype=np.float64))
    if mat.size == 0:
        return 0
    s = np.linalg.svd(mat, compute_uv=False)
    return int(np.sum(s > _threshold(s, rtol)))


def row_basis(mat, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis (rows) of the row space of ``mat``; shape (rank, ncols)."""
    mat = np.atleast_2d(np.asarray(mat, dtype=np.float64))
    ncols = mat.shape[1]
    if mat.shape[0] == 0:
        return np.zeros((0, ncols))
    _, s, vt = np.linalg.svd(mat, full_matrices=False)
    r = int(np.sum(s > _threshold(s, rtol)))
    return vt[:r]


def kernel_basis(mat, rtol: float = RANK_RTOL) -> np.ndarray:
    """Orthonormal basis (rows) of ``{x : mat @ x = 0}``; shape (ncols − rank, ncols)."""
    mat = np.atleast_2d(np.asarray(mat, dtype=np.float64))
    ncols = mat.shape[1]
    if mat.shape[0] == 0:
        return np.eye(ncols)
    _, s, vt = np.linalg.svd(mat, full_matrices=True)
    r = int(np.sum(s > _threshold(s, rtol)))
    return vt[r:]


def projector(basis: np.ndarray) -> np.ndarray:
    """Orthogonal projector onto the span of the orthonormal rows of ``basis``."""
    return basis.T @ basis


def distance(basis: np.ndarray, x) -> float:
    """Euclidean distance of ``x`` from the span of the orthonormal rows of ``basis``."""
    x = np.asarray(x, dtype=np.float64)
    return float(np.linalg.norm(x - basis.T @ (basis @ x)))


def subspace_gap(b1: np.ndarray, b2: np.ndarray) -> float:
    """``‖P₁ − P₂‖₂``: the sine of the largest principal angle (1 if dimensions differ)."""
    if b1.shape[0] != b2.shape[0]:
        return 1.0
    if b1.shape[0] == 0:
        return 0.0
    return float(np.linalg.norm(projector(b1) - projector(b2), ord=2))


def block_diag(*mats) -> np.ndarray:
    """Block-diagonal matrix of 2-D arrays (rows and columns concatenated)."""
    mats = [np.atleast_2d(np.asarray(m, dtype=np.float64)) for m in mats]
    rows = sum(m.shape[0] for m in mats)
    cols = sum(m.shape[1] for m in mats)
    out = np.zeros((rows, cols))
    r = c = 0
    for m in mats:
        out[r : r + m.shape[0], c : c + m.shape[1]] = m
        r, c = r + m.shape[0], c + m.shape[1]
    return out


def batched_rowspace_residual(forms: np.ndarray, vecs: np.ndarray, rtol: float = RANK_RTOL):
    r"""For each k, ``r_k − A_kᵀ ν_k`` with ``ν_k`` the least-squares multipliers.

    ``forms`` has shape (K, m, n) (rows = one-forms), ``vecs`` (K, n). Returns
    ``(residual (K, n), ν (K, m))``: the component of ``r_k`` outside ``span A_k`` (its
    norm is the distance of ``r_k`` from the annihilator ``Δ°``) and the minimum-norm
    multipliers reproducing the rest. Rank is decided per k, so redundant one-forms are
    fine (their multipliers are then only defined up to the kernel; ν is the min-norm one).
    """
    forms = np.asarray(forms, dtype=np.float64)
    vecs = np.asarray(vecs, dtype=np.float64)
    k, m, _n = forms.shape
    if m == 0:
        return vecs.copy(), np.zeros((k, 0))
    # A_kᵀ = U S Vᵀ; the least-squares ν = V S⁺ Uᵀ r over the numerically nonzero σ.
    u, s, vt = np.linalg.svd(np.transpose(forms, (0, 2, 1)), full_matrices=False)
    floor = rtol * np.maximum(1.0, s[:, :1])
    keep = s > floor
    coeff = np.einsum("kni,kn->ki", u, vecs) * keep
    inside = np.einsum("kni,ki->kn", u, coeff)
    s_inv = np.where(keep, 1.0 / np.where(keep, s, 1.0), 0.0)
    nu = np.einsum("kij,ki->kj", vt, coeff * s_inv)
    return vecs - inside, nu
