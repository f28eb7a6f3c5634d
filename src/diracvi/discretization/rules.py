r"""Quadrature rules: one place that turns L, ω and F into L_d, ω_{d±} and f_d^±.

A discretization is a quadrature rule applied *alike* to the Lagrangian, the constraint
one-forms and the forces (DESIGN.md §1). With ``v_k = (q_{k+1} − q_k)/h`` (the inverse of
the vector-space retraction ``R_q(v) = q + h v``):

- ``"retraction"`` (the paper's, order 1): ``L_d = h L(q_k, v_k)``,
  ``ω_{d+} = A(q_k) v_k``, ``(f_d^−, f_d^+) = (h F(q_k, v_k), 0)``;
- ``"midpoint"`` (symmetric, order 2): ``L_d = h L(q̄, v_k)``, ``ω_{d±} = A(q̄) v_k``,
  ``(f_d^−, f_d^+) = (h/2 F(q̄, v_k), h/2 F(q̄, v_k))``,

with ``q̄ = (q_k + q_{k+1})/2``; the (−) constraint of the retraction rule is
``ω_{d−} = A(q_{k+1}) v_k``.

Time-dependent models ``L(q, v, t)``, ``F(q, v, t)``, ``A(q, t) v + b(q, t) = 0`` see time
at the rule's own node: the retraction rule evaluates L and F at ``t_k`` and ``ω_{d±}`` at
the time of its configuration node (``t_k`` for (+), ``t_{k+1}`` for (−)); the midpoint
rule evaluates everything at ``t_k + h/2``. The affine term ``b`` of a constraint is
discretized with the same rule as ``A``: ``ω_{d±} = A(node±, t±) v_k + b(node±, t±)``.

Forces follow the discrete Lagrange–d'Alembert principle
``f_d^∓ ≈ ∫ F · ∂q(t)/∂q_{k,k+1} dt`` along the straight segment
``q(t) = q_k + t v_k``: the left-point rule sees ``∂q(0)/∂q_k = 1``, ``∂q(0)/∂q_{k+1} = 0``;
the midpoint rule sees ``1/2`` for each end.

``"lobatto"`` (order 4) is Lobatto IIID in Hamilton–Pontryagin form: three stage
velocities at ``t_k + (0, ½, 1) h``, stage positions ``Q_i = q_k + h Σ_j a_ij V_j``, and
L, the forces, the inputs and the one-forms evaluated at the stages. Its stage positions
``Q₁, Q₂`` and one multiplier vector per stage are extra unknowns of the step (see
:class:`Lobatto` and ``docs/discretizations.md``).
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp

from ..errors import ModelError


class QuadratureRule(eqx.Module):
    """A rule for discretizing L, ω and F on one step ``[q_k, q_{k+1}]``."""

    name: str = eqx.field(static=True)
    order: int = eqx.field(static=True)

    @property
    def stages(self) -> int:
        """Internal stages per step (extra unknowns ``(Q, ν)`` of the step equations)."""
        return 0

    def step_energy(self, energy: Callable, qk, qk1, h, tk=0.0, stage=None):
        """The energy reported for a step: ``E(node, v_k, t_node)``."""
        return energy(self.node(qk, qk1), (qk1 - qk) / h, self.time_node(tk, h))

    def node(self, qk, qk1):
        """The configuration at which L, F (and E for diagnostics) are evaluated."""
        raise NotImplementedError

    def time_node(self, tk, h):
        """The time at which L, F (and E) are evaluated on the step ``[t_k, t_k + h]``."""
        raise NotImplementedError

    def constraint_node(self, side: str, qk, qk1):
        """The configuration at which ω_{d±} evaluates the one-forms A(q)."""
        raise NotImplementedError

    def constraint_time(self, side: str, tk, h):
        """The time that goes with :meth:`constraint_node`."""
        raise NotImplementedError

    def force_weights(self) -> tuple[float, float]:
        """Weights ``(w⁻, w⁺)`` with ``f_d^∓ = w^∓ h F(node, v_k)``."""
        raise NotImplementedError

    def impulse_share(self) -> float:
        """The share of a step's constraint impulse that belongs to the far end of the step.

        The (±) equations put the whole impulse ``A(·)ᵀμ`` on the known end's momentum
        line, so the stepped momentum lags the true one by this share of it (½ for the
        symmetric midpoint rule; 0 for the first-order left-point rule, whose force
        quadrature puts everything on the left end anyway).
        """
        raise NotImplementedError

    def discrete_lagrangian(self, lagrangian: Callable, qk, qk1, h, tk=0.0):
        r"""``L_d(q_k, q_{k+1}) = h L(node, (q_{k+1} − q_k)/h, t_node)``."""
        return h * lagrangian(self.node(qk, qk1), (qk1 - qk) / h, self.time_node(tk, h))

    def discrete_forces(self, force: Callable, qk, qk1, h, tk=0.0):
        r"""``(f_d^−, f_d^+)``: the rule applied to ``∫ F · ∂q/∂q_{k,k+1} dt``."""
        f = h * force(self.node(qk, qk1), (qk1 - qk) / h, self.time_node(tk, h))
        w_minus, w_plus = self.force_weights()
        return w_minus * f, w_plus * f

    def discrete_constraints(self, forms: Callable, side: str, qk, qk1, h, tk=0.0, offset=None):
        r"""``ω_{d±}(q_k, q_{k+1}) = A(node±, t±) (q_{k+1} − q_k)/h + b(node±, t±)``.

        ``forms(q, t)`` gives ``A``; ``offset(q, t)`` the affine term ``b`` (or ``None``).
        """
        node, t = self.constraint_node(side, qk, qk1), self.constraint_time(side, tk, h)
        out = forms(node, t) @ ((qk1 - qk) / h)
        return out if offset is None else out + offset(node, t)


class Retraction(QuadratureRule):
    """The paper's rule: left-point quadrature with the vector-space retraction (order 1)."""

    def __init__(self):
        self.name = "retraction"
        self.order = 1

    def node(self, qk, qk1):
        return qk

    def time_node(self, tk, h):
        return tk

    def constraint_node(self, side, qk, qk1):
        return qk if side == "plus" else qk1

    def constraint_time(self, side, tk, h):
        return tk if side == "plus" else tk + h

    def force_weights(self):
        return 1.0, 0.0

    def impulse_share(self):
        return 0.0


class _CentredNodes:
    """Nodes of the symmetric rules: ``q̄ = (q_k + q_{k+1})/2`` at ``t_k + h/2``, for the
    Lagrangian, the forces and the one-forms alike (both schemes)."""

    def node(self, qk, qk1):
        return 0.5 * (qk + qk1)

    def time_node(self, tk, h):
        return tk + 0.5 * h

    def constraint_node(self, side, qk, qk1):
        return 0.5 * (qk + qk1)

    def constraint_time(self, side, tk, h):
        return tk + 0.5 * h


class Midpoint(_CentredNodes, QuadratureRule):
    """The symmetric midpoint rule (order 2); ω_{d+} = ω_{d−}, so (+) and (−) agree."""

    def __init__(self):
        self.name = "midpoint"
        self.order = 2

    def force_weights(self):
        return 0.5, 0.5

    def impulse_share(self):
        return 0.5


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


class Lobatto(_CentredNodes, QuadratureRule):
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

    @staticmethod
    def pullback(covectors):
        r"""``(φ₁, φ₂, φ₃)`` at the stage positions → their pull-back to ``(q_k, [Q₁ Q₂],
        q_{k+1})``: ``Σ_j φ_j ∂Q_j/∂(·)``, with ``∂Q₃/∂(q_k, Q₁, q_{k+1}) = (1, −1, 1)``."""
        f1, f2, f3 = covectors
        return f3, jnp.stack([f1 - f3, f2], axis=-1), f3

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
        nodes = self.nodes(qk, stage, qk1, h, tk)
        return h * sum(w * lagrangian(q, v, t) for w, (q, v, t) in zip(WEIGHTS, nodes, strict=True))

    def discrete_forces(self, force, qk, qk1, h, tk=0.0, stage=None):
        r"""``(f_d^−, f_d^+, f_Q)``: the pull-back of ``h b_j F(Q_j, V_j, t_j)``."""
        if stage is None:
            self._need_stage("f_d")
        nodes = self.nodes(qk, stage, qk1, h, tk)
        left, mid, right = self.pullback(
            [h * w * force(q, v, t) for w, (q, v, t) in zip(WEIGHTS, nodes, strict=True)]
        )
        return left, right, mid

    def reaction_covectors(self, multiplier_force, side, qk, stage, qk1, h, tk, mu, nu):
        r"""``−b_j A(Q_j, t_j)ᵀ μ_j`` at each stage (``h b_j A_jᵀ λ_j`` with ``λ_j = −μ_j/h``);
        ``multiplier_force(q, μ, t) = A(q, t)ᵀ μ``."""
        end, mids = self.rows_of(side)
        mus = [None] * 3
        mus[end], mus[mids[0]], mus[mids[1]] = mu, nu[..., 0], nu[..., 1]
        nodes = self.nodes(qk, stage, qk1, h, tk)
        return [
            -w * multiplier_force(q, m, t)
            for w, (q, _, t), m in zip(WEIGHTS, nodes, mus, strict=True)
        ]

    def discrete_constraints(self, forms, side, qk, qk1, h, tk=0.0, offset=None, stage=None):
        r"""``(c_end, [c_a c_b])`` with ``c_j = A(Q_j, t_j) V_j + b(Q_j, t_j)``: the row at the
        unknown end's stage, shape (m,), and at the other two, shape (m, 2)."""
        if stage is None:
            self._need_stage("ω_d")
        values = []
        for q, v, t in self.nodes(qk, stage, qk1, h, tk):
            c = forms(q, t) @ v
            values.append(c if offset is None else c + offset(q, t))
        end, (a, b) = self.rows_of(side)
        return values[end], jnp.stack([values[a], values[b]], axis=-1)

    def holonomic_points(self, side, qk, stage, qk1, h, tk):
        """Where ``g(q, t) = 0`` is imposed: the unknown end itself (so every stored
        configuration is on the constraint), and the two other stages."""
        qs = self.stage_positions(qk, stage, qk1)
        ts = (tk, tk + 0.5 * h, tk + h)
        end, (a, b) = self.rows_of(side)
        q_end = qk1 if side == "plus" else qk
        return (q_end, ts[end]), ((qs[a], ts[a]), (qs[b], ts[b]))

    def step_energy(self, energy, qk, qk1, h, tk=0.0, stage=None):
        """The Simpson mean of ``E`` over the stages (``E`` at the chord midpoint when
        the stages are not known)."""
        if stage is None:
            return super().step_energy(energy, qk, qk1, h, tk)
        nodes = self.nodes(qk, stage, qk1, h, tk)
        return sum(w * energy(q, v, t) for w, (q, v, t) in zip(WEIGHTS, nodes, strict=True))

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


RULES: dict[str, type[QuadratureRule]] = {
    "retraction": Retraction,
    "midpoint": Midpoint,
    "lobatto": Lobatto,
}


_INSTANCES: dict[str, QuadratureRule] = {}


def get_rule(name: str) -> QuadratureRule:
    """The rule called ``name`` (rules are immutable, so one instance serves every run)."""
    if name not in _INSTANCES:
        _INSTANCES[name] = RULES[name]()
    return _INSTANCES[name]


__all__ = ["RULES", "Lobatto", "Midpoint", "QuadratureRule", "Retraction", "get_rule"]
