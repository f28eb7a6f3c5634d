r"""``"lobatto"`` (order 4): Lobatto IIID in Hamilton–Pontryagin form, with stage multipliers.

Three stage velocities at ``t_k + (0, ½, 1) h``, stage positions ``Q_i = q_k + h Σ_j a_ij
V_j``, and L, the forces, the inputs and the one-forms evaluated at the stages. Its stage
positions ``Q₁, Q₂`` and one multiplier vector per stage are extra unknowns of the step
(see :class:`Lobatto` and ``docs/discretizations.md``).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..errors import ModelError
from .base import QuadratureRule
from .midpoint import CentredNodes

#: Lobatto nodes and weights (Simpson) of the step ``[t_k, t_k + h]``
NODES = (0.0, 0.5, 1.0)
WEIGHTS = (1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0)
#: Lobatto IIID, ``a = (IIIC + IIIC*)/2``: its own symplectic partner
#: (``b_i a_ij + b_j a_ji = b_i b_j``) and invertible, unlike IIIA (first row 0) and IIIB
#: (last column 0)
IIID = (
    (1.0 / 12.0, -1.0 / 6.0, 1.0 / 12.0),
    (5.0 / 24.0, 1.0 / 3.0, -1.0 / 24.0),
    (1.0 / 12.0, 5.0 / 6.0, 1.0 / 12.0),
)


class Lobatto(CentredNodes, QuadratureRule):
    r"""The order-4 rule: Lobatto IIID in Hamilton–Pontryagin form, with stage multipliers.

    On ``[t_k, t_k + h]`` three stage velocities ``V_j`` at ``t_j = t_k + c_j h``,
    ``c = (0, ½, 1)``, give the stage positions and the step::

        Q_i = q_k + h Σ_j a_ij V_j,     q_{k+1} = q_k + h Σ_j b_j V_j

    with the Lobatto IIID coefficients ``a`` (:data:`IIID`) and Simpson's weights ``b``.
    ``L_d = h Σ_j b_j L(Q_j, V_j, t_j)``; forces and constraint reactions act at the
    stages, ``h Σ_j b_j ⟨F_j + A(Q_j, t_j)ᵀλ_j, δQ_j⟩`` (Lagrange–d'Alembert), and every
    stage satisfies the one-forms, ``c_j = A(Q_j, t_j) V_j + b(Q_j, t_j) = 0``. Because
    ``a`` is its own symplectic partner the momenta are stepped with the same ``a``:
    the variational partitioned Runge–Kutta method is the (symmetric, symplectic,
    order 4) Runge–Kutta method Lobatto IIID applied to ``q̇ = v, ṗ = ∂L/∂q + F + Aᵀλ,
    p = ∂L/∂v``. Its ``a`` is invertible, so a degenerate direction of ``L`` (where
    ``p = ∂L/∂v`` does not involve ``v``) is collocated at all three stages and keeps
    order 4 — Lobatto IIIA–IIIB leaves the last stage velocity of such a direction
    undetermined (``docs/discretizations.md``).

    The stages are ``stage = [Q₁ Q₂]`` (an ``(n, 2)`` array), with ``Q₃ = q_k + q_{k+1} −
    Q₁`` (IIID's row 3 is row 1 mirrored); the step's unknowns besides ``q_other`` are the
    stage at the known end and ``Q₂`` (:meth:`stage_from_unknowns`), and one multiplier
    vector per stage, in impulse units ``μ_j = −h λ_j``
    (the sign and scale of the paper's ``μ_k``). ``μ`` of the step is the one at the
    unknown end's stage (``t_{k+1}`` for (+), ``t_k`` for (−)), ``ν`` the other two.

    A holonomic row ``g(q, t) = 0`` is held at the unknown end with its multiplier ``μ``
    acting at the known node, and by the stage rows ``g(Q₂) = 0``, ``g(Q₃) − g(Q₁) = 0``
    (:meth:`holonomic_rows`, :meth:`reaction_covectors`): a variational step on the
    constraint manifold. Imposing ``g`` at ``q_{k+1}, Q₁, Q₂`` with the end row's
    multiplier at ``Q₃`` (this rule's first version) left the momentum along ``∇g(q_k)``
    unabsorbed, a step-map eigenvalue of −1.0009 that grew until Newton failed
    (``docs/discretizations.md``, issue 31).
    """

    def __init__(self):
        self.name = "lobatto"
        self.order = 4

    @property
    def stages(self) -> int:
        return 2

    def force_weights(self):
        return WEIGHTS[0], WEIGHTS[2]

    def impulse_share(self):
        # the reactions act at the stages and are integrated into p_{k+1}: p is nodal
        return 0.0

    def increment_stages(self):
        # the stage at the known end, Q_near, is within O(h³) of it
        return (0,)

    def tableau(self):
        """``(a, â, b) = (IIID, IIID, Simpson)``: IIID is its own symplectic partner
        (``b_i â_ij + b_j a_ji = b_i b_j`` with ``â = a``), so the momenta of the variational
        step follow the same coefficients as the positions."""
        return IIID, IIID, WEIGHTS

    @staticmethod
    def stage_positions(qk, stage, qk1):
        """``(Q₁, Q₂, Q₃)`` from ``stage = [Q₁ Q₂]`` (shape (n, 2)) and the two ends."""
        q1, q2 = stage[..., 0], stage[..., 1]
        return q1, q2, qk1 - (q1 - qk)

    @classmethod
    def nodes(cls, qk, stage, qk1, h, tk):
        """``(Q_j, V_j, t_j)`` at the three stages: ``V = M⁻¹ (Q₁ − q_k, Q₂ − q_k,
        q_{k+1} − q_k)/h`` with ``M`` = the rows ``a₁, a₂, b`` (inverted exactly)."""
        q1, q2, q3 = cls.stage_positions(qk, stage, qk1)
        # in increments from q_k: each is formed with little rounding (the stages are near
        # q_k), where 4Q₁ + 4Q₂ − 7q_k − q_{k+1} would cancel terms 16 times |q|
        d1, d2, d = q1 - qk, q2 - qk, qk1 - qk
        v1 = (4.0 * d1 + 4.0 * d2 - d) / h
        v2 = (d - 2.0 * d1) / h
        v3 = (4.0 * d1 - 4.0 * d2 + 3.0 * d) / h
        return ((q1, v1, tk), (q2, v2, tk + 0.5 * h), (q3, v3, tk + h))

    @classmethod
    def stacked_nodes(cls, qk, stage, qk1, h, tk):
        """:meth:`nodes` as three arrays with the stage on the leading axis, ``Q`` and ``V``
        of shape (3, n) and ``t`` of shape (3,), for :func:`at_stages`."""
        return _stack(cls.nodes(qk, stage, qk1, h, tk))

    @staticmethod
    def pullback(covectors):
        r"""``(φ₁, φ₂, φ₃)`` at the stage positions → their pull-back to ``(q_k, [Q₁ Q₂],
        q_{k+1})``: ``Σ_j φ_j ∂Q_j/∂(·)``, with ``∂Q₃/∂(q_k, Q₁, q_{k+1}) = (1, −1, 1)``.
        Two more entries ``(ψ_k, ψ_{k+1})``, covectors at the nodes themselves (the
        holonomic rows' nodal reactions), add to the end lines as they are."""
        f1, f2, f3, *nodal = covectors
        left, right = f3, f3
        if nodal:
            left, right = left + nodal[0], right + nodal[1]
        return left, jnp.stack([f1 - f3, f2], axis=-1), right

    @staticmethod
    def rows_of(side: str):
        """The stage index of the end rows and of the two stage rows: the end is the
        unknown end of the step (``t_{k+1}`` for (+), ``t_k`` for (−))."""
        return (2, (0, 1)) if side == "plus" else (0, (1, 2))

    def _need_stage(self, what: str):
        raise ModelError(
            f"discretization='lobatto' cannot evaluate {what} from (q_k, q_(k+1)) alone: it "
            "needs the step's internal stages. Fix: use the staged forms (pass stage=), "
            "or discretization='midpoint' for this diagnostic."
        )

    def discrete_lagrangian(self, lagrangian, qk, qk1, h, tk=0.0, stage=None):
        r"""``L_d = h Σ_j b_j L(Q_j, V_j, t_j)``."""
        if stage is None:
            self._need_stage("L_d")
        values = at_stages(lagrangian, *self.stacked_nodes(qk, stage, qk1, h, tk))
        return h * sum(w * values[j] for j, w in enumerate(WEIGHTS))

    def discrete_forces(self, force, qk, qk1, h, tk=0.0, stage=None):
        r"""``(f_d^−, f_d^+, f_Q)``: the pull-back of ``h b_j F(Q_j, V_j, t_j)``."""
        if stage is None:
            self._need_stage("f_d")
        values = at_stages(force, *self.stacked_nodes(qk, stage, qk1, h, tk))
        left, mid, right = self.pullback([h * w * values[j] for j, w in enumerate(WEIGHTS)])
        return left, right, mid

    def reaction_covectors(self, multiplier_force, side, qk, stage, qk1, h, tk, mu, nu, held=None):
        r"""The reactions, from ``multiplier_force(q, μ, t) = A(q, t)ᵀ μ``.

        One-form rows: ``−b_j A(Q_j, t_j)ᵀ μ_j`` at each stage (``h b_j A_jᵀ λ_j`` with
        ``λ_j = −μ_j/h``), ``μ_j`` the multiplier of the row at stage ``j``.
        Holonomic rows (``held``): the multiplier ``μ`` of ``g(q_unknown) = 0`` acts at the
        known node (``−∇g(q_k)ᵀμ`` on the (+) left line, ``+∇g(q_{k+1})ᵀμ`` on the (−)
        right line, the midpoint rule's nodal impulse), and the stage rows' multipliers
        at the stages they constrain, ``−b_j ∇g(Q_j)ᵀ ν_j`` with ``ν_j = (−ν_pair, ν_mid,
        ν_pair)``: ``b₁ = b₃``, so this is the variation of ``−b₁ ν_pair (g(Q₃) − g(Q₁))
        − b₂ ν_mid g(Q₂)``, the stage rows of :meth:`holonomic_rows`. Returns the three
        stage covectors, then (with ``held``) the two nodal ones, for :meth:`pullback`.
        """
        end, mids = self.rows_of(side)
        mus = [None] * 3
        mus[end], mus[mids[0]], mus[mids[1]] = mu, nu[..., 0], nu[..., 1]
        q, _, t = self.stacked_nodes(qk, stage, qk1, h, tk)
        if held is None:
            forces = at_stages(multiplier_force, q, jnp.stack(mus), t)
            return [-w * forces[j] for j, w in enumerate(WEIGHTS)]
        pair, mid = self.held_columns(side)
        # ν_pair multiplies g(Q₃) − g(Q₁): its reaction is −ν at Q₁, +ν at Q₃
        held_mus = (-nu[..., pair], nu[..., mid], nu[..., pair])
        stage_mus = [jnp.where(held, mh, m) for m, mh in zip(mus, held_mus, strict=True)]
        forces = at_stages(multiplier_force, q, jnp.stack(stage_mus), t)
        stage_covectors = [-w * forces[j] for j, w in enumerate(WEIGHTS)]
        # the known node's reaction is a call of its own, not a fourth row of the stages'
        # batch: q_k is a constant of the step, but a row of a batch has the batch's
        # tangent, so the Newton Jacobian differentiated A at q_k along every unknown (zero
        # directions: a quarter of Andrews' largest fused kernel) — warm calls 11 % slower
        # than the stage loop there (benchmarks/README.md); on its own its tangent is zero
        nodal = jnp.where(held, mu, 0.0)
        zero = jnp.zeros_like(qk)
        if side == "plus":
            return [*stage_covectors, -multiplier_force(qk, nodal, tk), zero]
        return [*stage_covectors, zero, multiplier_force(qk1, nodal, tk + h)]

    @staticmethod
    def held_columns(side: str):
        """The ``ν`` columns of a holonomic row: ``(pair, mid)``, the row
        ``g(Q₃) − g(Q₁)`` in the column of the known end's stage and ``g(Q₂)`` in the
        other, as the one-form rows lay out their stages (:meth:`rows_of`)."""
        return (0, 1) if side == "plus" else (1, 0)

    def holonomic_rows(self, held_at, side, qk, stage, qk1, h, tk):
        r"""``g`` at the unknown end, and the stage rows ``g(Q₃, t_{k+1}) − g(Q₁, t_k)``
        and ``g(Q₂, t_k + h/2)`` in the columns of :meth:`held_columns`.

        With the nodal multiplier of :meth:`reaction_covectors` this is the discrete
        Lagrangian ``L_d(q_k, q_{k+1}) = ext h Σ_j b_j L(Q_j, V_j)`` over the stages that
        satisfy the two stage rows, restricted to ``g(q_k) = g(q_{k+1}) = 0``: a
        variational (symplectic) step on the constraint manifold whose known end's
        momentum direction ``∇g(q_known)`` is absorbed by ``μ``. Time reversal
        (``Q₁ ↔ Q₃``) maps the two rows to themselves up to sign, so the rule stays
        symmetric. ``g(Q₃) + g(Q₁)`` in place of the difference gives the same orbits but
        a step Jacobian that is singular where the stages coincide (the first guess);
        ``g(Q₁)`` and ``g(Q₃)`` separately drop the order to 2 (``docs/discretizations.md``).
        """
        q1, q2, q3 = self.stage_positions(qk, stage, qk1)
        q_end, t_end = (qk1, tk + h) if side == "plus" else (qk, tk)
        # g at (q_end, Q₁, Q₂, Q₃) in one batch
        g = at_stages(
            held_at, jnp.stack([q_end, q1, q2, q3]), _times(t_end, tk, tk + 0.5 * h, tk + h)
        )
        rows = [None, None]
        pair, mid = self.held_columns(side)
        rows[pair] = g[3] - g[1]
        rows[mid] = g[2]
        return g[0], jnp.stack(rows, axis=-1)

    def discrete_constraints(self, forms, side, qk, qk1, h, tk=0.0, offset=None, stage=None):
        r"""``(c_end, [c_a c_b])`` with ``c_j = A(Q_j, t_j) V_j + b(Q_j, t_j)``: the row at the
        unknown end's stage, shape (m,), and at the other two, shape (m, 2)."""
        if stage is None:
            self._need_stage("ω_d")

        def row(q, v, t):
            c = forms(q, t) @ v
            return c if offset is None else c + offset(q, t)

        values = at_stages(row, *self.stacked_nodes(qk, stage, qk1, h, tk))
        end, (a, b) = self.rows_of(side)
        return values[end], jnp.stack([values[a], values[b]], axis=-1)

    def step_energy(self, energy, qk, qk1, h, tk=0.0, stage=None):
        """The Simpson mean of ``E`` over the stages (``E`` at the chord midpoint when
        the stages are not known)."""
        if stage is None:
            return super().step_energy(energy, qk, qk1, h, tk)
        values = at_stages(energy, *self.stacked_nodes(qk, stage, qk1, h, tk))
        return sum(w * values[j] for j, w in enumerate(WEIGHTS))

    @staticmethod
    def stage_from_unknowns(side: str, qk, qk1, unknowns):
        """``[Q₁ Q₂]`` from the step's stage unknowns ``[Q_near Q₂]``, where ``Q_near`` is the
        stage at the known end (``Q₁`` for (+), ``Q₃ = q_k + q_{k+1} − Q₁`` for (−)): it is
        within O(h³) of the known end whichever way the scheme runs, so one guess serves
        both schemes and the affine map's increment ``Q_near − q`` is small."""
        if side == "plus":
            return unknowns
        return jnp.stack([qk - (unknowns[..., 0] - qk1), unknowns[..., 1]], axis=-1)

    def stage_guess(self, q, q_other_guess):
        """Starting ``[Q_near Q₂]``: the known end and the midpoint (see
        :meth:`stage_from_unknowns`)."""
        return jnp.stack([q, 0.5 * (q + q_other_guess)], axis=-1)


def _times(*times):
    """Node times (Python floats or scalars) as one array of shape (len(times),)."""
    return jnp.stack([jnp.asarray(t, dtype=jnp.result_type(*times)) for t in times])


def _stack(nodes):
    q, v, t = zip(*nodes, strict=True)
    return jnp.stack(q), jnp.stack(v), _times(*t)


def at_stages(fn, *stacked):
    """``fn`` at every stage at once: ``jax.vmap`` over the leading axis of ``stacked``.

    One trace of ``fn`` (of ``L``, ``F``, ``A``, ``g`` …) serves the three stages, and a
    derivative of the step is one derivative of that batched trace: with a Python loop
    over the stages the step's program held three copies of each model function and of
    each of its derivatives, which tripled its tracing and compile time (issue 30).
    The arithmetic of each stage is unchanged; the rule's weighted sums keep their order.
    """
    return jax.vmap(fn)(*stacked)


__all__ = ["IIID", "NODES", "WEIGHTS", "Lobatto"]
