r"""The plan of a partitioned step, made once per system structure and scheme: alike
subsystems grouped, the interface slots of every row, the local orders and bands, and
the tiles of the step's unknowns (see the package docstring)."""

from __future__ import annotations

import dataclasses
import itertools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ...model.interconnect import InterconnectedSystem
from ...model.stacked import structure_key as _structure_key
from .. import banded as _banded
from ..sparsity import step_pattern
from .interface import (
    _local_order,
)


# ------------------------------------------------------------------------------ plan
@dataclasses.dataclass(frozen=True, eq=False)
class _Group:
    """Subsystems stepped together (host-side index tables; G members, all alike).

    A member's unknowns ``y_i`` are in the local order of :func:`_local_order` (``s =
    copies·(n + m)`` of them); its interface rows come in ``copies`` copies, copy-major:
    local row ``j·rows_each + r`` is copy ``j`` of its ``r``-th row."""

    members: np.ndarray  # (G,) subsystem indices
    n: int  # coordinates per member
    m: int  # own multipliers per member
    rows_each: int  # interface rows per member (each in `copies` copies)
    copies: int
    perm: np.ndarray  # (s,) local unknown/equation i = the own step's perm[i]
    y_index: np.ndarray  # (G, s) positions of the local unknowns in x
    rows: np.ndarray  # (G, copies·rows_each) the stage rows each member is involved in
    slots: np.ndarray  # (G, copies·rows_each) the slot (stage row, member) of each
    ports: tuple[np.ndarray, ...]  # (member, local row, local column, coefficient): the
    # entries of connections and of constant sparse rows
    general: tuple[np.ndarray, ...]  # (member, local row, row of general_forms)
    # T[e, s'] += coefficient · w_(row of e) · P_member[row, column], at (position, row of e)
    assembly: tuple[np.ndarray, ...]


@dataclasses.dataclass(frozen=True, eq=False)
class _Plan:
    groups: tuple[_Group, ...]
    size: int  # len(x)
    lam_at: tuple[int, ...]  # copy j of λ is x[lam_at[j] : lam_at[j] + base_rows]
    base_rows: int  # l
    rows: int  # stage rows: copies · l, copy-major
    slots: int  # interface unknowns
    band: tuple[int, int] | None  # (kl, ku) of T in slot order; (1, 1): tridiagonal
    subsystems: int
    slot_row: np.ndarray  # (slots,)
    slot_sub: np.ndarray  # (slots,)
    first_slot: np.ndarray  # (rows,) the slot λ_b is read from
    sigma_terms: tuple[np.ndarray, ...]  # (equation, slot, coefficient) of the σ's
    flux_coef: np.ndarray  # (slots,) coefficient of c_b in each equation
    fixed: tuple[np.ndarray, ...]  # (position in T, ±1): the g terms of the equations

    @property
    def tridiagonal(self) -> bool:
        return self.band == (1, 1)

    @property
    def width(self) -> int:
        """Entries stored per row of ``T``."""
        return self.slots if self.band is None else self.band[0] + self.band[1] + 1


def _slot_equations(slots_of_row):
    """``Σ_s C_g[e,s] g_s + w_b (Σ_s C_σ[e,s] σ_s + C_c[e] c_b) = 0`` for each slot e of row
    b, as sparse triples: the swap form for two sides, the direct form otherwise."""
    cg, cs, cc = [], [], {}
    for sides in slots_of_row:
        if len(sides) == 2:
            left, right = sides
            cg += [(left, left, -1.0), (left, right, 1.0), (right, left, 1.0), (right, right, -1.0)]
            cs += [(left, left, -2.0), (right, right, -2.0)]
            cc[left] = cc[right] = 1.0
            continue
        first = sides[0]
        cs += [(first, s, 1.0) for s in sides]  # w (Σσ − c) = 0
        cc[first] = -1.0
        for prev, cur in itertools.pairwise(sides):  # λ_prev − λ_cur = 0
            cg += [(cur, prev, 1.0), (cur, cur, -1.0)]
            cs += [(cur, prev, 1.0), (cur, cur, -1.0)]
            cc[cur] = 0.0
    return cg, cs, cc


#: plans by the system's PyTree structure (static fields included) and scheme: a plan
#: depends on nothing else, and a traced step asks for it several times per trace
_PLANS: dict = {}
_PLANS_SIZE = 16


def _build_plan(system: InterconnectedSystem, scheme: str, copies: int = 1) -> _Plan:
    """Index tables for one system (host side, at trace time: O(N + slots) work, once
    per structure)."""
    try:
        leaves, treedef = jax.tree.flatten(system)
        shapes = tuple((jnp.shape(x), jnp.result_type(x)) if eqx.is_array(x) else x for x in leaves)
        key = (treedef, shapes, scheme, copies)
        hit = _PLANS.get(key)
    except TypeError:  # an unhashable static field: no caching
        return _new_plan(system, scheme, copies)
    if hit is None:
        hit = _PLANS[key] = _new_plan(system, scheme, copies)
        while len(_PLANS) > _PLANS_SIZE:
            _PLANS.pop(next(iter(_PLANS)))
    return hit


def _new_plan(system: InterconnectedSystem, scheme: str, copies: int) -> _Plan:
    subs = system.subsystems
    count = len(subs)
    n_total = system.n
    stages = copies - 1
    q_start = np.asarray(system._offsets[:-1])
    mu_sizes = np.array([s.m for s in subs], dtype=np.int64)
    mu_rel = np.concatenate([[0], np.cumsum(mu_sizes)[:-1]]).astype(np.int64)
    own = int(mu_sizes.sum())
    nrows = len(system.interaction_names)
    m_total = own + nrows
    # where copy j of the coordinates and of the multipliers starts in x (the step's
    # layout: [q_other, μ, S_1 … S_s, ν_1 … ν_s], see _equations.split_stage)
    q_at = [0, *(n_total + m_total + (j - 1) * n_total for j in range(1, copies))]
    nu_at = n_total + m_total + stages * n_total
    mu_at = [n_total, *(nu_at + (j - 1) * m_total for j in range(1, copies))]
    lam_at = tuple(at + own for at in mu_at)

    # slots: one per (stage row, subsystem involved); ordered by row, then copy, then
    # subsystem, so that a chain's T stays banded (copy-major would spread it by l)
    slot_row, slot_sub, slots_of_row = [], [], [[] for _ in range(copies * nrows)]
    base_rows_of_sub = [[] for _ in range(count)]
    slot_of = {}
    for b, involved in enumerate(system.row_subsystems):
        for i in involved:
            base_rows_of_sub[i].append(b)
        for j in range(copies):
            for i in involved:
                slot_of[(j * nrows + b, i)] = len(slot_row)
                slots_of_row[j * nrows + b].append(len(slot_row))
                slot_row.append(j * nrows + b)
                slot_sub.append(i)
    nslots = len(slot_row)
    # a member's stage rows, copy-major (its local order)
    rows_of_sub = [[j * nrows + b for j in range(copies) for b in rs] for rs in base_rows_of_sub]
    slots_of_sub = [[slot_of[(t, i)] for t in rs] for i, rs in enumerate(rows_of_sub)]

    # which rows are connections (coefficients ±1) or constant sparse rows (their
    # entries, as a connection's) and which come from general_forms
    pairs = zip(system._port_index, system._port_rows, strict=True)
    port_of_row = {int(row): ((int(a), 1.0), (int(b), -1.0)) for (a, b), row in pairs}
    sparse = system.incidence()
    if sparse is not None:
        for row, col, val in zip(
            sparse.rows.tolist(), sparse.cols.tolist(), sparse.values.tolist(), strict=True
        ):
            port_of_row.setdefault(row, ())
            port_of_row[row] += ((col, val),)
    general_of_row = {int(row): k for k, row in enumerate(system._form_row_index())}

    # groups: same structure and the same number of interface rows
    keyed: dict = {}
    for i, sub in enumerate(subs):
        keyed.setdefault((_structure_key(sub), len(base_rows_of_sub[i])), []).append(i)

    cg, cs, cc = _slot_equations(slots_of_row)
    equations_of_slot: dict[int, list] = {}
    for e, s, val in cs:
        equations_of_slot.setdefault(s, []).append((e, val))
    positions = [(e, s) for e, s, _ in cg]

    raw_groups = []
    for (_, nrow), members in keyed.items():
        members = np.asarray(members, dtype=np.int64)
        n, m = subs[members[0]].n, subs[members[0]].m
        coords = [q_at[j] + q_start[members, None] + np.arange(n) for j in range(copies)]
        mults = [mu_at[j] + mu_rel[members, None] + np.arange(m) for j in range(copies)]
        y_index = np.concatenate(
            [
                np.stack(coords, axis=-1).reshape(len(members), n * copies),
                np.stack(mults, axis=-1).reshape(len(members), m * copies),
            ],
            axis=1,
        )
        shape = (len(members), nrow * copies)
        rows = np.array([rows_of_sub[i] for i in members], dtype=np.int64).reshape(shape)
        slots = np.array([slots_of_sub[i] for i in members], dtype=np.int64).reshape(shape)
        ports, general = [], []
        for k, i in enumerate(members):
            for r, b in enumerate(base_rows_of_sub[i]):
                if b in port_of_row:
                    for col, val in port_of_row[b]:
                        if q_start[i] <= col < q_start[i] + n:
                            ports.append((k, r, col - q_start[i], val))
                else:
                    general.append((k, r, general_of_row[b]))
        assembly = []
        for k, i in enumerate(members):
            for r, s in enumerate(slots_of_sub[i]):
                for e, val in equations_of_slot.get(s, ()):
                    for c, s2 in enumerate(slots_of_sub[i]):
                        assembly.append((e, s2, k, r, c, -val))
                        positions.append((e, s2))
        raw_groups.append((members, n, m, nrow, y_index, rows, slots, ports, general, assembly))

    pos = np.array(positions, dtype=np.int64).reshape(-1, 2)
    kl = int(max(0, (pos[:, 0] - pos[:, 1]).max(initial=0)))
    ku = int(max(0, (pos[:, 1] - pos[:, 0]).max(initial=0)))
    if kl <= 1 and ku <= 1:
        band = (1, 1)  # tridiagonal (the storage of a band (1, 1))
    elif _banded.worth_it(nslots, kl, ku):
        band = (kl, ku)
    else:
        band = None
    width = nslots if band is None else band[0] + band[1] + 1

    def position(e, s):
        return e * width + s if band is None else e * width + (s - e + band[0])

    slot_row_arr = np.asarray(slot_row, dtype=np.int64)
    groups = []
    for members, n, m, nrow, y_index, rows, slots, ports, general, assembly in raw_groups:
        pt = np.array(ports, dtype=np.float64).reshape(-1, 4)
        gn = np.array(general, dtype=np.int64).reshape(-1, 3)
        asm = np.array(assembly, dtype=np.float64).reshape(-1, 6)
        groups.append(
            _Group(
                members=members,
                n=n,
                m=m,
                rows_each=nrow,
                copies=copies,
                perm=_local_order(n, m, copies),
                y_index=y_index,
                rows=rows,
                slots=slots,
                ports=(*(pt[:, j].astype(np.int64) for j in range(3)), pt[:, 3]),
                general=tuple(gn[:, j] for j in range(3)),
                assembly=(
                    np.array([position(int(e), int(s)) for e, s in asm[:, :2]], dtype=np.int64),
                    slot_row_arr[asm[:, 0].astype(np.int64)],
                    *(asm[:, j].astype(np.int64) for j in (2, 3, 4)),
                    asm[:, 5],
                ),
            )
        )
    cs_arr = np.array(cs, dtype=np.float64).reshape(-1, 3)
    cg_arr = np.array(cg, dtype=np.float64).reshape(-1, 3)
    first = np.full(copies * nrows, -1, dtype=np.int64)
    for t, here in enumerate(slots_of_row):
        first[t] = here[0]
    return _Plan(
        groups=tuple(groups),
        size=(n_total + m_total) * copies,
        lam_at=lam_at,
        base_rows=nrows,
        rows=copies * nrows,
        slots=nslots,
        band=band,
        subsystems=count,
        slot_row=slot_row_arr,
        slot_sub=np.asarray(slot_sub, dtype=np.int64),
        first_slot=first,
        sigma_terms=(cs_arr[:, 0].astype(np.int64), cs_arr[:, 1].astype(np.int64), cs_arr[:, 2]),
        flux_coef=np.array([cc.get(s, 0.0) for s in range(nslots)], dtype=np.float64),
        fixed=(
            np.array([position(int(e), int(s)) for e, s in cg_arr[:, :2]], dtype=np.int64),
            cg_arr[:, 2],
        ),
    )


def _local_band(group: _Group, system, rule, scheme: str):
    """``(kl, ku)`` of every member's ``K_i = J_i + G_i W H_i``, or ``None`` for dense.

    ``J_i``'s pattern comes from ``_sparsity.step_pattern``;
    ``G_i W H_i = (s/h) B_iᵀ W B_i`` couples the columns one interface row touches: for
    a connection within the group that is one column (a diagonal entry) per member and
    row. A row of ``general_forms`` may touch any column, so its groups stay dense. The
    band is used in the given order of the unknowns when it is narrow enough to pay
    (``_banded.worth_it``).
    """
    if group.general[0].size:
        return None
    first = system._member(int(group.members[0]))  # in full, also when packed
    key = (_structure_key(first), type(rule), rule.name, scheme)
    perm = group.perm
    pattern = step_pattern(first, rule, scheme, key)[np.ix_(perm, perm)]  # local order
    a, b = _aug_entries(group)
    pattern[a, b] = True
    kl, ku = _banded.bandwidths(pattern)
    return (kl, ku) if _banded.worth_it(perm.size, kl, ku) else None


def _port_cliques(group: _Group):
    """The local columns of each (member, row) that touches more than one of them."""
    k, r, c, _ = group.ports
    if not k.size:
        return []
    which = k * max(group.rows_each, 1) + r
    order = np.argsort(which, kind="stable")
    which, c = which[order], c[order]
    starts = np.flatnonzero(np.r_[True, which[1:] != which[:-1]])
    ends = np.r_[starts[1:], which.size]
    return [np.unique(c[a:b]) for a, b in zip(starts, ends, strict=True) if b - a > 1]


def _port_pairs(group: _Group):
    """The coordinate pairs ``(c, c')`` that ``B_iᵀ W B_i`` couples, over the union of the
    members' port columns: static tables."""
    pairs = {(col, col) for col in group.ports[2].tolist()}
    for cols in _port_cliques(group):
        pairs.update((a, b) for a in cols.tolist() for b in cols.tolist())
    pairs = np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)
    return pairs[:, 0], pairs[:, 1]


def _aug_entries(group: _Group):
    """The entries ``(a, b)`` of ``G_i W H_i`` in the local order: every copy of each
    coordinate pair of :func:`_port_pairs`, shape (pairs, copies, copies)."""
    c, c2 = _port_pairs(group)
    k = np.arange(group.copies)
    rows = c[:, None, None] * group.copies + k[None, :, None]
    cols = c2[:, None, None] * group.copies + k[None, None, :]
    return np.broadcast_arrays(rows, cols)


def _tile(group: _Group):
    """``(coordinate starts, multiplier starts)``, one per copy, if the members' unknowns
    lie side by side in ``x`` (copy j of member k's coordinates at ``start_j + k n …``,
    of its multipliers at ``start_μj + k m …``), else ``None``."""
    count, n, m, copies = len(group.members), group.n, group.m, group.copies
    coords = group.y_index[:, : n * copies].reshape(count, n, copies)
    mults = group.y_index[:, n * copies :].reshape(count, m, copies)
    starts = []
    for index, size in ((coords, n), (mults, m)):
        at = []
        for j in range(copies):
            first = int(index[0, 0, j]) if size else 0
            want = first + np.arange(count * size).reshape(count, size)
            if size and not np.array_equal(index[:, :, j], want):
                return None
            at.append(first)
        starts.append(tuple(at))
    return starts[0], starts[1]


def _uniform_ports(group: _Group):
    """The (rows × n) matrix ``E`` with ``B_i = E`` for every member, if only
    connections touch the group and at the same local rows, columns and signs; else
    ``None``."""
    if group.general[0].size:
        return None
    count = len(group.members)
    k, r, c, val = group.ports
    if k.size % count:
        return None
    each = k.size // count
    order = np.lexsort((c, r, k))
    table = np.stack([r[order], c[order], val[order]], axis=1).reshape(count, each, 3)
    if not (
        np.array_equal(k[order], np.repeat(np.arange(count), each)) and (table == table[:1]).all()
    ):
        return None
    e = np.zeros((group.rows_each, group.n))
    e[table[0, :, 0].astype(np.int64), table[0, :, 1].astype(np.int64)] = table[0, :, 2]
    return e


#: from this many unknowns on, ``x`` is assembled by in-place updates, not a concatenation
#: (below it a concatenation is faster: 2.1 against 3.6 ms per step at 10⁴)
CONCATENATE_MAX = 1 << 16


def _concatenate_tiles(pieces, size: int):
    """``x`` of length ``size`` from ``(start, values)`` pieces that tile it exactly, by one
    concatenation (``None`` if they leave a gap or overlap)."""
    pieces = sorted((p for p in pieces if p[1].shape[0]), key=lambda p: p[0])
    at = 0
    for start, values in pieces:
        if start != at:
            return None
        at += values.shape[0]
    if at != size:
        return None
    if size < CONCATENATE_MAX:
        return jnp.concatenate([values for _, values in pieces])
    # Large: written piece by piece into one buffer. XLA fuses a concatenation into each
    # of its consumers (the finiteness checks, the slices of the next step) and the
    # fused loops cost 2–5× a step at 10⁵ unknowns (measured: 155 → 66 ms per step, the
    # same bits); in-place updates are written once. The buffer starts as the largest
    # piece padded (one pass over it), not as zeros that every piece then overwrites.
    big = max(range(len(pieces)), key=lambda i: pieces[i][1].shape[0])
    start, values = pieces[big]
    out = jnp.pad(values, (start, size - start - values.shape[0]))
    for i, (start, values) in enumerate(pieces):
        if i != big:
            out = jax.lax.dynamic_update_slice(out, values, (start,))
    return out


# ------------------------------------------------------------------------- numerics
def _stack(plan: _Plan, system) -> tuple:
    """Each group's array leaves, stacked along a new leading axis (under the first
    member's structure: only the names differ).

    Done once per chunk, in ``init``, and carried in the solver state: stacked inside the
    time loop, every subsystem's leaves would be separate operands of every step. A
    packed system (``InterconnectedSystem._packed``) holds them stacked already: a
    group is then a slice of its stacks (no per-subsystem operand at all).
    """
    if system._packing is not None:
        return tuple(system._packing.group_stack(g.members) for g in plan.groups)
    out = []
    for g in plan.groups:
        parts = [eqx.partition(system.subsystems[int(i)], eqx.is_array)[0] for i in g.members]
        leaves = zip(*(jax.tree.leaves(a) for a in parts), strict=True)
        out.append(
            jax.tree.unflatten(jax.tree.structure(parts[0]), [jnp.stack(xs) for xs in leaves])
        )
    return tuple(out)
