r"""The operating point's Jacobian read through its pattern: a few compressed products
instead of one tangent per unknown.

The static equations ``r(x) = 0`` of :mod:`._operating_point` have a sparse Jacobian
``J = ∂r/∂x`` (``x = (v, μ, q_dep, i_hold)``): each branch meets its part and its nodes.
Formed by ``jax.jacfwd`` it takes one tangent per unknown through every part's law — on
a 144-transistor BSIM3 adder 2403 tangents, and a dense LU of 1300 unknowns, at every
Newton iterate of the point and of each gmin step. Here it is read as

.. math::

    (J s_c)_i = J_{ij} \quad \text{for the one column } j \text{ of colour } c
    \text{ in row } i,

one JVP per colour ``c`` (``s_c`` the sum of its columns' unit vectors), the columns
coloured greedily so that no two of a colour meet in a row; a row with more than
:data:`DENSE_ROW` entries (a supply node's KCL row meets every transistor on it, and
alone would need as many colours) is read whole by one transposed product (VJP) and
left out of the colouring. The matrix is assembled sparse and solved by SuperLU.

**The pattern** is the circuit's structure (:func:`structural`, modified nodal
analysis): a part's equations meet its own unknowns and the multipliers of the rows it
joins, an interaction row the unknowns of the parts it joins — every part's own block
taken full, a superset of the true pattern, so no entry is missed wherever the iterates
go (a pattern read off random probes was tried first: on ``ng_mosamp`` two probes
missed 259 entries of a level-2 MOSFET's charges, zero in the probes' regions, and its
point was not found). It is checked against the dense Jacobian at one random probe
(which the point computes anyway, to find the charges that enter the equations): an
entry there outside the structure (a row finite at the probe) sends the circuit back to
the dense Jacobian.

**When**: from :data:`MIN_SIZE` unknowns on, and where the products number at most a
quarter of the unknowns (:data:`SHARE`); smaller or densely coupled systems keep the dense Jacobian
(their points unchanged bit for bit).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: below this many unknowns the dense Jacobian is kept, bit for bit as before. It pays
#: well below (``ng_mosamp``, 514 unknowns: the point 85.9 → 20.3 CPU s, the same 396
#: iterations, its voltages 3.3e-13 apart), but a point that moves by round-off moves a
#: sensitive deck's steps, and no corpus deck under this size was re-run with it yet
MIN_SIZE = 1000
#: a row with more entries than this is read by a VJP (a hub: the supply's KCL row)
DENSE_ROW = 24
#: the products (JVPs and VJPs) allowed, as a share of the unknowns
SHARE = 0.25


class Plan(NamedTuple):
    """How to read the Jacobian: ``colour`` per column (-1 for none: a column met only
    by dense rows), the dense rows, and the sparse rows' entries ``(rows, cols)``."""

    colour: np.ndarray
    count: int  # colours
    dense: np.ndarray  # row indices read by VJPs
    rows: np.ndarray  # the sparse rows' entries
    cols: np.ndarray
    shape: tuple

    @property
    def products(self) -> int:
        return self.count + len(self.dense)

    def seeds(self) -> np.ndarray:
        """The JVP tangents, ``(count, size)``: each colour's columns summed."""
        out = np.zeros((max(self.count, 1), self.shape[1]))
        coloured = np.nonzero(self.colour >= 0)[0]
        out[self.colour[coloured], coloured] = 1.0
        return out

    def cotangents(self) -> np.ndarray:
        """The VJP cotangents, ``(len(dense), rows)`` (one zero row if there are none)."""
        out = np.zeros((max(len(self.dense), 1), self.shape[0]))
        out[np.arange(len(self.dense)), self.dense] = 1.0
        return out

    def assemble(self, jvps: np.ndarray, vjps: np.ndarray):
        """The Jacobian as ``(rows, cols, values)`` from ``jvps`` (``(count, rows)``) and
        ``vjps`` (``(len(dense), size)``)."""
        values = jvps[self.colour[self.cols], self.rows]
        d_rows = np.repeat(self.dense, self.shape[1])
        d_cols = np.tile(np.arange(self.shape[1]), len(self.dense))
        d_vals = np.asarray(vjps[: len(self.dense)]).reshape(-1)
        keep = d_vals != 0.0
        return (
            np.concatenate([self.rows, d_rows[keep]]),
            np.concatenate([self.cols, d_cols[keep]]),
            np.concatenate([values, d_vals[keep]]),
        )


def pattern(jacobians) -> np.ndarray:
    """The boolean pattern seen in dense Jacobians at probes: per row, the entries
    nonzero at the probes where that row is finite (forward mode spreads one non-finite
    partial over its whole row); a row finite at none is full."""
    jacobians = [np.asarray(j) for j in jacobians]
    out = np.zeros(jacobians[0].shape, bool)
    seen = np.zeros(jacobians[0].shape[0], bool)
    for jac in jacobians:
        finite = np.all(np.isfinite(jac), axis=1)
        out[finite] |= jac[finite] != 0.0
        seen |= finite
    out[~seen] = True
    return out


def structural(system, dep, held) -> np.ndarray | None:
    """The static equations' pattern from the circuit's structure (rows: the balance
    lines, the one-forms' rows, the held rows; columns ``x = (v, μ, q_dep, i_hold)``): a
    part's balance lines meet its own ``v``, ``q`` and multipliers and those of the
    interaction rows it joins; its own rows its ``v`` and ``q``; an interaction row the
    ``v`` and ``q`` of the parts it joins and its own multiplier (gmin). Every part's own
    block is taken full: a superset. ``None`` for a system that is not an
    interconnection of parts."""
    subs = getattr(system, "subsystems", None)
    if not subs:
        return None
    n, m = system.n, system.m
    d, h = len(dep), len(held)
    offsets = np.asarray(system._offsets)
    own_sizes = np.array([s.m for s in subs], dtype=np.int64)
    own_start = np.concatenate([[0], np.cumsum(own_sizes)[:-1]]).astype(np.int64)
    own = int(own_sizes.sum())
    row_subs = system.row_subsystems
    if own + len(row_subs) != m:
        return None
    q_col = np.full(n, -1, np.int64)
    q_col[dep] = n + m + np.arange(d)
    mask = np.zeros((n + m + h, n + m + d + h), bool)
    joins = [[] for _ in subs]
    for b, involved in enumerate(row_subs):
        for i in involved:
            joins[i].append(b)
    for i in range(len(subs)):
        coords = np.arange(offsets[i], offsets[i + 1])
        cols = np.concatenate([coords, q_col[coords][q_col[coords] >= 0]])
        mus = np.concatenate(
            [n + own_start[i] + np.arange(own_sizes[i]), n + own + np.asarray(joins[i], np.int64)]
        )
        lines = np.concatenate([coords, n + own_start[i] + np.arange(own_sizes[i])])
        mask[np.ix_(coords, mus.astype(np.int64))] = True
        mask[np.ix_(lines, cols)] = True
        for b in joins[i]:
            mask[n + own + b, cols] = True
    mask[n + np.arange(m), n + np.arange(m)] = True  # gmin on a node's row (a superset)
    held = np.asarray(held, np.int64)
    mask[n + held, n + m + d + np.arange(h)] = True  # i_hold enters its node's row
    mask[n + m + np.arange(h), n + held] = True  # φ_n − s·V_ic
    return mask


def plan(mask: np.ndarray) -> Plan | None:
    """The colouring of ``mask`` (rows × size) per the module doc, or ``None`` where the
    dense Jacobian is kept (small, or the products more than a quarter of the columns)."""
    n_rows, size = mask.shape
    if size < MIN_SIZE:
        return None
    degree = mask.sum(axis=1)
    dense = np.nonzero(degree > DENSE_ROW)[0]
    sparse = mask.copy()
    sparse[dense] = False
    rows, cols = np.nonzero(sparse)
    by_col = [[] for _ in range(size)]
    for i, j in zip(rows, cols, strict=True):
        by_col[j].append(i)
    used = [set() for _ in range(n_rows)]  # the colours each row already meets
    colour = np.full(size, -1, np.int64)
    # columns of most entries first (greedy colouring's usual order)
    for j in sorted(range(size), key=lambda j: -len(by_col[j])):
        if not by_col[j]:
            continue  # met only by dense rows (or by none): read by their VJPs
        taken = set().union(*(used[i] for i in by_col[j]))
        c = 0
        while c in taken:
            c += 1
        colour[j] = c
        for i in by_col[j]:
            used[i].add(c)
    count = int(colour.max()) + 1 if np.any(colour >= 0) else 0
    found = Plan(colour, count, dense, rows, cols, (n_rows, size))
    if found.products > SHARE * size:
        return None
    return found
