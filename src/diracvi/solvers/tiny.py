r"""Tiny linear algebra as elementwise code: ``y = A x`` and ``max_i |v_i|`` for short
vectors, written so that XLA fuses them with their neighbours.

A per-step check of a small model, vectorized over the steps of a run, is a product
``(r × c) · (c × steps)`` or a reduction ``max_i |v_i|`` over ``c ≤ 16`` entries per
step. Written as ``dot`` / ``max(axis=-1)``, XLA's CPU backend hands each to a library
kernel (Eigen, YNNPACK) of its own: a separate launch and a pass over memory for a few
thousand multiply–adds. Unrolled over the short axis,

    y_i = Σ_j A_ij x_j = (…(A_i1 x_1 + A_i2 x_2) + …) + A_ic x_c,
    max_i |v_i| = max(…max(|v_1|, |v_2|)…, |v_c|),

both are elementwise operations on the long (steps) axis, which XLA fuses into the
loop that produces ``x`` or consumes ``y``. Beyond :data:`TINY` the library calls are
faster and these fall back to them.
"""

from __future__ import annotations

from functools import reduce

import jax.numpy as jnp

#: the longest axis that is unrolled (a product unrolls ``c`` multiply–adds of length r)
TINY = 16


def matvec(a, x):
    """``a @ x`` over the last axes, broadcast over the leading ones: ``a`` (…, r, c),
    ``x`` (…, c) ↦ (…, r). ``c`` elementwise multiply–adds when ``c ≤`` :data:`TINY`
    (summed in the order of ``j``), else ``a @ x``."""
    cols = a.shape[-1]
    if cols == 0 or cols > TINY:
        return jnp.matmul(a, x[..., None])[..., 0]
    terms = (a[..., j] * x[..., j, None] for j in range(cols))
    return reduce(jnp.add, terms)


def max_abs(v):
    """``max_i |v_i|`` over the last axis (0 for an empty axis, NaN if any entry is NaN):
    ``jnp.max(jnp.abs(v), axis=-1, initial=0.0)``, as an elementwise chain when the axis
    is at most :data:`TINY` long."""
    size = v.shape[-1]
    if size == 0 or size > TINY:
        return jnp.max(jnp.abs(v), axis=-1, initial=0.0)
    return reduce(jnp.maximum, (jnp.abs(v[..., i]) for i in range(size)))
