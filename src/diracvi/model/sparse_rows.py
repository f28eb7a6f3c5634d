r"""Constant one-form rows kept sparse: ``B`` as the triples ``(row, column, value)``.

A circuit's Kirchhoff current law is ``B v = 0`` with ``B`` the node–branch incidence
matrix: each branch charge appears in the rows of its two nodes only, so ``B`` has
``2·branches`` non-zeros among ``nodes × coordinates`` entries. Stored densely it is
O(N²) in memory and every product is O(N²) in time (4.8 GB for a ladder of 10⁴ stages);
as triples both are O(nnz):

    (B v)_b = Σ_{e: row_e = b} value_e v_{col_e},      (Bᵀλ)_j = Σ_{e: col_e = j} value_e λ_{row_e}.

The triples are host constants (NumPy, read-only), so the rows' structure can be read
without tracing (which parts a row joins, the sparse step Jacobian's pattern) and a
compiled program holds them as constants. :class:`SparseRows` is hashable and compares
by value, so it can sit in a static field of a system.
"""

from __future__ import annotations

import hashlib

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError


def _frozen(a, dtype) -> np.ndarray:
    out = np.array(a, dtype=dtype, copy=True).reshape(-1)
    out.setflags(write=False)
    return out


class SparseRows:
    """The constant matrix ``B`` of shape ``(rows, columns)`` as its non-zero triples
    (duplicates summed, exact zeros dropped, ordered by row then column).

    ``B @ v`` (also for ``v`` of shape ``(columns, k)``), :meth:`transpose_apply`,
    :meth:`dense` and :meth:`to_scipy`.
    """

    __slots__ = ("_hash", "cols", "rows", "shape", "values")

    def __init__(self, rows, cols, values, shape):
        shape = tuple(int(s) for s in shape)
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        cols = np.asarray(cols, dtype=np.int64).reshape(-1)
        values = np.asarray(values, dtype=np.float64).reshape(-1)
        if not (rows.size == cols.size == values.size) or len(shape) != 2:
            raise ModelError(
                f"sparse one-forms: rows, columns and values have {rows.size}, {cols.size} "
                f"and {values.size} entries and the shape is {shape}; give one row and one "
                "column index per value and a 2-d shape."
            )
        if rows.size and (
            rows.min() < 0 or cols.min() < 0 or rows.max() >= shape[0] or cols.max() >= shape[1]
        ):
            raise ModelError(
                f"sparse one-forms of shape {shape} have an entry outside it (rows "
                f"{rows.min()}…{rows.max()}, columns {cols.min()}…{cols.max()})."
            )
        if not np.all(np.isfinite(values)):
            raise ModelError("sparse one-forms contain NaN or Inf: one-forms must be finite.")
        # canonical: duplicates summed, zeros dropped, row-major order (so equal matrices
        # compare and hash equal whatever order the triples came in)
        key = rows * shape[1] + cols
        order = np.argsort(key, kind="stable")
        key, values = key[order], values[order]
        if key.size:
            first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
            summed = np.add.reduceat(values, first)
            keep = summed != 0.0
            key, values = key[first][keep], summed[keep]
        self.rows = _frozen(key // max(shape[1], 1), np.int64)
        self.cols = _frozen(key % max(shape[1], 1), np.int64)
        self.values = _frozen(values, np.float64)
        self.shape = shape
        digest = hashlib.sha256()
        for a in (self.rows, self.cols, self.values):
            digest.update(a.tobytes())
        self._hash = hash((shape, digest.hexdigest()))

    @classmethod
    def from_scipy(cls, matrix) -> SparseRows:
        coo = matrix.tocoo()
        return cls(coo.row, coo.col, coo.data, coo.shape)

    # ------------------------------------------------------------- identity
    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other) -> bool:
        return (
            isinstance(other, SparseRows)
            and self._hash == other._hash
            and self.shape == other.shape
            and np.array_equal(self.rows, other.rows)
            and np.array_equal(self.cols, other.cols)
            and np.array_equal(self.values, other.values)
        )

    def __stored__(self):
        """What the program store's key prints (the arrays by value: they are baked in)."""
        return ("SparseRows", self.shape, self.rows, self.cols, self.values)

    def __repr__(self) -> str:
        return f"SparseRows(shape={self.shape}, nnz={self.nnz})"

    @property
    def nnz(self) -> int:
        return int(self.values.size)

    # ------------------------------------------------------------ products
    def __matmul__(self, v):
        """``B v`` (``v`` of shape ``(columns,)`` or ``(columns, k)``)."""
        v = jnp.asarray(v)
        coef = self.values.reshape((-1,) + (1,) * (v.ndim - 1))
        out = jnp.zeros((self.shape[0], *v.shape[1:]), dtype=v.dtype)
        return out.at[self.rows].add(coef * v[self.cols])

    def transpose_apply(self, lam):
        """``Bᵀ λ``."""
        lam = jnp.asarray(lam)
        out = jnp.zeros(self.shape[1], dtype=lam.dtype)
        return out.at[self.cols].add(self.values * lam[self.rows])

    def dense(self, dtype=jnp.float64):
        """``B`` as a dense JAX array (small systems and the dense checks only)."""
        return jnp.zeros(self.shape, dtype=dtype).at[self.rows, self.cols].add(self.values)

    def to_scipy(self):
        import scipy.sparse as sp

        return sp.csr_matrix((self.values, (self.rows, self.cols)), shape=self.shape)

    def shifted(self, row0: int, rows: int) -> SparseRows:
        """The same entries as rows ``row0 …`` of a matrix with ``rows`` rows."""
        return SparseRows(self.rows + row0, self.cols, self.values, (rows, self.shape[1]))

    @staticmethod
    def stack(parts, rows: int, columns: int) -> SparseRows | None:
        """``[(row0, SparseRows), …]`` placed in one ``(rows, columns)`` matrix (or None)."""
        if not parts:
            return None
        return SparseRows(
            np.concatenate([p.rows + r0 for r0, p in parts]),
            np.concatenate([p.cols for _, p in parts]),
            np.concatenate([p.values for _, p in parts]),
            (rows, columns),
        )


def is_scipy_sparse(value) -> bool:
    """Whether ``value`` is a SciPy sparse matrix or array (without importing SciPy for
    a value that cannot be one)."""
    if not type(value).__module__.startswith("scipy.sparse"):
        return False
    import scipy.sparse as sp

    return sp.issparse(value)
