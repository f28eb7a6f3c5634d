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

``"lobatto"`` (order 4) is a Galerkin rule with one *internal stage*: the path is the
quadratic through ``q_k``, ``Q`` (at ``t_k + h/2``) and ``q_{k+1}``, and Simpson's rule
(3-point Lobatto quadrature) is applied alike to L, the forces and the constraints. Its
stage ``Q`` and the stage multipliers are extra unknowns of the step (see :class:`Lobatto`
and ``docs/discretizations.md``).
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx

from ._errors import ModelError


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


#: Simpson weights of the nodes ``(t_k, t_k + h/2, t_{k+1})``
SIMPSON = (1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0)
#: ``∫`` over the first half step of a quadratic-path integrand from its three nodal
#: values (the Lobatto IIIA row of the stage), in units of h; mirrored for the second half
FIRST_HALF = (5.0 / 24.0, 1.0 / 3.0, -1.0 / 24.0)
SECOND_HALF = (-1.0 / 24.0, 1.0 / 3.0, 5.0 / 24.0)


class Lobatto(_CentredNodes, QuadratureRule):
    r"""The order-4 Galerkin rule: a quadratic path and Simpson (3-point Lobatto) quadrature.

    The path through ``q_k``, the internal stage ``Q`` and ``q_{k+1}`` has the nodal
    velocities ``v₀ = (−3q_k + 4Q − q_{k+1})/h``, ``v½ = (q_{k+1} − q_k)/h``,
    ``v₁ = (q_k − 4Q + 3q_{k+1})/h``; with weights ``w = (1/6, 4/6, 1/6)`` and node times
    ``t_j = t_k + (0, h/2, h)``::

        L_d(q_k, Q, q_{k+1}) = h Σ_j w_j L(q_j, v_j, t_j)
        (f_d^−, f_Q, f_d^+)  = h (w₀ F₀, w½ F½, w₁ F₁)          F_j = F(q_j, v_j, t_j)

    (the Lagrange basis of the path is 1 at its own node and 0 at the others, so each
    node's force goes to its own variation). A one-form row ``c_j = A(q_j, t_j) v_j +
    b(q_j, t_j)`` gives two constraint rows per step: the step integral
    ``Σ_j w_j c_j = 0`` (``ω_{d±}``) and the half-step integral ``Σ_j a_j c_j = 0``
    with the Lobatto IIIA weights ``a = (5, 8, −1)/24`` (first half, (+) scheme) or
    ``(−1, 8, 5)/24`` (second half, (−)); for constant ``A`` and ``b = 0`` both say that
    the whole quadratic path lies in ``ker A``. Order 4 (Ober-Blöbaum & Saake 2015 for the
    regular unconstrained case; measured for the constrained and degenerate ones).
    """

    def __init__(self):
        self.name = "lobatto"
        self.order = 4

    @property
    def stages(self) -> int:
        return 1

    def force_weights(self):
        return SIMPSON[0], SIMPSON[2]

    def impulse_share(self):
        # the node impulse h/6 A^T λ(t_k) belongs half to each of the two steps sharing it
        return 0.5

    @staticmethod
    def nodes(qk, stage, qk1, h, tk):
        """``(q_j, v_j, t_j)`` at the three Lobatto nodes of the quadratic path."""
        v0 = (-3.0 * qk + 4.0 * stage - qk1) / h
        vh = (qk1 - qk) / h
        v1 = (qk - 4.0 * stage + 3.0 * qk1) / h
        return ((qk, v0, tk), (stage, vh, tk + 0.5 * h), (qk1, v1, tk + h))

    def _need_stage(self, what: str):
        raise ModelError(
            f"discretization='lobatto' cannot evaluate {what} from (q_k, q_(k+1)) alone: it "
            "needs the step's internal stage Q. Fix: use the staged forms (pass stage=Q), "
            "or discretization='midpoint' for this diagnostic."
        )

    def discrete_lagrangian(self, lagrangian, qk, qk1, h, tk=0.0, stage=None):
        r"""``L_d = h Σ_j w_j L(q_j, v_j, t_j)`` along the quadratic path."""
        if stage is None:
            self._need_stage("L_d")
        return h * sum(
            w * lagrangian(q, v, t)
            for w, (q, v, t) in zip(SIMPSON, self.nodes(qk, stage, qk1, h, tk), strict=True)
        )

    def discrete_forces(self, force, qk, qk1, h, tk=0.0, stage=None):
        r"""``(f_d^−, f_d^+, f_Q) = h (w₀ F₀, w₁ F₁, w½ F½)``."""
        if stage is None:
            self._need_stage("f_d")
        f0, fh, f1 = (
            h * w * force(q, v, t)
            for w, (q, v, t) in zip(SIMPSON, self.nodes(qk, stage, qk1, h, tk), strict=True)
        )
        return f0, f1, fh

    def discrete_constraints(self, forms, side, qk, qk1, h, tk=0.0, offset=None, stage=None):
        r"""``(Σ_j w_j c_j, Σ_j a_j c_j)`` with ``c_j = A(q_j, t_j) v_j + b(q_j, t_j)``."""
        if stage is None:
            self._need_stage("ω_d")
        values = []
        for q, v, t in self.nodes(qk, stage, qk1, h, tk):
            c = forms(q, t) @ v
            values.append(c if offset is None else c + offset(q, t))
        half = FIRST_HALF if side == "plus" else SECOND_HALF
        whole = sum(w * c for w, c in zip(SIMPSON, values, strict=True))
        part = sum(a * c for a, c in zip(half, values, strict=True))
        return whole, part

    def step_energy(self, energy, qk, qk1, h, tk=0.0, stage=None):
        """The Simpson mean of ``E`` along the step's path (``E`` at the chord midpoint
        when the stage is not known)."""
        if stage is None:
            return super().step_energy(energy, qk, qk1, h, tk)
        return sum(
            w * energy(q, v, t)
            for w, (q, v, t) in zip(SIMPSON, self.nodes(qk, stage, qk1, h, tk), strict=True)
        )

    def stage_guess(self, q, q_other_guess):
        """A starting value of ``Q``: the midpoint of the two ends."""
        return 0.5 * (q + q_other_guess)


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
