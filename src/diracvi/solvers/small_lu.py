r"""``P A = L U`` with partial pivoting, and its solve, in plain elementwise XLA operations.

Column ``k`` of the elimination: the pivot row ``p ≥ k`` of the largest ``|a_pk|`` (the
first of equals, as LAPACK's ``idamax``), rows ``k`` and ``p`` exchanged by selects, the
multipliers ``l_ik = a_ik / a_kk`` stored below the diagonal and the rank-one update
``a_ij ← a_ij − l_ik a_kj`` (``i, j > k``). The solve of ``A x = b`` is
``y = P b`` (a gather by the kept permutation), ``L y′ = y`` forward and ``U x = y′``
backward, each a column-oriented sweep ``y ← y − y_j ℓ_j`` over whole vectors.

Why not LAPACK (``jax.scipy.linalg.lu_factor``): its ``getrf`` and ``trsm`` are custom
calls, and a ``while`` loop holding a custom call is never compiled as one kernel by
XLA's CPU backend (``small_while_loop_hoisting_pass``: a loop whose body accesses fewer
bytes than ``xla_cpu_small_while_loop_byte_threshold`` and holds no custom call becomes
one ``call`` emitted as straight machine code, instead of a graph of thunks dispatched
one by one). For the variable-step loop of a small circuit, whose cost is that dispatch
(``docs/performance.md``, "Counting thunks"), these operations let the whole loop be one
kernel (:mod:`diracvi.runtime.small_loops`). Straight-line code: for up to :data:`SMALL`
unknowns only.
"""

from __future__ import annotations

import jax.numpy as jnp

#: the most unknowns factored here (the elimination is unrolled: ``n`` stages of ``n × n``)
SMALL = 24


def lu_factor(a):
    """``(lu, perm)``: ``L`` (unit, below the diagonal) and ``U`` in one matrix, and the
    permutation ``perm`` with ``a[perm] = L U`` (not LAPACK's pivot sequence)."""
    n = a.shape[-1]
    rows = jnp.arange(n)
    perm = rows.astype(jnp.int32)
    for k in range(n):
        pivot = jnp.argmax(jnp.where(rows >= k, jnp.abs(a[:, k]), -1.0))
        row_k, row_p = a[k], a[pivot]
        at_k, at_p = (rows == k)[:, None], (rows == pivot)[:, None]
        a = jnp.where(at_k, row_p[None, :], jnp.where(at_p, row_k[None, :], a))
        perm_k, perm_p = perm[k], perm[pivot]
        perm = jnp.where(rows == k, perm_p, jnp.where(rows == pivot, perm_k, perm))
        if k == n - 1:
            break
        below = rows > k
        mult = jnp.where(below, a[:, k] / a[k, k], 0.0)
        right = jnp.where(below, a[k], 0.0)  # columns j > k of row k
        a = a - mult[:, None] * right[None, :]
        a = jnp.where(below[:, None] & (rows == k)[None, :], mult[:, None], a)
    return a, perm


def lu_solve(factors, b):
    """``x`` with ``A x = b`` from :func:`lu_factor`'s ``(lu, perm)``."""
    lu, perm = factors[0], factors[1]
    n = lu.shape[-1]
    rows = jnp.arange(n)
    y = b[perm]
    for j in range(n - 1):  # L y′ = y (unit diagonal)
        y = y - y[j] * jnp.where(rows > j, lu[:, j], 0.0)
    for j in range(n - 1, -1, -1):  # U x = y′
        xj = y[j] / lu[j, j]
        y = jnp.where(rows == j, xj, y - xj * jnp.where(rows < j, lu[:, j], 0.0))
    return y
