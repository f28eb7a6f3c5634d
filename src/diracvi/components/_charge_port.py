r"""A part with a **charge port**: a charge ``Q(q, q̇)`` that is not the momentum of a
Lagrangian (its velocity Jacobian need not be symmetric), entered as SPICE enters charges.

Continuous equations: the port adds the force ``−d/dt Q(q, q̇)`` to the part's lines,

    d/dt (∂L/∂q̇ + Q(q, q̇)) = ∂L/∂q + F + Aᵀμ,

so the state momentum is ``p = ∂L/∂q̇ + Q`` (for a circuit branch in flux form, the
``w``-line reads ``q̇ = i + dQ_L/dt + dQ/dt``: the charge's current ``dQ/dt`` flows beside
the branch's own). When ``∂Q/∂q̇`` is symmetric ``Q = ∂C*/∂q̇`` for a co-energy ``C*`` and
``Q`` could sit in ``L``; when it is not (Gummel–Poon's ``TF·I_be/q_b``), no Lagrangian
gives it and the port is a resistive-like element: it does not touch the Dirac structure
(KCL, the parts' Lagrangians), and its power ``−⟨dQ/dt, q̇⟩`` enters the power balance
``dE/dt = ⟨F, q̇⟩ − ⟨dQ/dt, q̇⟩`` as a source term, like a controlled source's.

Discrete equations. The Lagrange–d'Alembert pair of the force ``−dQ/dt`` on one step,
``∫ −Q̇ φ_{k,k+1} dt`` with the hat functions ``φ``, is ``(Q(t_k) − Q̄, Q̄ − Q(t_{k+1}))``
after an integration by parts, ``Q̄ = (1/h)∫Q dt``. The node values ``Q(t_k)`` cancel
between neighbouring steps; carried in the momentum (``p = ∂L/∂q̇ + Q``, the same
augmentation as the continuous one) they leave

    p_k     = −D₁L_d − f_d^− + Q̄_k + Aᵀμ,     p_{k+1} = D₂L_d + f_d^+ + Q̄_k,

with ``Q̄_k = Q(node, v_k, t_node)`` at the rule's node. Chained over two steps this is
``Q̄_k − Q̄_{k−1} = …``: the charge's change over a step, as SPICE's charge-based
companion model integrates ``dQ/dt``. A rule with internal stages is not supported (the
port's pair is defined for two-point rules).
"""

from __future__ import annotations

import jax

from ..errors import ModelError
from ..model.system import _user_function
from .controlled import ControlledPart


class ChargePortPart(ControlledPart):
    r"""A :class:`ControlledPart` with a charge port ``Q(q, v)`` (a covector, shape (n,)):
    its momentum is ``∂L/∂v + Q`` and its discrete Legendre transforms carry ``Q̄_k`` (the
    module's docstring derives them). ``charge`` is ``Q(q, v)``; the rest as
    :class:`ControlledPart`."""

    _charge: object

    def __init__(self, *args, charge, **kwargs):
        super().__init__(*args, **kwargs)
        n = len(self.coords)
        self._charge, out = _user_function("charge", charge, [(n,), (n,)], "Q(q, v)", "Q(q, v, t)")
        if out.shape != (n,):
            raise ModelError(
                f"part {self.name!r}: charge returned shape {out.shape}; it must return a "
                f"covector of shape ({n},), one charge per coordinate {self.coords}."
            )

    def charge(self, q, v, t=0.0):
        """The port's charge ``Q(q, v, t)``, shape (n,)."""
        return self._charge(q, v, t=t)

    def momentum(self, q, v, t=0.0):
        r"""``p = ∂L/∂v(q, v, t) + Q(q, v, t)``."""
        return jax.grad(self.lagrangian, argnums=1)(q, v, t) + self.charge(q, v, t)

    def port_charge(self, rule, qk, qk1, h, tk=0.0):
        """``Q̄_k = Q(node, v_k, t_node)``: the charge the rule assigns to the step."""
        return self.charge(rule.node(qk, qk1), (qk1 - qk) / h, rule.time_node(tk, h))

    def discrete_momenta(self, rule, qk, qk1, h, tk=0.0, stage=None):
        r"""``(−D₁L_d − f_d^− + Q̄_k, D₂L_d + f_d^+ + Q̄_k)``."""
        if stage is not None or getattr(rule, "stages", 0):
            raise ModelError(
                f"part {self.name!r} has a charge port (a charge that is not the momentum of "
                f"a Lagrangian), defined for two-point rules only; rule {rule.name!r} has "
                "internal stages: use discretization='midpoint'."
            )
        d1, d2 = jax.grad(
            lambda a, b: rule.discrete_lagrangian(self.lagrangian, a, b, h, tk), argnums=(0, 1)
        )(qk, qk1)
        f_minus, f_plus = rule.discrete_forces(self.force, qk, qk1, h, tk)
        charge = self.port_charge(rule, qk, qk1, h, tk)
        return -d1 - f_minus + charge, d2 + f_plus + charge


__all__ = ["ChargePortPart"]
