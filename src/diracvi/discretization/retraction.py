r"""The paper's rule: left-point quadrature with the vector-space retraction (order 1).

    L_d = h L(q_k, v_k, t_k),
    ω_{d+} = A(q_k, t_k) v_k + b,   ω_{d−} = A(q_{k+1}, t_{k+1}) v_k + b,
    (f_d^−, f_d^+) = (h F(q_k, v_k, t_k), 0)

with ``v_k = (q_{k+1} − q_k)/h``, the inverse of ``R_q(v) = q + h v``. Forces follow the
discrete Lagrange–d'Alembert principle along the straight segment: the left-point rule
sees ``∂q(0)/∂q_k = 1``, ``∂q(0)/∂q_{k+1} = 0``.
"""

from __future__ import annotations

from .base import QuadratureRule


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


__all__ = ["Retraction"]
