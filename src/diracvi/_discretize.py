r"""Quadrature rules: one place that turns L, ω and F into L_d, ω_{d±} and f_d^±.

A discretization is a quadrature rule applied *alike* to the Lagrangian, the constraint
one-forms and the forces (DESIGN.md §1). With ``v_k = (q_{k+1} − q_k)/h`` (the inverse of
the vector-space retraction ``R_q(v) = q + h v``):

- ``"retraction"`` (the paper's, order 1): ``L_d = h L(q_k, v_k)``,
  ``ω_{d+} = A(q_k) v_k``, ``(f_d^−, f_d^+) = (h F(q_k, v_k), 0)``;
- ``"midpoint"`` (symmetric, order 2): ``L_d = h L(q̄, v_k)``, ``ω_{d±} = A(q̄) v_k``,
  ``(f_d^−, f_d^+) = (h/2 F(q̄, v_k), h/2 F(q̄, v_k))``,

with ``q̄ = (q_k + q_{k+1})/2``; the (−) constraint of the retraction rule is
``ω_{d−} = A(q_{k+1}) v_k``. Forces follow the discrete Lagrange–d'Alembert principle
``f_d^∓ ≈ ∫ F · ∂q(t)/∂q_{k,k+1} dt`` along the straight segment
``q(t) = q_k + t v_k``: the left-point rule sees ``∂q(0)/∂q_k = 1``, ``∂q(0)/∂q_{k+1} = 0``;
the midpoint rule sees ``1/2`` for each end.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx


class QuadratureRule(eqx.Module):
    """A rule for discretizing L, ω and F on one step ``[q_k, q_{k+1}]``."""

    name: str = eqx.field(static=True)
    order: int = eqx.field(static=True)

    def node(self, qk, qk1):
        """The configuration at which L, F (and E for diagnostics) are evaluated."""
        raise NotImplementedError

    def constraint_node(self, side: str, qk, qk1):
        """The configuration at which ω_{d±} evaluates the one-forms A(q)."""
        raise NotImplementedError

    def force_weights(self) -> tuple[float, float]:
        """Weights ``(w⁻, w⁺)`` with ``f_d^∓ = w^∓ h F(node, v_k)``."""
        raise NotImplementedError

    def discrete_lagrangian(self, lagrangian: Callable, qk, qk1, h):
        r"""``L_d(q_k, q_{k+1}) = h L(node, (q_{k+1} − q_k)/h)``."""
        return h * lagrangian(self.node(qk, qk1), (qk1 - qk) / h)

    def discrete_forces(self, force: Callable, qk, qk1, h):
        r"""``(f_d^−, f_d^+)``: the rule applied to ``∫ F · ∂q/∂q_{k,k+1} dt``."""
        f = h * force(self.node(qk, qk1), (qk1 - qk) / h)
        w_minus, w_plus = self.force_weights()
        return w_minus * f, w_plus * f

    def discrete_constraints(self, forms: Callable, side: str, qk, qk1, h):
        r"""``ω_{d±}(q_k, q_{k+1}) = A(node±) (q_{k+1} − q_k)/h``."""
        return forms(self.constraint_node(side, qk, qk1)) @ ((qk1 - qk) / h)


class Retraction(QuadratureRule):
    """The paper's rule: left-point quadrature with the vector-space retraction (order 1)."""

    def __init__(self):
        self.name = "retraction"
        self.order = 1

    def node(self, qk, qk1):
        return qk

    def constraint_node(self, side, qk, qk1):
        return qk if side == "plus" else qk1

    def force_weights(self):
        return 1.0, 0.0


class Midpoint(QuadratureRule):
    """The symmetric midpoint rule (order 2); ω_{d+} = ω_{d−}, so (+) and (−) agree."""

    def __init__(self):
        self.name = "midpoint"
        self.order = 2

    def node(self, qk, qk1):
        return 0.5 * (qk + qk1)

    def constraint_node(self, side, qk, qk1):
        return 0.5 * (qk + qk1)

    def force_weights(self):
        return 0.5, 0.5


RULES: dict[str, type[QuadratureRule]] = {"retraction": Retraction, "midpoint": Midpoint}


_INSTANCES: dict[str, QuadratureRule] = {}


def get_rule(name: str) -> QuadratureRule:
    """The rule called ``name`` (rules are immutable, so one instance serves every run)."""
    if name not in _INSTANCES:
        _INSTANCES[name] = RULES[name]()
    return _INSTANCES[name]


__all__ = ["RULES", "Midpoint", "QuadratureRule", "Retraction", "get_rule"]
