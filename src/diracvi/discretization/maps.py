r"""The discrete maps of a rule on a system: momenta, constraint rows, reactions.

For a quadrature rule (:mod:`diracvi.discretization.base`) and a system ``(L, Δ, F)``:

    (P⁻, P⁺) = (−D₁L_d − f_d^−,  D₂L_d + f_d^+)        the discrete Legendre transforms
    ω_{d±}(q_k, q_{k+1}) = A(node±, t±) v_k + b(node±, t±);  g(q_end, t_end)/h
    r_j = −b_j A(Q_j, t_j)ᵀ μ_j                          reactions at a staged rule's stages

with ``L_d``, ``f_d^±`` and the nodes the rule's. These are functions of ``(rule,
system)``: the models know no rule, and a rule never calls a model back. A rule reaches
a system only through this small interface (every :class:`~diracvi.model.system.
DiracSystem` has it):

- ``lagrangian(q, v, t)``, ``force(q, v, t)`` and ``has_force`` (``False`` skips ``F``);
- ``one_forms(q, t)`` (``A``), ``has_offset`` and ``constraint_offset(q, t)`` (``b``),
  ``has_holonomic`` and ``position_constraints(q, t)`` (``g``), ``order_rows(rows)``
  (the system's order of its one-form and holonomic rows);
- ``multiplier_force(q, μ, t) = A(q, t)ᵀ μ``;

and an interconnection, in addition, through ``map_subsystems`` / ``join_subsystems``
(each subsystem's blocks, group by group when alike subsystems are packed),
``port_arrays()`` (the connections ``v_x − v_y``), ``incidence()`` (constant sparse rows,
a circuit's KCL: a :class:`~diracvi.model.sparse_rows.SparseRows`, applied as ``B @ v``
in O(non-zeros)) and ``general_rows()`` / ``general_forms(q)`` (the rows of general
interactions ``B(q)``).

A system may define its own ``discrete_momenta(rule, q_k, q_{k+1}, h, t_k)`` (a user
class implementing the protocol directly): :func:`discrete_momenta` then uses it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..model.interconnect import InterconnectedSystem


def discrete_momenta(rule, system, qk, qk1, h, tk=0.0, stage=None):
    r"""``(−D₁L_d − f_d^−, D₂L_d + f_d^+)`` at ``(q_k, q_{k+1})`` on ``[t_k, t_k + h]``.

    These are the two discrete Legendre transforms of the forced system: the (+)
    equations read ``p_k = first + A(q_k)ᵀ μ`` and ``p_{k+1} = second``. A rule with
    internal stages takes them as ``stage=`` and gives a third entry, ``D_Q L_d + f_Q``
    (the stage equations add the stage reactions). An interconnection stacks each
    subsystem's.
    """
    if isinstance(system, InterconnectedSystem):
        extra = () if stage is None else (stage,)
        parts = system.map_subsystems(
            lambda s, a, b, *st: discrete_momenta(rule, s, a, b, h, tk, *st), qk, qk1, *extra
        )
        return tuple(system.join_subsystems([p[j] for p in parts]) for j in range(2 + len(extra)))
    own = getattr(type(system), "discrete_momenta", None)
    if own is not None:  # the system gives its discrete Legendre transforms itself
        extra = {} if stage is None else {"stage": stage}
        return system.discrete_momenta(rule, qk, qk1, h, tk, **extra)
    if stage is not None:
        return _staged_momenta(rule, system, qk, stage, qk1, h, tk)
    d1, d2 = jax.grad(
        lambda a, b: rule.discrete_lagrangian(system.lagrangian, a, b, h, tk), argnums=(0, 1)
    )(qk, qk1)
    if not system.has_force:  # skip tracing a zero force
        return -d1, d2
    f_minus, f_plus = rule.discrete_forces(system.force, qk, qk1, h, tk)
    return -d1 - f_minus, d2 + f_plus


def _staged_momenta(rule, system, qk, stage, qk1, h, tk):
    d1, dq, d2 = jax.grad(
        lambda a, s, b: rule.discrete_lagrangian(system.lagrangian, a, b, h, tk, stage=s),
        argnums=(0, 1, 2),
    )(qk, stage, qk1)
    if not system.has_force:
        return -d1, d2, dq
    f_minus, f_plus, f_stage = rule.discrete_forces(system.force, qk, qk1, h, tk, stage=stage)
    return -d1 - f_minus, d2 + f_plus, dq + f_stage


def discrete_constraints(rule, system, side: str, qk, qk1, h, tk=0.0, stage=None):
    r"""``[A(node±, t±) v_k + b(node±, t±);  g(q_end, t_end)/h]``, in the system's row order.

    The holonomic rows are evaluated at the unknown end of the step (``q_{k+1}`` for
    (+), ``q_k`` for (−)) and scaled by ``1/h`` to the size of a velocity row. With
    internal stages (``stage=``), the pair (end rows, stage rows): the rule's one-form
    rows at its stages, and ``g`` at the unknown end and the rule's stage rows of ``g``
    (:meth:`~diracvi.discretization.base.QuadratureRule.holonomic_rows`). An
    interconnection: each subsystem's ``ω^i_{d±}``, then ``α_{d±}`` (the product
    retraction), each part of a staged pair in that order.
    """
    if isinstance(system, InterconnectedSystem):
        return _interconnected_constraints(rule, system, side, qk, qk1, h, tk, stage)
    if stage is not None:
        return _staged_constraints(rule, system, side, qk, stage, qk1, h, tk)
    rows = rule.discrete_constraints(
        system.one_forms,
        side,
        qk,
        qk1,
        h,
        tk,
        offset=system.constraint_offset if system.has_offset else None,
    )
    if system.has_holonomic:
        q_end, t_end = (qk1, tk + h) if side == "plus" else (qk, tk)
        rows = jnp.concatenate([rows, system.position_constraints(q_end, t_end) / h])
    return system.order_rows(rows)


def _staged_constraints(rule, system, side, qk, stage, qk1, h, tk):
    offset = system.constraint_offset if system.has_offset else None
    end, mid = rule.discrete_constraints(
        system.one_forms, side, qk, qk1, h, tk, offset=offset, stage=stage
    )
    if system.has_holonomic:
        g_end, g_mid = rule.holonomic_rows(system.position_constraints, side, qk, stage, qk1, h, tk)
        end = jnp.concatenate([end, g_end / h])
        mid = jnp.concatenate([mid, g_mid / h])
    return system.order_rows(end), system.order_rows(mid)


def _interconnected_constraints(rule, system, side, qk, qk1, h, tk, stage):
    extra = () if stage is None else (stage,)
    parts = system.map_subsystems(
        lambda s, a, b, *st: discrete_constraints(rule, s, side, a, b, h, tk, *st),
        qk,
        qk1,
        *extra,
    )
    inter = interaction_constraints(rule, system, side, qk, qk1, h, tk, stage)
    if stage is None:
        return jnp.concatenate([system.join_subsystems(parts, "m"), inter])
    own_end = system.join_subsystems([p[0] for p in parts], "m")
    own_mid = system.join_subsystems([p[1] for p in parts], "m")
    return jnp.concatenate([own_end, inter[0]]), jnp.concatenate([own_mid, inter[1]])


def interaction_constraints(rule, system, side: str, qk, qk1, h, tk=0.0, stage=None):
    r"""``α_{d±}(q_k, q_{k+1}) = B(node±) v_k``, with ``v_k = (q_{k+1} − q_k)/h``.

    With internal stages: the pair (end rows, stage rows), the rule's rows ``B(Q_j) V_j``
    at its stages."""
    if stage is not None:
        return _staged_interaction(rule, system, side, qk, stage, qk1, h, tk)
    out = jnp.zeros(len(system.interaction_names), dtype=qk.dtype)
    ports = system.port_arrays()
    if ports is not None:
        a, b, rows = ports
        v = (qk1 - qk) / h
        out = out.at[rows].set(v[a] - v[b])
    sparse = system.incidence()
    if sparse is not None:  # B v on its rows, zero on the others (the rule's quadrature
        # of a constant one-form: only its products B v are taken)
        out = out + rule.discrete_constraints(lambda q, t: sparse, side, qk, qk1, h, tk)
    index = system.general_rows()
    if index is not None:
        forms = system.general_forms
        general = rule.discrete_constraints(lambda q, t: forms(q), side, qk, qk1, h, tk)
        out = out.at[index].set(general)
    return out


def _staged_interaction(rule, system, side, qk, stage, qk1, h, tk):
    rows = len(system.interaction_names)
    end = jnp.zeros(rows, dtype=qk.dtype)
    mid = jnp.zeros((rows, *stage.shape[1:]), dtype=qk.dtype)  # one column per stage row
    ports = system.port_arrays()
    if ports is not None:
        a, b, index = ports
        # row by row, the rule's quadratures of v[x] − v[y] along the path: the
        # constant one-form dx − dy applied to the difference path
        e, s = rule.discrete_constraints(
            lambda q, t: jnp.eye(len(a), dtype=q.dtype),
            side,
            qk[a] - qk[b],
            qk1[a] - qk1[b],
            h,
            tk,
            stage=stage[a] - stage[b],
        )
        end, mid = end.at[index].set(e), mid.at[index].set(s)
    sparse = system.incidence()
    if sparse is not None:
        e, s = rule.discrete_constraints(lambda q, t: sparse, side, qk, qk1, h, tk, stage=stage)
        end, mid = end + e, mid + s
    index = system.general_rows()
    if index is not None:
        forms = system.general_forms
        e, s = rule.discrete_constraints(lambda q, t: forms(q), side, qk, qk1, h, tk, stage=stage)
        end, mid = end.at[index].set(e), mid.at[index].set(s)
    return end, mid


def reactions(rule, system, side: str, qk, stage, qk1, h, tk, mu, nu):
    r"""A staged rule's constraint reactions, ``−b_j A(Q_j, t_j)ᵀ μ_j`` at its stages
    (``h b_j A_jᵀ λ_j`` with ``λ_j = −μ_j/h``) for the one-form rows, ``μ`` at the unknown
    end's stage and ``ν`` (shape (m, stages)) at the others; the rule places the
    holonomic rows' reactions itself (:class:`~diracvi.discretization.lobatto.Lobatto`:
    ``μ`` at the known node). Pull them back with ``rule.pullback``."""
    # the rule places holonomic rows' reactions differently (lobatto: at the known node)
    held = jnp.asarray(system.holonomic_mask) if system.has_holonomic else None
    return rule.reaction_covectors(
        system.multiplier_force, side, qk, stage, qk1, h, tk, mu, nu, held=held
    )


__all__ = [
    "discrete_constraints",
    "discrete_momenta",
    "interaction_constraints",
    "reactions",
]
