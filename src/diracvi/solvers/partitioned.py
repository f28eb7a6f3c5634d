r"""Newton's method on an interconnection's step equations, solved subsystem by subsystem.

The step equations of an :class:`~diracvi.InterconnectedSystem` with subsystems
``i = 1..M`` and interaction rows ``B`` (l × N) are, for the unknowns
``y_i = (q_other_i, μ_i)`` and ``λ``::

    ρ_i(y_i) + G_i λ = 0        ρ_i = [p_left_i + A_iᵀ μ_i − p_i ; ω^i_d],  G_i = [B_iᵀ ; 0]
    α_d = B(node) v_k = 0       (l rows)

(``p_right`` replaces ``p_left`` for the (−) scheme). ``B`` is evaluated at the known
configuration, so ``α_d`` is linear in the unknowns with ``∂α_d/∂y_i = H_i = (s/h)[B_i, 0]``
(``s = +1`` for "plus", ``−1`` for "minus"). Newton's correction solves::

    J_i dy_i + G_i dλ = a_i   (each i),        Σ_i H_i dy_i = c.

**Why not the plain Schur complement** ``S = Σ_i H_i J_i⁻¹ G_i``: it needs every local
Jacobian ``J_i`` to be invertible, and torn models are built from pieces that cannot be
stepped alone. Under the left-point ("retraction") rule the massless port ``q̄`` of a torn
spring chain, the capacitor side of the torn RLC circuit and the gyrator of the DC motor
all have a zero row and column in ``J_i`` (the paper: "the second piece alone cannot be
stepped; joined, it can"). So the interface is written with *Robin* data instead, as in
two-Lagrange-multiplier FETI methods: for every interface row ``b`` and every subsystem
``i`` it involves, a slot unknown ``g_{b,i}`` with

    λ_b = g_{b,i} + w_b σ_{b,i},      σ_{b,i} = (H_i dy_i)_b    (subsystem i's share of α_b)

turns subsystem i's equations into ``K_i dy_i = a_i − G_i g_i`` with
``K_i = J_i + G_i W H_i`` (``W = diag(w_b) > 0``), which is invertible for a massless
port, a capacitor or a gyrator alike (``G_i W H_i = (s/h) B_iᵀ W B_i`` has the sign of
``J_i``'s mass block under both schemes). The interface conditions — all ``λ_{b,i}``
equal, ``Σ_i σ_{b,i} = c_b`` — become a linear system ``T g = t`` over the slots. This is
an exact reformulation: ``T`` is invertible exactly when the whole step Jacobian is
(given invertible ``K_i``), and any ``w > 0`` gives the same Newton step; ``w_b`` is only
chosen for conditioning, as the mean over its subsystems of ``h max|J_i| / max|B_i|²``
(so that ``G_i W H_i`` is of the size of ``J_i``).

For a row joining two subsystems L and R the two slot equations are written as

    g_R − g_L + w_b (c_b − 2 σ_L) = 0,        g_L − g_R + w_b (c_b − 2 σ_R) = 0

(their sum is the flux condition, their difference ``λ_L = λ_R``). Each involves only one
side's outputs, so a chain of subsystems — slots ordered by row, sides by subsystem —
gives a *tridiagonal* ``T`` of size ``2(M − 1)``, solved in O(M) by
``jax.lax.linalg.tridiagonal_solve`` (LAPACK ``gtsv``, partial pivoting). Rows that
involve one or three or more subsystems use the direct form (``w_b(Σσ − c) = 0`` and
``λ_{b,i−1} = λ_{b,i}``); an interface that is not tridiagonal in the given row order
but narrow-banded (``_banded.worth_it``: the stage copies of a chain's rows, below) is
solved by a banded LU with partial pivoting, and any other (a star, a loop, a
configuration-dependent ``Interaction``, which involves every subsystem) with a dense LU
of ``T``: O(slots³) — fine for a few hundred rows, not for a large general mesh.

Work per linear solve is O(Σ_i s_i² + l) with stored factors, O(Σ_i s_i³ + l) with a
refactorization; nothing is ever O(N · l). Subsystems with the same PyTree structure
(static fields included, names aside) and the same leaf shapes — the equal segments of
a torn chain — are grouped at trace time and stepped with ``jax.vmap``: their residuals,
Jacobians, factors and solves are single batched operations. The local factors are kept
as explicit inverses ``K_i⁻¹`` (from a pivoted LU): on CPU, XLA applies a batch of small
inverses as one batched product many times faster than a batch of triangular solves, and
they are applied at every iteration of every step while reused; the converged ``x`` is
fixed by the residual test, not by them.

**Banded local factors.** A group whose ``K_i`` has a narrow band in the given order of
its unknowns — a chain piece: diagonal masses under the left-point rule, tridiagonal
stiffness under the midpoint rule, and a connection only adds to the diagonal — is
factorized as a banded LU with partial pivoting instead
(``_solvers._banded``): the band is read once per group structure from
``J_i``'s sparsity pattern (``_solvers._sparsity``), ``J_i`` is formed from
``kl + ku + 1`` compressed JVPs instead of ``s`` and solves cost O(s·(2kl+ku)) instead
of O(s²) per member, so a step is O(N) for pieces of any size. Pivoting keeps the
multipliers ≤ 1 as in the dense LU; the two agree to round-off. Groups with a row of
``general_forms`` (which may touch every column) or a wide band keep dense inverses
(``local_factors="dense"`` forces them everywhere). A group whose members' unknowns lie
side by side in ``x`` is read and written as a reshaped slice, and connections at the
same local places of every member act through one small matrix: no N-sized index tables.

**Stages stay local ("lobatto").** Under the order-4 rule a subsystem's step has the
unknowns ``y_i = (q_other_i, S_i, μ_i, ν_i)`` — its two stage unknowns ``S_i`` (n × 2)
and a multiplier vector per stage — ``3(n_i + m_i)`` in all, and every one of them is
local: the rule forms the stages coordinate by coordinate, so the interconnection's
stages are the subsystems' stages stacked, and a subsystem's own one-forms at its
stages involve nothing else. Each interaction row is imposed as the rule imposes it in
the monolithic equations, at all three stages (``B V_j = 0``: the unknown end's stage and
the two stage rows), each *copy* with its own multiplier ``λ_j`` (``x`` holds them in
``μ`` and in ``ν_1, ν_2``), acting as the reaction ``−b_j Bᵀλ_j`` at its stage, pulled
back to the momentum line, the two stage lines and the explicit line. With ``B``
constant this is still linear: ``G_i = C_G ⊗ B_iᵀ`` and ``H_i = (1/h) C_H ⊗ B_i`` with
3 × 3 rule constants read off the rule's own step equations on a one-coordinate probe
(:func:`_couplings`), and ``λ`` has ``3l`` entries. The Robin interface then carries one
slot set per copy: slot ``(b, j, i)`` per row, copy and subsystem involved, ordered by
row, then copy, then subsystem, so that a chain's ``T`` is banded (bandwidths (9, 9),
solved by the banded LU of ``_solvers._banded``) where copy-major order would spread it
over ``3l``. The weights take the scheme's sign: for a free unit mass, whose step
Jacobian is ``M``, the eigenvalues of ``M⁻¹ C_G C_H`` are 0.31 and 0.09 ± 0.24i under
(+) and their negatives under (−), none on the negative real axis once the sign is
taken, so ``M + t C_G C_H`` (a massive coordinate with Robin weight ``t``) is invertible
for every ``t > 0``, and a massless coordinate's block is ``C_G W C_H`` (invertible).
Locally the unknowns are interleaved per coordinate, ``[(q_other_c, S_1c, S_2c) for
c]``, then per multiplier (:func:`_local_order`), so a chain piece's ``K_i`` keeps a
band of (4, 4) where the step's own order (all ``q_other``, then all stages) would give
a band of 2n ((202, 202) for a piece of 101 coordinates). A configuration-dependent
``Interaction`` is refused, as under the midpoint rule: at the stages it moves with the
unknowns.

The solver state is ``(stacked group parameters, factors, factors valid)``; ``init``
stacks each group's parameters once per chunk, so inside the time loop a group is a few
arrays, not one operand per subsystem.

The Newton iteration, its tolerances and its reuse of factors mirror
:class:`~diracvi.NewtonSolver` line by line, so both solve to the same precision.
"""

from __future__ import annotations

import dataclasses
import itertools
from functools import partial
from typing import ClassVar, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np

from ..discretization.equations import SCHEMES, new_momentum, ordered, residual
from ..discretization.rules import RULES, QuadratureRule, get_rule
from ..errors import ModelError
from ..model.interconnect import InterconnectedSystem
from ..model.stacked import structure_key as _structure_key
from ..model.system import LagrangeDiracSystem
from ..model.validate import check_choice
from . import banded as _banded
from .base import StepResult, StepSolver, check_newton_options
from .newton import chord_newton
from .sparsity import step_pattern

LOCAL_FACTORS = ("auto", "dense")


class PartitionLayout(NamedTuple):
    """How :class:`PartitionedSolver` splits a system (see :meth:`PartitionedSolver.layout`).

    ``groups``: the subsystem names stepped together with one ``jax.vmap``;
    ``interface``: ``"tridiagonal"``, ``"banded(kl, ku)"``, ``"dense"`` or ``"none"`` (no
    interaction rows): how the slot system ``T`` is solved;
    ``interface_size``: the number of slot unknowns (two per copy of a row joining two
    subsystems);
    ``local_factors``: per group, ``"banded(kl, ku)"`` (a banded LU of bandwidths
    ``kl``, ``ku``) or ``"dense"`` (an explicit inverse), as ``local_factors="auto"``
    picks them;
    ``row_copies``: copies of every interaction row (and of its multiplier) in the step:
    1, or 3 for ``"lobatto"`` (the row at the unknown end's stage and at the two stage
    rows);
    ``local_unknowns``: per group, the unknowns of one member: ``n + m``, or for
    ``"lobatto"`` ``3(n + m)``: ``q_other``, the two stage unknowns and the three stage
    multipliers, all kept local to the member.
    """

    groups: tuple[tuple[str, ...], ...]
    interface: str
    interface_size: int
    local_factors: tuple[str, ...] = ()
    row_copies: int = 1
    local_unknowns: tuple[int, ...] = ()


# ----------------------------------------------------------------------------- checks
def _node_is_known(rule: QuadratureRule, scheme: str) -> bool:
    """Does ``rule`` evaluate one-forms at the known end of the step (never the unknown)?"""
    known = np.array([0.3])
    for other in (np.array([1.7]), np.array([-2.9])):
        node = np.asarray(rule.constraint_node(scheme, *ordered(scheme, known, other)))
        if node.shape != known.shape or not np.array_equal(node, known):
            return False
    return True


def _as_rule(rule) -> QuadratureRule:
    if isinstance(rule, QuadratureRule):
        return rule
    return get_rule(check_choice("discretization", rule, tuple(RULES)))


def check_partitionable(system, rule="retraction", scheme: str = "plus") -> None:
    """Raise :class:`ModelError` unless the partitioned solver applies (host side)."""
    if not isinstance(system, InterconnectedSystem):
        raise ModelError(
            f"solver=PartitionedSolver() needs an interconnected system, but system="
            f"{system!r} is a single {type(system).__name__} with no subsystems to split. "
            "Fix: use solver=dv.NewtonSolver() (the default), or build the model from "
            "subsystems with dv.interconnect(...)."
        )
    scheme = check_choice("scheme", scheme, SCHEMES)
    rule = _as_rule(rule)
    if _node_is_known(rule, scheme):
        return
    for inter, (first, count) in zip(system.interactions, system._form_rows, strict=True):
        if inter._fn is not None:
            names = system.interaction_names[first : first + count]
            raise ModelError(
                f"solver=PartitionedSolver() cannot step {system.name!r} with "
                f"discretization={rule.name!r}, scheme={scheme!r}: the interaction with rows "
                f"{names} depends on the configuration, and this rule evaluates it at points "
                "that move with the unknowns (q̄ = (q_k + q_(k+1))/2 for 'midpoint', the "
                "stages Q_j for 'lobatto'), so the interface equations are not linear in them "
                "and do not split by subsystem. "
                "Fix: use solver=dv.NewtonSolver(), or discretization='retraction' (which "
                "evaluates the one-forms at the known configuration)."
            )


# ------------------------------------------------------------------- stage couplings
class _Couplings(NamedTuple):
    """How one interaction row enters a subsystem's step equations under a rule, per unit
    coefficient of ``B`` (rule constants, the same for every row and coordinate).

    ``copies``: the rows' copies (1, or 1 + stages: the row at the unknown end's stage,
    then one per stage row, each with its own multiplier); ``reaction[i, j]``: the share
    of copy ``j``'s multiplier in the coordinate line ``i`` (the momentum line, then the
    stage lines); ``rate[j, u]``: ``h ∂(copy j of B v)/∂(unknown u)`` (``q_other``, then
    the stage unknowns); ``momentum[j]``: copy ``j``'s multiplier in the explicit line;
    ``sign``: the sign the Robin weights take (see :func:`_couplings`).
    """

    copies: int
    reaction: np.ndarray
    rate: np.ndarray
    momentum: np.ndarray
    sign: float


_COUPLINGS: dict = {}


def _couplings(rule: QuadratureRule, scheme: str) -> _Couplings:
    """The rule's :class:`_Couplings`, read off its own step equations on a probe.

    Without stages: ``B_iᵀλ`` on the momentum line and ``(s/h) B_i`` (``s = ±1`` for
    (±)) in ``α``. With stages the probe is one coordinate with the constant one-form
    ``dx`` and ``L = 0``: its multipliers enter its lines and its one-form rows enter in
    the unknowns exactly as an interaction row's multipliers and rows do in the
    interconnection's equations (both are ``A`` of a constant one-form at each stage),
    so the coefficients are the derivatives of
    :func:`~diracvi.discretization.equations.residual` and
    :func:`~diracvi.discretization.equations.new_momentum` themselves, not a copy of their algebra.

    The Robin weights then take the sign of the scheme (see the module documentation:
    ``reaction · rate`` is then, like the mass block of the lines, never of opposite
    sign to it along a real eigendirection), so ``K_i`` is invertible for a massive or
    a massless coordinate."""
    key = (type(rule), rule.name, rule.stages, scheme)
    hit = _COUPLINGS.get(key)
    if hit is not None:
        return hit
    sign = 1.0 if scheme == "plus" else -1.0
    if not rule.stages:
        out = _Couplings(1, np.ones((1, 1)), np.full((1, 1), sign), np.zeros(1), 1.0)
    else:
        copies = 1 + rule.stages
        # natural layout of one coordinate and one row: [q_other, μ, S_1.., ν_1..]
        coord = np.array([0, *range(2, 2 + rule.stages)])
        mult = np.array([1, *range(2 + rule.stages, 2 + 2 * rule.stages)])
        with jax.ensure_compile_time_eval():
            probe = LagrangeDiracSystem(
                ("x",), lambda q, v: 0.0 * v[0], constraints=np.ones((1, 1)), name="probe"
            )
            zero = jnp.zeros(1)
            x = jnp.linspace(0.1, 0.7, 2 * copies)
            jac = np.asarray(
                jax.jacfwd(lambda x: residual(probe, rule, scheme, 1.0, zero, zero, x))(x)
            )
            mom = np.asarray(
                jax.jacfwd(lambda x: new_momentum(probe, rule, scheme, 1.0, zero, x))(x)
            )
        out = _Couplings(
            copies, jac[np.ix_(coord, mult)], jac[np.ix_(mult, coord)], mom[0, mult], sign
        )
    _COUPLINGS[key] = out
    return out


def _local_order(n: int, m: int, copies: int) -> np.ndarray:
    """``perm``: local unknown ``i`` is unknown ``perm[i]`` of the subsystem's own step
    (and local equation ``i`` its equation ``perm[i]``).

    The own step orders its unknowns by kind, ``[q_other, μ, S_1 … S_s, ν_1 … ν_s]``;
    locally they are interleaved per coordinate, ``[(q_other_c, S_1c … S_sc) for c]``,
    then per multiplier, so that a chain piece, whose coordinate ``c`` couples to ``c ± 1``
    at every stage, keeps a band of ``≈ 2·copies`` instead of ``≈ 2n`` (the identity
    without stages)."""
    stages = copies - 1

    def coord(k, c):
        return c if k == 0 else n + m + (k - 1) * n + c

    def mult(k, r):
        return n + r if k == 0 else n + m + stages * n + (k - 1) * m + r

    return np.array(
        [coord(k, c) for c in range(n) for k in range(copies)]
        + [mult(k, r) for r in range(m) for k in range(copies)],
        dtype=np.int64,
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
    ports: tuple[np.ndarray, ...]  # (member, local row, local column, ±1) of connections
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

    # which rows are connections (coefficients ±1) and which come from general_forms
    pairs = zip(system._port_index, system._port_rows, strict=True)
    port_of_row = {int(row): (int(a), int(b)) for (a, b), row in pairs}
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
                    for col, val in zip(port_of_row[b], (1.0, -1.0), strict=True):
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


class _Step:
    """One step's operators over the plan: residual, factorization and linear solve on
    the stacked representation ``X = ((y_g for each group), λ)``.

    ``λ`` holds every copy of the interaction multipliers, copy-major (``plan.rows``);
    a member's coordinates ``y[:, : n·copies]`` are ``(n, copies)`` row-major (local order)."""

    def __init__(self, plan: _Plan, eqs, stacked, bands, couplings: _Couplings):
        self.plan = plan
        self.eqs = eqs
        self.bands = bands  # per group: (kl, ku) of banded local factors, or None
        self.c = couplings
        system = eqs.system
        self.h = eqs.h
        self.stacks, self.index, self.q, self.p, self.blocks = [], [], [], [], []
        self.tiles, self.uniform, self.inverse, self.port_cols = [], [], [], []
        general = system.general_forms(eqs.q) if system.interactions else None
        for g, arrays in zip(plan.groups, stacked, strict=True):
            first = system.subsystems[int(g.members[0])]
            self.stacks.append((arrays, eqx.partition(first, eqx.is_array)[1]))
            # local order → the own step's order (None: they are the same)
            self.inverse.append(None if g.copies == 1 else np.argsort(g.perm))
            # a group whose members' unknowns lie side by side is a reshaped slice of x
            # (no gather, no scatter, no N-sized index table in the program)
            self.tiles.append(_tile(g))
            # one constant per table (not one per use): N-sized tables bloat the program
            self.index.append(None if self.tiles[-1] else jnp.asarray(g.y_index))
            self.q.append(self._take(index=len(self.q), x=eqs.q, coords_only=True))
            self.p.append(self._take(index=len(self.p), x=eqs.p, coords_only=True))
            # B restricted to each member's columns and rows, at the known configuration:
            # the same small (rows × n) matrix E for every member when only connections
            # touch the group at the same local places, else one block per member
            self.uniform.append(_uniform_ports(g))
            # the columns E touches (a connection: one per row): σ and the reaction
            # read and write only these, not all n·copies unknowns of every member
            self.port_cols.append(
                None if self.uniform[-1] is None else np.flatnonzero(self.uniform[-1].any(0))
            )
            if self.uniform[-1] is not None:
                self.blocks.append(None)
                continue
            block = jnp.zeros((len(g.members), g.rows_each, g.n), dtype=eqs.q.dtype)
            k, r, c, val = g.ports
            if k.size:
                block = block.at[k, r, c].set(jnp.asarray(val))
            k, r, grow = g.general
            if k.size:
                cols = jnp.asarray(g.y_index[:, : g.n * g.copies : g.copies])[k]
                block = block.at[k, r].set(general[grow[:, None], cols])
            self.blocks.append(block)

    def _take(self, index, x, coords_only=False):
        """Group ``index``'s unknowns (or only its ``q_other``, of ``x = q``), (G, ·)."""
        g, tile = self.plan.groups[index], self.tiles[index]
        copies = g.copies
        if tile is None:
            table = self.index[index]
            return x[table[:, : g.n * copies : copies]] if coords_only else x[table]
        count = len(g.members)
        q_at, mu_at = tile
        if coords_only:
            return x[q_at[0] : q_at[0] + count * g.n].reshape(count, g.n)

        def interleaved(starts, size):
            parts = [x[a : a + count * size].reshape(count, size) for a in starts]
            if copies == 1:
                return parts[0]
            return jnp.stack(parts, axis=-1).reshape(count, size * copies)

        q = interleaved(q_at, g.n)
        if not g.m:
            return q
        return jnp.concatenate([q, interleaved(mu_at, g.m)], axis=1)

    def block(self, index):
        """``B_i`` of every member of group ``index``, (G, rows, n)."""
        if self.blocks[index] is not None:
            return self.blocks[index]
        shape = (len(self.plan.groups[index].members), *self.uniform[index].shape)
        return jnp.broadcast_to(jnp.asarray(self.uniform[index]), shape)

    def spread(self, index, lam):
        """``B_iᵀ λ_j`` for every member and copy: (G, copies·rows) → (G, copies, n)."""
        g = self.plan.groups[index]
        v = lam.reshape(len(g.members), g.copies, g.rows_each)
        if self.uniform[index] is not None:
            return v @ jnp.asarray(self.uniform[index])
        return jnp.einsum("krn,kjr->kjn", self.blocks[index], v)

    def reaction(self, index, lam):
        """``G_i λ_i`` on the coordinate lines, (G, n·copies) in the local order."""
        g = self.plan.groups[index]
        u = jnp.einsum("ij,kjn->kni", jnp.asarray(self.c.reaction), self.spread(index, lam))
        return u.reshape(len(g.members), g.n * g.copies)

    def add_reaction(self, index, r, lam):
        """``r`` with ``G_i λ_i`` added on its coordinate lines (local order); with a
        uniform ``E`` only at the columns it touches (the same numbers: the rest adds 0)."""
        g, cols = self.plan.groups[index], self.port_cols[index]
        if cols is None:
            return r.at[:, : g.n * g.copies].add(self.reaction(index, lam))
        count = len(g.members)
        v = lam.reshape(count, g.copies, g.rows_each)
        spread = v @ jnp.asarray(self.uniform[index][:, cols])  # (G, copies, cols)
        u = jnp.einsum("ij,kjc->kci", jnp.asarray(self.c.reaction), spread)
        at = (cols[:, None] * g.copies + np.arange(g.copies)[None, :]).ravel()
        return r.at[:, at].add(u.reshape(count, at.size))

    def sigma(self, index, y, block=None):
        """``H_i y`` for every member: its share of every copy of its interface rows.

        ``y``: (G, n·copies, …) in the local order (the coordinate rows of ``y_i``, or of
        a matrix); returns (G, copies·rows, …)."""
        g = self.plan.groups[index]
        count, extra = len(g.members), y.shape[2:]
        y = y.reshape(count, g.n, g.copies, *extra)
        if block is None and self.uniform[index] is not None:
            cols = self.port_cols[index]  # E is zero elsewhere: read only these columns
            z = jnp.einsum("ju,kcu...->kjc...", jnp.asarray(self.c.rate), y[:, cols]) / self.h
            out = jnp.einsum("rc,kjc...->kjr...", jnp.asarray(self.uniform[index][:, cols]), z)
        else:
            z = jnp.einsum("ju,knu...->kjn...", jnp.asarray(self.c.rate), y) / self.h
            block = self.blocks[index] if block is None else block
            out = jnp.einsum("krn,kjn...->kjr...", block, z)
        return out.reshape(count, g.copies * g.rows_each, *extra)

    def g_matrix(self, index, block):
        """``G_i`` restricted to the coordinate lines, (G, n·copies, copies·rows)."""
        g = self.plan.groups[index]
        gm = jnp.einsum("ij,krc->kcijr", jnp.asarray(self.c.reaction), block)
        return gm.reshape(len(g.members), g.n * g.copies, g.copies * g.rows_each)

    # ---------------------------------------------------------------- layout
    def split(self, x):
        ys = tuple(self._take(i, x) for i in range(len(self.plan.groups)))
        plan = self.plan
        if len(plan.lam_at) == 1:
            return ys, x[plan.lam_at[0] : plan.lam_at[0] + plan.base_rows]
        return ys, jnp.concatenate([x[a : a + plan.base_rows] for a in plan.lam_at])

    def _lam_pieces(self, lam):
        size = self.plan.base_rows
        return [(a, lam[j * size : (j + 1) * size]) for j, a in enumerate(self.plan.lam_at)]

    def join(self, ys, lam):
        plan = self.plan
        pieces = self._lam_pieces(lam)
        for g, tile, y in zip(plan.groups, self.tiles, ys, strict=True):
            if tile is None:
                break
            count = len(g.members)
            coords = y[:, : g.n * g.copies].reshape(count, g.n, g.copies)
            mults = y[:, g.n * g.copies :].reshape(count, g.m, g.copies)
            for j in range(g.copies):
                pieces.append((tile[0][j], coords[:, :, j].ravel()))
                if g.m:
                    pieces.append((tile[1][j], mults[:, :, j].ravel()))
        else:
            joined = _concatenate_tiles(pieces, plan.size)
            if joined is not None:
                return joined
        x = jnp.zeros(plan.size, dtype=lam.dtype)
        for index, y in enumerate(ys):
            table = jnp.asarray(plan.groups[index].y_index)
            x = x.at[table].set(y)
        for at, values in self._lam_pieces(lam):
            x = x.at[at : at + values.shape[0]].set(values)
        return x

    # -------------------------------------------------------------- equations
    def momentum(self, ys, lam):
        """The explicit line ``p_{k+1} = D₂L_d + f_d^+`` (or ``p_k``), group by group (a
        staged rule's line carries its stage reactions, the interaction's among them)."""
        eqs, plan = self.eqs, self.plan
        lines = []
        for index, y in enumerate(ys):
            g = plan.groups[index]
            arrays, rest = self.stacks[index]

            def line(arrays, q, y, rest=rest, inverse=self.inverse[index]):
                sub = eqx.combine(arrays, rest)
                y = y if inverse is None else y[inverse]
                return new_momentum(sub, eqs.rule, eqs.scheme, eqs.h, q, y, eqs.t)

            p = jax.vmap(line)(arrays, self.q[index], y)
            if np.any(self.c.momentum) and g.rows_each:
                u = self.spread(index, lam[g.rows])
                p = p + jnp.einsum("j,kjn->kn", jnp.asarray(self.c.momentum), u)
            lines.append(p)
        if all(tile is not None for tile in self.tiles):
            pieces = [(tile[0][0], p.ravel()) for tile, p in zip(self.tiles, lines, strict=True)]
            joined = _concatenate_tiles(pieces, eqs.system.n)
            if joined is not None:
                return joined
        out = jnp.zeros(eqs.system.n, dtype=eqs.q.dtype)
        for g, p in zip(plan.groups, lines, strict=True):
            out = out.at[jnp.asarray(g.y_index[:, : g.n * g.copies : g.copies])].set(p)
        return out

    def _local(self, index):
        """``ρ_i(y_i)`` of group ``index`` in the local order, for one member."""
        eqs = self.eqs
        _, rest = self.stacks[index]
        inverse, perm = self.inverse[index], self.plan.groups[index].perm

        def rho(arrays, q, p, y):
            sub = eqx.combine(arrays, rest)
            if inverse is None:
                return residual(sub, eqs.rule, eqs.scheme, eqs.h, q, p, y, eqs.t)
            return residual(sub, eqs.rule, eqs.scheme, eqs.h, q, p, y[inverse], eqs.t)[perm]

        return rho

    def _band_jacobian(self, index, arrays, q, p, y):
        """One member's ``J_i`` as banded rows, from ``kl + ku + 1`` compressed JVPs."""
        kl, ku = self.bands[index]
        rho = self._local(index)
        seeds = jnp.asarray(_banded.seeds(y.shape[0], kl, ku), dtype=y.dtype)
        _, products = jax.vmap(lambda s: jax.jvp(lambda y: rho(arrays, q, p, y), (y,), (s,)))(seeds)
        return _banded.from_products(products, kl, ku)

    def residual(self, ys, lam):
        """The step residual, per group ``ρ_i + G_i λ``, and the interface rows ``α_d``."""
        plan, out = self.plan, []
        alpha = jnp.zeros(plan.rows, dtype=lam.dtype)
        for index, (g, y) in enumerate(zip(plan.groups, ys, strict=True)):
            arrays, _ = self.stacks[index]
            r = jax.vmap(self._local(index))(arrays, self.q[index], self.p[index], y)
            coords = g.n * g.copies
            out.append(self.add_reaction(index, r, lam[g.rows]))
            # α is linear in the unknowns and vanishes when every copy is the known q
            moved = y[:, :coords] - jnp.repeat(self.q[index], g.copies, axis=1)
            alpha = alpha.at[g.rows].add(self.sigma(index, moved))
        return tuple(out), alpha

    def factorize(self, ys):
        """Factors of ``K_i = J_i + G_i W H_i`` and of the slot system ``T``."""
        plan, h = self.plan, self.h
        jacs, scales = [], jnp.zeros(plan.subsystems, dtype=self.q[0].dtype)
        for index, (g, y) in enumerate(zip(plan.groups, ys, strict=True)):
            arrays, _ = self.stacks[index]
            args = (arrays, self.q[index], self.p[index], y)
            if self.bands[index] is None:
                jac = jax.vmap(jax.jacfwd(self._local(index), argnums=3))(*args)
            else:  # banded rows R[i, d] = J[i, i − kl + d]: kl + ku + 1 JVPs per member
                jac = jax.vmap(partial(self._band_jacobian, index))(*args)
            jacs.append(jac)
            # max|J_i| / max|G_i H_i|: the weight that makes G_i W H_i comparable to J_i
            if self.uniform[index] is None:
                bmax = jnp.max(jnp.abs(self.blocks[index]), axis=(1, 2), initial=0.0)
            else:
                bmax = jnp.full(len(g.members), np.abs(self.uniform[index]).max(initial=0.0))
            jmax = jnp.max(jnp.abs(jac), axis=(1, 2))
            tau = jnp.where(bmax > 0, jmax * h / jnp.where(bmax > 0, bmax, 1.0) ** 2, 0.0)
            scales = scales.at[g.members].set(tau)
        tau = scales[plan.slot_sub]
        total = jax.ops.segment_sum(tau, plan.slot_row, num_segments=plan.rows)
        used = jax.ops.segment_sum((tau > 0).astype(tau.dtype), plan.slot_row, plan.rows)
        w = jnp.where(total > 0, total / jnp.where(used > 0, used, 1.0), 1.0)
        w = self.c.sign * w  # the scheme's sign (see _couplings)

        flat = jnp.zeros(plan.slots * plan.width, dtype=w.dtype)
        pos, val = plan.fixed
        flat = flat.at[pos].add(jnp.asarray(val))
        reaction, rate = jnp.asarray(self.c.reaction), jnp.asarray(self.c.rate)
        local = []
        for index, (g, jac) in enumerate(zip(plan.groups, jacs, strict=True)):
            block = self.block(index)
            count, coords = len(g.members), g.n * g.copies
            weight = w[g.rows].reshape(count, g.copies, g.rows_each)
            gmat = self.g_matrix(index, block)
            if self.bands[index] is None:
                bwb = jnp.einsum("krn,kjr,krp->kjnp", block, weight, block)
                aug = jnp.einsum("ij,kjnp,ju->knipu", reaction, bwb, rate) / h
                aug = aug.reshape(count, coords, coords)
                # explicit inverses: see the module documentation
                kinv = jnp.linalg.inv(jac.at[:, :coords, :coords].add(aug))
                kinv_g = jnp.einsum("ksn,knr->ksr", kinv[:, :, :coords], gmat)  # K⁻¹ G_i
            else:
                kl, ku = self.bands[index]
                c, c2 = _port_pairs(g)
                a, b = _aug_entries(g)  # G_i W H_i's entries, all inside the band
                bwb = jnp.einsum("kre,kjr,kre->kje", block[:, :, c], weight, block[:, :, c2])
                aug = jnp.einsum("ij,kje,ju->keiu", reaction, bwb, rate) / h
                rows = jac.at[:, a, b - a + kl].add(aug)
                kinv = jax.vmap(partial(_banded.lu, kl=kl, ku=ku))(rows)  # banded P K = L U
                rhs = jnp.zeros((count, jac.shape[1], gmat.shape[2]), dtype=block.dtype)
                rhs = rhs.at[:, :coords].set(gmat)
                kinv_g = jax.vmap(partial(_banded.solve, kl=kl, ku=ku))(kinv, rhs)
            p_mat = self.sigma(index, kinv_g[:, :coords])  # H_i K_i⁻¹ G_i
            pos, eq_row, k, r, c, coef = g.assembly
            if pos.size:
                flat = flat.at[pos].add(jnp.asarray(coef) * w[eq_row] * p_mat[k, r, c])
            # B_i with the factors: a configuration-dependent one is kept as it was
            local.append((kinv, kinv_g, self.blocks[index]))
        if plan.slots == 0:
            interface = ()
        elif plan.tridiagonal:
            tri = flat.reshape(plan.slots, 3)
            interface = (tri[:, 0], tri[:, 1], tri[:, 2])
        elif plan.band is not None:
            interface = _banded.lu(flat.reshape(plan.slots, plan.width), *plan.band)
        else:
            interface = jsl.lu_factor(flat.reshape(plan.slots, plan.slots))
        return tuple(local), w, interface

    def solve_linear(self, factors, rs, r_alpha):
        """``(dy, dλ)`` with ``J_i dy_i + G_i dλ = −r_i`` and ``Σ_i H_i dy_i = −r_α``."""
        plan = self.plan
        local, w, interface = factors
        base, z = [], jnp.zeros(plan.slots, dtype=w.dtype)
        for index, (g, (kinv, _, block), r) in enumerate(zip(plan.groups, local, rs, strict=True)):
            band = self.bands[index]
            if band is None:
                kinv_a = -jnp.einsum("kst,kt->ks", kinv, r)
            else:
                kinv_a = -jax.vmap(partial(_banded.solve, kl=band[0], ku=band[1]))(kinv, r)
            base.append(kinv_a)
            z = z.at[g.slots].set(self.sigma(index, kinv_a[:, : g.n * g.copies], block))
        dys = []
        if plan.slots:
            eq, slot, coef = plan.sigma_terms
            sigma_part = jax.ops.segment_sum(jnp.asarray(coef) * z[slot], eq, plan.slots)
            weight = w[plan.slot_row]
            rhs = -weight * (sigma_part - jnp.asarray(plan.flux_coef) * r_alpha[plan.slot_row])
            if plan.tridiagonal:
                dl, d, du = interface
                g_all = jax.lax.linalg.tridiagonal_solve(dl, d, du, rhs[:, None])[:, 0]
            elif plan.band is not None:
                g_all = _banded.solve(interface, rhs, *plan.band)
            else:
                g_all = jsl.lu_solve(interface, rhs)
        else:
            g_all = jnp.zeros(0, dtype=w.dtype)
        sigma = jnp.zeros(plan.slots, dtype=w.dtype)
        for index, (g, (_, kinv_g, block), kinv_a) in enumerate(
            zip(plan.groups, local, base, strict=True)
        ):
            # the few slots' terms written out: one elementwise pass (a batched dot of
            # (s × slots) by (slots,) per member, or a reduction over the slot axis, is a
            # separate pass that XLA runs 4–20× slower at 10⁴ members)
            dy = kinv_a
            g_here = g_all[g.slots]
            for j in range(g_here.shape[1]):
                dy = dy - kinv_g[:, :, j] * g_here[:, j, None]
            dys.append(dy)
            share = self.sigma(index, dy[:, : g.n * g.copies], block)
            sigma = sigma.at[g.slots].set(share)
        first = plan.first_slot
        dlam = g_all[first] + w * sigma[first]
        return tuple(dys), dlam


class PartitionedSolver(StepSolver):
    """Newton's method whose linear solves run subsystem by subsystem (O(n) per step).

    For an :class:`~diracvi.InterconnectedSystem` whose interaction one-forms do not move
    with the unknowns: constant ones (``dv.connect``, a constant ``dv.Interaction``) under
    any rule, configuration-dependent ones under ``"retraction"``. Subsystems of equal
    structure are batched with ``jax.vmap``; a chain-like interface is solved as a
    tridiagonal (banded under ``"lobatto"``) system. Under ``"lobatto"`` each subsystem's
    stages and stage multipliers are its own local unknowns, and every interaction row
    is imposed at the three stages with one multiplier and one slot set per stage
    (:meth:`layout` reports ``row_copies`` and ``local_unknowns``). See the module
    documentation for the method.

    Args: as :class:`~diracvi.NewtonSolver` (same defaults, same meaning), and
        local_factors: ``"auto"`` (default) factorizes a group's local matrices as banded
            LU when their structure, read at plan time, has a narrow band (O(s·b²) work
            and O(s·b) memory per member of s unknowns); ``"dense"`` keeps explicit
            inverses for every group (O(s³) and O(s²)). Both give the same steps to
            round-off.
    """

    # vectorized over a chunk, the diagnostics cost a step of the torn chain 1.8× (34
    # against 19 ms at N = 10⁵, 1.7× at 10⁴; the same bits to 3e-16)
    diagnostics_per_step: ClassVar[bool] = True

    rtol: float = eqx.field(static=True, default=1e-13)
    max_steps: int = eqx.field(static=True, default=40)
    floor: float = eqx.field(static=True, default=1e-9)
    reuse_jacobian: bool = eqx.field(static=True, default=True)
    contraction: float = eqx.field(static=True, default=0.25)
    local_factors: str = eqx.field(static=True, default="auto")

    def __check_init__(self):
        check_newton_options(self)
        check_choice("local_factors", self.local_factors, LOCAL_FACTORS)

    @staticmethod
    def check(system, rule="retraction", scheme: str = "plus") -> None:
        """Raise :class:`~diracvi.ModelError` (naming the fix) unless this solver applies
        to ``system`` under ``rule`` (a name or a QuadratureRule) and ``scheme``."""
        check_partitionable(system, rule, scheme)

    @staticmethod
    def layout(system, rule="retraction", scheme: str = "plus") -> PartitionLayout:
        """The groups of batched subsystems and the kind of interface solve."""
        check_partitionable(system, rule, scheme)
        rule = _as_rule(rule)
        couplings = _couplings(rule, scheme)
        plan = _build_plan(system, scheme, couplings.copies)
        names = tuple(tuple(system.subsystems[int(i)].name for i in g.members) for g in plan.groups)
        if plan.slots == 0:
            kind = "none"
        elif plan.tridiagonal:
            kind = "tridiagonal"
        else:
            kind = "dense" if plan.band is None else f"banded{plan.band}"
        bands = (_local_band(g, system, rule, scheme) for g in plan.groups)
        local = tuple("dense" if b is None else f"banded{b}" for b in bands)
        sizes = tuple(g.perm.size for g in plan.groups)
        return PartitionLayout(names, kind, plan.slots, local, couplings.copies, sizes)

    def _prepare(self, eqs, state=None) -> _Step:
        check_partitionable(eqs.system, eqs.rule, eqs.scheme)
        couplings = _couplings(eqs.rule, eqs.scheme)
        plan = _build_plan(eqs.system, eqs.scheme, couplings.copies)
        stacked = _stack(plan, eqs.system) if state is None else state[0]
        if self.local_factors == "dense":
            bands = [None] * len(plan.groups)
        else:
            bands = [_local_band(g, eqs.system, eqs.rule, eqs.scheme) for g in plan.groups]
        return _Step(plan, eqs, stacked, bands, couplings)

    def momentum(self, eqs, x, state=None):
        """``eqs.momentum(x)`` computed group by group: the same numbers, traced once per
        group of alike subsystems instead of once per subsystem. Pass the solver
        ``state`` to reuse its stacked parameters (what a driver for thousands of
        subsystems wants inside its time loop)."""
        step = self._prepare(eqs, state)
        return step.momentum(*step.split(x))

    def init(self, eqs):
        """``(stacked group parameters, zero factors, factors valid = False)``."""
        step = self._prepare(eqs)
        ys, _ = step.split(jnp.zeros(step.plan.size, dtype=eqs.q.dtype))
        shapes = jax.eval_shape(step.factorize, ys)
        factors = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype), shapes)
        return tuple(a for a, _ in step.stacks), factors, jnp.asarray(False)

    def solve(self, eqs, guess, state) -> StepResult:
        """Solve the step equations from ``guess`` (``x`` in the system's global order)."""
        step = self._prepare(eqs, state)
        stacked, factors, valid = state
        x, status, iterations, res_norm, factors = chord_newton(
            self,
            lambda x: step.residual(*x),
            lambda x: step.factorize(x[0]),
            lambda factors, r: step.solve_linear(factors, *r),
            step.split(guess),
            factors,
            valid,
            eqs.scale(),
        )
        state = (stacked, factors, status == 0)
        return StepResult(step.join(*x), status, iterations, res_norm, state)
