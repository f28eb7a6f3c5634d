r"""Banded matrices: a Jacobian from ``kl + ku + 1`` JVPs, LU with partial pivoting, solves.

A matrix ``A`` (s × s) with lower bandwidth ``kl`` and upper bandwidth ``ku`` (``A[i, j] = 0``
unless ``−kl ≤ j − i ≤ ku``) is stored by rows, ``R[i, d] = A[i, i − kl + d]``
(``d = 0 … kl + ku``; entries outside the matrix are zero): O(s·b) numbers.

**Jacobian** (Curtis–Powell–Reid). Columns ``j`` and ``j'`` with ``j ≡ j' (mod c)``,
``c = kl + ku + 1``, touch disjoint rows, so the ``c`` products ``J·e_(color k)`` with
``e_(color k) = Σ_(j ≡ k) e_j`` hold every entry once: ``J[i, j] = (J e_(j mod c))[i]``.
That is ``c`` forward-mode passes, O(s·c) work, instead of the ``s`` of a dense
``jax.jacfwd``.

**Factorization** ``P A = L U``, Gaussian elimination with partial pivoting as LAPACK's
``gbtrf``: at step ``k`` the pivot is the largest of the ``kl + 1`` candidates
``|A[k … k+kl, k]|``, so every multiplier has ``|l| ≤ 1`` (the same growth bound as a
dense pivoted LU), and row swaps widen ``U`` to ``kl + ku`` superdiagonals. Only
``kl + 1`` rows are ever active: a ``lax.scan`` over ``k`` carries them as a window
``C`` (rows ``k … k+kl``, columns ``k … k+kl+ku``), emits ``U[k, k … k+kl+ku]``, the
``kl`` multipliers and the pivot, and takes in row ``k + kl + 1``. Work O(s·kl·(kl+ku)),
memory O(s·(2kl+ku)); a solve is two scans, O(s·(2kl+ku)).

Everything here is for one matrix; callers ``jax.vmap`` over a group of them.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

#: scan iterations unrolled per loop trip: a trip of XLA's loop costs about as much as
#: the few small operations of one elimination or substitution step
UNROLL = 8


def bandwidths(pattern: np.ndarray) -> tuple[int, int]:
    """``(kl, ku)`` of a boolean (s × s) pattern: the largest ``i − j`` and ``j − i``."""
    rows, cols = np.nonzero(pattern)
    if rows.size == 0:
        return 0, 0
    return int(max(0, (rows - cols).max())), int(max(0, (cols - rows).max()))


def worth_it(size: int, kl: int, ku: int) -> bool:
    """Is the band clearly cheaper than a dense inverse (applied at O(s²) per solve)?"""
    return (2 * kl + ku + 1) * 4 <= size


def seeds(size: int, kl: int, ku: int) -> np.ndarray:
    """The ``c`` seed vectors (c × s): ``e_(color k) = Σ_(j ≡ k mod c) e_j``."""
    c = kl + ku + 1
    out = np.zeros((c, size))
    out[np.arange(size) % c, np.arange(size)] = 1.0
    return out


def from_products(products, kl: int, ku: int):
    """``R`` (s × (kl+ku+1)) from the products ``J·e_(color k)`` (c × s) of :func:`seeds`."""
    c, size = products.shape
    col = np.arange(size)[:, None] - kl + np.arange(kl + ku + 1)[None, :]  # A[i, col]
    inside = (col >= 0) & (col < size)
    values = products[np.where(inside, col, 0) % c, np.arange(size)[:, None]]
    return jnp.where(jnp.asarray(inside), values, 0.0)


def lu(rows, kl: int, ku: int):
    """``P A = L U`` of the banded ``A`` given by rows ``R`` (s × (kl+ku+1)).

    Returns ``(U, L, pivots)``: ``U[k] = U[k, k … k+kl+ku]``, ``L[k]`` the ``kl``
    multipliers of step ``k`` and ``pivots[k] ∈ [0, kl]`` the offset of the row swapped
    with row ``k``. A zero pivot (a singular ``A``) gives non-finite factors, as a dense
    LU's inverse does, which Newton reports as a singular step.
    """
    size = rows.shape[0]
    width = kl + ku + 1
    if kl == 0:  # nothing below the diagonal: A = U already
        return rows, jnp.zeros((size, 0), rows.dtype), jnp.zeros(0, jnp.int32)
    padded = jnp.concatenate([rows, jnp.zeros((kl + 1, width), rows.dtype)])
    # the first window: rows 0 … kl, columns 0 … kl+ku (row t starts at column t − kl)
    first = jnp.stack(
        [
            jnp.concatenate([padded[t, kl - t :], jnp.zeros(kl - t, rows.dtype)])
            for t in range(kl + 1)
        ]
    )
    offsets = jnp.arange(kl + 1)

    def eliminate(window, entering):
        pivot = jnp.argmax(jnp.abs(window[:, 0]))
        is_pivot = (offsets == pivot)[:, None]
        top = window[0]
        chosen = jnp.sum(jnp.where(is_pivot, window, 0.0), axis=0)
        window = jnp.where(is_pivot, top, window)  # the old top row takes the pivot's place
        mult = window[1:, 0] / chosen[0]
        rest = window[1:, 1:] - mult[:, None] * chosen[None, 1:]
        rest = jnp.concatenate([rest, jnp.zeros((kl, 1), rows.dtype)], axis=1)
        return jnp.concatenate([rest, entering[None]]), (chosen, mult, pivot.astype(jnp.int32))

    _, (upper, lower, pivots) = jax.lax.scan(
        eliminate, first, padded[kl + 1 :][:size], unroll=UNROLL
    )
    return upper, lower, pivots


def solve(factors, b, kl: int, ku: int):
    """``x`` with ``A x = b`` from the factors of :func:`lu`; ``b`` is (s,) or (s, r)."""
    upper, lower, pivots = factors
    size = upper.shape[0]
    tail = b.shape[1:]
    if kl:
        padded = jnp.concatenate([b, jnp.zeros((kl + 1, *tail), b.dtype)])
        offsets = jnp.arange(kl + 1).reshape(-1, *(1,) * len(tail))

        def forward(window, inputs):
            mult, pivot, entering = inputs
            is_pivot = offsets == pivot
            chosen = jnp.sum(jnp.where(is_pivot, window, 0.0), axis=0)
            window = jnp.where(is_pivot, window[0], window)
            rest = window[1:] - mult.reshape(-1, *(1,) * len(tail)) * chosen
            return jnp.concatenate([rest, entering[None]]), chosen

        _, b = jax.lax.scan(
            forward, padded[: kl + 1], (lower, pivots, padded[kl + 1 :][:size]), unroll=UNROLL
        )
    span = kl + ku
    if span == 0:
        return b / upper[:, 0].reshape(-1, *(1,) * len(tail))

    def backward(later, inputs):  # later = (x[k+1], …, x[k+span])
        u, y = inputs
        coef = u[1:].reshape(-1, *(1,) * len(tail))
        x = (y - jnp.sum(coef * later, axis=0)) / u[0]
        return jnp.concatenate([x[None], later[:-1]]), x

    start = jnp.zeros((span, *tail), b.dtype)
    _, x = jax.lax.scan(backward, start, (upper, b), reverse=True, unroll=UNROLL)
    return x
