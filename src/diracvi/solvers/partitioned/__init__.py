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

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from ...model.validate import check_choice
from ..base import StepResult, StepSolver, check_newton_options
from ..newton import chord_newton
from .interface import LOCAL_FACTORS, PartitionLayout, _as_rule, _couplings, check_partitionable
from .plan import _build_plan, _local_band, _stack
from .step import _Step


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
    predict_stop: bool = eqx.field(static=True, default=False)
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

    def solve(self, eqs, guess, state, atol=None) -> StepResult:
        """Solve the step equations from ``guess`` (``x`` in the system's global order;
        ``atol``: see :meth:`~diracvi.NewtonSolver.solve`)."""
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
            reference=step.split(eqs.reference()),
            atol=None if atol is None else step.split(atol),
        )
        state = (stacked, factors, status == 0)
        return StepResult(step.join(*x), status, iterations, res_norm, state)


__all__ = ["LOCAL_FACTORS", "PartitionLayout", "PartitionedSolver", "check_partitionable"]
