r"""The symmetric midpoint rule (order 2): everything at ``q̄ = (q_k + q_{k+1})/2``, ``t_k + h/2``.

    L_d = h L(q̄, v_k, t̄),   ω_{d±} = A(q̄, t̄) v_k + b(q̄, t̄),
    (f_d^−, f_d^+) = (h/2 F(q̄, v_k, t̄), h/2 F(q̄, v_k, t̄))

Along the straight segment each end sees ``∂q(½)/∂q_{k,k+1} = ½`` of the force.
"""

from __future__ import annotations

from .base import QuadratureRule


class CentredNodes:
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


class Midpoint(CentredNodes, QuadratureRule):
    """The symmetric midpoint rule (order 2); ω_{d+} = ω_{d−}, so (+) and (−) agree."""

    def __init__(self):
        self.name = "midpoint"
        self.order = 2

    def force_weights(self):
        return 0.5, 0.5

    def impulse_share(self):
        return 0.5


__all__ = ["CentredNodes", "Midpoint"]
