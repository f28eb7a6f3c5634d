r"""The structure of a circuit-scale step Jacobian, known before any value is computed.

A part's columns (its ``q``, ``p``, increment and own multipliers) can touch only its own
equations and the interaction rows it is in; an interaction row's multiplier ``λ_b`` only
the equations of the parts row ``b`` joins — the pattern of modified nodal analysis.
:func:`structural_pattern` turns it into compressed-JVP seeds: parts that share no row
get the same seed (a greedy colouring), so the number of JVPs ``K`` is a few times the
largest part's size, whatever the number of parts. It depends on the system and the
rule only, not on the step size, so the variable-step path builds it once for all its
step sizes (:mod:`diracvi.driver.adaptive_sparse`).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..discretization.equations import unknown_count


class NotSparseAffine(Exception):
    """The sparse path does not apply (the reason is the message)."""


#: the last few systems' tables (keyed by identity; a build per step size asks again,
#: and on a 10⁴-part circuit each walk of the parts costs a good fraction of a second)
_TABLES: dict = {}


def _by_identity(system, name, make):
    """``make(system)``, kept for the few systems seen last (the system held with it, so
    its id cannot be reused while the entry lives)."""
    hit = _TABLES.get((id(system), name))
    if hit is not None and hit[0] is system:
        return hit[1]
    value = make(system)
    _TABLES[(id(system), name)] = (system, value)
    while len(_TABLES) > 8:
        _TABLES.pop(next(iter(_TABLES)))
    return value


def driving(system) -> list[int]:
    """The indices of the time-dependent parts (sources) of an interconnection."""
    return _by_identity(
        system, "driving", lambda s: [i for i, sub in enumerate(s.subsystems) if sub.time_dependent]
    )


def _structure(system):
    """Host-side index tables: per part its columns in ``w = (q, p, y)`` and rows, per
    interaction row its multiplier's column and equation, and who touches whom."""
    return _by_identity(system, "structure", _tables)


def _tables(system):
    n = system.n
    subs = system.subsystems
    offsets = np.asarray(system._offsets)
    mu_sizes = np.array([s.m for s in subs], dtype=np.int64)
    mu_start = n + np.concatenate([[0], np.cumsum(mu_sizes)[:-1]]).astype(np.int64)
    own = int(mu_sizes.sum())
    rows_of_sub = [[] for _ in subs]
    row_subs = [tuple(int(i) for i in r) for r in system.row_subsystems]
    for b, involved in enumerate(row_subs):
        for i in involved:
            rows_of_sub[i].append(b)
    return offsets, mu_start, mu_sizes, own, row_subs, rows_of_sub


def _greedy(count, neighbours):
    """A greedy colouring: ``color[i]`` differs from every neighbour's."""
    color = np.full(count, -1, dtype=np.int64)
    for i in range(count):
        taken = {int(color[j]) for j in neighbours(i) if color[j] >= 0}
        c = 0
        while c in taken:
            c += 1
        color[i] = c
    return color


def _ranges(starts, sizes):
    """``(which, index)``: ``starts[k] + 0 … sizes[k] − 1`` for every ``k`` in turn, and
    the ``k`` of each."""
    which = np.repeat(np.arange(len(starts), dtype=np.int64), sizes)
    first = np.cumsum(sizes) - sizes
    return which, starts[which] + np.arange(which.size) - first[which]


def _pattern(system, rule):
    """Seeds ``(K, 2n + U)`` and the structural entries ``(seed, row, column)`` of the
    residual (rows in ``[0, U)``) and of the momentum lines (rows ``U + [0, n)``)."""
    if rule.stages:
        raise NotSparseAffine("a staged rule (its stages are not in this path)")
    n, size = system.n, unknown_count(system, rule)
    offsets, mu_start, mu_sizes, own, row_subs, rows_of_sub = _structure(system)
    count = len(system.subsystems)
    sub_color = _greedy(count, lambda i: {j for b in rows_of_sub[i] for j in row_subs[b] if j != i})
    row_color = _greedy(
        len(row_subs), lambda b: {c for i in row_subs[b] for c in rows_of_sub[i] if c != b}
    )
    local = 3 * np.diff(offsets) + mu_sizes  # q, p, increment and own μ of each part
    width = np.zeros(int(sub_color.max(initial=-1)) + 1, dtype=np.int64)
    np.maximum.at(width, sub_color, local)
    first_seed = np.concatenate([[0], np.cumsum(width)])
    row_seed0 = int(first_seed[-1])
    seeds_count = row_seed0 + int(row_color.max(initial=-1)) + 1
    lam0 = 2 * n + n + own  # column of λ_0 in w
    seeds = np.zeros((seeds_count, 2 * n + size))
    # the parts, one layout (coordinates, own multipliers, rows it is in) at a time: every
    # array of a layout's parts is one (parts, …) array (a loop over 3·10⁵ parts of a
    # 10⁵-stage ladder, a dozen NumPy calls each, was seconds). The entries come out
    # grouped by layout, not part by part: the matrices built from them are the same
    # (scipy's COO → CSR conversion sorts each row's columns)
    degree = np.array([len(r) for r in rows_of_sub], dtype=np.int64)
    entries = []  # arrays (seed, row, column)
    for nc, m, d in np.unique(np.stack([np.diff(offsets), mu_sizes, degree], axis=1), axis=0):
        members = np.flatnonzero((np.diff(offsets) == nc) & (mu_sizes == m) & (degree == d))
        coords = offsets[members][:, None] + np.arange(nc)
        mus = mu_start[members][:, None] + np.arange(m)
        cols = np.concatenate([coords, n + coords, 2 * n + coords, 2 * n + mus], axis=1)
        seed = first_seed[sub_color[members]][:, None] + np.arange(cols.shape[1])
        seeds[seed, cols] = 1.0
        joined = np.array([rows_of_sub[i] for i in members], dtype=np.int64)
        rows = np.concatenate(
            [coords, mus, n + own + joined.reshape(len(members), d), size + coords], axis=1
        )
        width_r, width_c = rows.shape[1], cols.shape[1]
        entries.append(
            (
                np.repeat(seed, width_r, axis=1).ravel(),  # each column against every row
                np.tile(rows, (1, width_c)).ravel(),
                np.repeat(cols, width_r, axis=1).ravel(),
            )
        )
    # the interaction rows: λ_b touches the coordinates' and own multipliers' equations
    # and the momentum lines of the parts row b joins, as (row, part) pairs
    lengths = np.array([len(r) for r in row_subs], dtype=np.int64)
    pair_b = np.repeat(np.arange(len(row_subs), dtype=np.int64), lengths)
    pair_i = np.fromiter(itertools.chain.from_iterable(row_subs), np.int64, int(lengths.sum()))
    at_c, c_idx = _ranges(offsets[pair_i], np.diff(offsets)[pair_i])
    at_m, m_idx = _ranges(mu_start[pair_i], mu_sizes[pair_i])
    rb = np.concatenate([pair_b[at_c], pair_b[at_m], pair_b[at_c]])
    seeds[row_seed0 + row_color, lam0 + np.arange(len(row_subs))] = 1.0
    entries.append((row_seed0 + row_color[rb], np.concatenate([c_idx, m_idx, size + c_idx]),
                    lam0 + rb))  # fmt: skip
    seed_of, row_of, col_of = (
        np.concatenate(e).astype(np.int64) for e in zip(*entries, strict=True)
    )
    return seeds, seed_of, row_of, col_of


#: the seeds and structural entries of a system's step Jacobians (independent of ``h``):
#: pass it to :func:`~diracvi.solvers.sparse_affine.build` to build maps for several step
#: sizes without recomputing it
structural_pattern = _pattern
