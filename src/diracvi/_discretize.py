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


class Midpoint(QuadratureRule):
    """The symmetric midpoint rule (order 2); ω_{d+} = ω_{d−}, so (+) and (−) agree."""

    def __init__(self):
        self.name = "midpoint"
        self.order = 2

    def node(self, qk, qk1):
        return 0.5 * (qk + qk1)

    def time_node(self, tk, h):
        return tk + 0.5 * h

    def constraint_node(self, side, qk, qk1):
        return 0.5 * (qk + qk1)

    def constraint_time(self, side, tk, h):
        return tk + 0.5 * h

    def force_weights(self):
        return 0.5, 0.5

    def impulse_share(self):
        return 0.5


RULES: dict[str, type[QuadratureRule]] = {"retraction": Retraction, "midpoint": Midpoint}


_INSTANCES: dict[str, QuadratureRule] = {}


def get_rule(name: str) -> QuadratureRule:
    """The rule called ``name`` (rules are immutable, so one instance serves every run)."""
    if name not in _INSTANCES:
        _INSTANCES[name] = RULES[name]()
    return _INSTANCES[name]


__all__ = ["RULES", "Midpoint", "QuadratureRule", "Retraction", "get_rule"]
