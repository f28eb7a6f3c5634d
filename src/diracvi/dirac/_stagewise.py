r"""The discrete Dirac condition of a staged step, stage by stage, from the kept stages.

A staged rule (``"lobatto"``: Lobatto IIID, three nodes ``t_j = t_k + c_j h``) is a
variational partitioned Runge–Kutta step. Written with the stage data a run keeps when
asked (``simulate(..., keep_stages=True)``: the stage positions ``Q_j``, their multipliers
``ν`` beside the step's ``μ``), the step ``(q_k, p_k) → (q_{k+1}, p_{k+1})`` is a point
of the induced Dirac structure at every stage node plus a discrete step relation:

1. **Stage velocities.** ``Q_i = q_k + h Σ_j a_ij V_j``, ``q_{k+1} = q_k + h Σ_j b_j V_j``
   (the rule's :meth:`~diracvi.discretization.lobatto.Lobatto.nodes`): ``Q̇_j = V_j`` is
   the ``α_p`` slot of the Dirac condition, ``α_p − Ω^♭(X)_p = V_j − Q̇_j = 0``, and holds
   by construction.
2. **Stage momenta** (the Legendre slot of ``𝔇L``): ``P_j = ∂L/∂v(Q_j, V_j, t_j)``; their
   rates ``Ṗ_j`` from the momentum stages ``P_i = p̂_k + h Σ_j â_ij Ṗ_j`` (``â`` invertible:
   IIID), ``p̂`` the node momenta without the holonomic rows' nodal impulses ``ψ``
   (``p̂_k = p_k + ψ_k``, ``p̂_{k+1} = p_{k+1} − ψ_{k+1}``; ``ψ = 0`` without holonomic rows).
3. **Induced Dirac structure at each node** ``j``, forced: ``(X_j, 𝔇L(Q_j, V_j) − F̃_j) ∈
   D_Δ(Q_j)``, i.e. ``V_j ∈ Δ(Q_j)`` and ``Ṗ_j − ∂L/∂q − F ∈ Δ°(Q_j)``, with the step's own
   multipliers as the witness, ``h b_j (Ṗ_j − ∂L/∂q − F) = R_j`` where
   ``R_j = h b_j A(Q_j)ᵀ λ_j = −b_j A(Q_j)ᵀ μ_j`` (the rule's
   :meth:`~diracvi.discretization.lobatto.Lobatto.reaction_covectors`, which also place the
   holonomic stage rows' ``∇g(Q_j)ᵀ``). The residual ``fiber_j`` is the left side minus
   the right, in momentum units.
4. **Discrete step relation**: ``p̂_{k+1} = p̂_k + h Σ_j b_j Ṗ_j`` (residual ``base``).
5. **Discrete distribution**: the rule's rows at every node, ``A(Q_j) V_j + b(Q_j) = 0``
   (and a holonomic row's position rows ``g(q_end)``, ``g(Q₂)``, ``g(Q₃) − g(Q₁)`` over
   ``h``) (residual ``constraint``).

Equations 2–5 are ``4n + 3m`` conditions on the step's ``q_other, μ, Q, ν`` and its new
momentum: as many as the step equations, of which they are a rewriting, so a run of the
rule gives round-off and a change of any kept stage, multiplier or momentum shows.
Without kept stages :mod:`._staged` re-solves them from the states instead.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.maps import discrete_constraints, reactions


def stagewise_parts(system, rule, side: str, h: float, q0, p0, q1, p1, tk, stages, mu, nu):
    """``{constraint, base, fiber, multipliers}`` of every step (arrays over steps):
    ``constraint`` (K, 3m) the rows at the nodes (the unknown end's first), ``base`` (K, n)
    the step relation, ``fiber`` (K, 3n) the stage conditions, ``multipliers`` the kept
    ``μ``. ``stages`` (K, n, s) and ``nu`` (K, m, s) as ``traj.stages`` and
    ``traj.stage_multipliers`` hold them."""
    a_hat, weights = np.asarray(rule.tableau()[1]), np.asarray(rule.tableau()[2])
    arrays = [jnp.asarray(x) for x in (q0, p0, q1, p1, tk, stages, mu, nu)]
    out = _batched(system, rule, side, h, np.linalg.inv(a_hat), weights, *arrays)
    constraint, base, fiber = (np.asarray(x) for x in out)
    return {"constraint": constraint, "base": base, "fiber": fiber, "multipliers": np.asarray(mu)}


@eqx.filter_jit  # one compilation per system, rule, side, h and number of steps
def _batched(system, rule, side, h, a_hat_inv, weights, q0, p0, q1, p1, tk, stages, mu, nu):
    grad_q = jax.grad(system.lagrangian, argnums=0)
    grad_v = jax.grad(system.lagrangian, argnums=1)

    def one(qk, pk, qk1, pk1, t, stage, m_, n_):
        nodes = rule.nodes(qk, stage, qk1, h, t)
        count = len(nodes)
        covectors = reactions(rule, system, side, qk, stage, qk1, h, t, m_, n_)
        stage_r = jnp.stack(covectors[:count])
        psi_k, psi_k1 = (
            (covectors[count], covectors[count + 1]) if len(covectors) > count else (0.0, 0.0)
        )
        p_start, p_end = pk + psi_k, pk1 - psi_k1
        momenta = jnp.stack([grad_v(q, v, s) for q, v, s in nodes])  # P_j = ∂L/∂v
        pulls = jnp.stack([grad_q(q, v, s) for q, v, s in nodes])  # ∂L/∂q (+ F)
        if system.has_force:
            pulls = pulls + jnp.stack([system.force(q, v, s) for q, v, s in nodes])
        rates = a_hat_inv @ (momenta - p_start)  # h Ṗ_j
        fiber = weights[:, None] * (rates - h * pulls) - stage_r
        base = p_end - p_start - weights @ rates
        c_end, c_mid = discrete_constraints(rule, system, side, qk, qk1, h, t, stage=stage)
        return jnp.concatenate([c_end, c_mid.T.ravel()]), base, fiber.ravel()

    return jax.vmap(one)(q0, p0, q1, p1, tk, stages, mu, nu)
