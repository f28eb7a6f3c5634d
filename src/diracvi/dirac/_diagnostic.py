r"""Does a trajectory lie in the discrete Dirac structure? ``(X_d^k, 𝔇^±L_d) ∈ D^{d±}_Δ``.

For every step ``k`` of a trajectory, with ``X_d^k = ((q_k, p_k), (q_{k+1}, p_{k+1}))`` and
the forced discrete Dirac differential built from the system's discrete momenta
``(P⁻, P⁺) = (−D₁L_d − f_d^−, D₂L_d + f_d^+)`` at ``(q_k, q_{k+1})`` (see
:mod:`diracvi.dirac._tulczyjew`):

- ``scheme="plus"``: ``𝔇⁺ = (q_k, P⁺ | P⁻, q_{k+1})`` must lie in ``D^{d+}_Δ`` over
  ``X_d^k``: base point ``p_{k+1} = P⁺``; ``ω_{d+}(q_k, q_{k+1}) = 0``;
  ``P⁻ − p_k ∈ Δ°(q_k)``.
- ``scheme="minus"``: ``𝔇⁻ = (P⁻, q_{k+1} | −q_k, −P⁺) ∈ D^{d−}_Δ``: base point
  ``p_k = P⁻``; ``ω_{d−}(q_k, q_{k+1}) = 0``; ``p_{k+1} − P⁺ ∈ Δ°(q_{k+1})``.

Driven systems (``L``, ``F`` depending on ``t``) are checked with each step's own time.
Holonomic rows and affine terms ``b`` are not one-forms, so ``D^{d±}_Δ`` of the paper does
not contain them: their constraint rows are the system's own ``g(q_{k+1})/h`` and
``A v_k + b``, which must vanish, and their reactions ``∇g``, ``A`` span the fibre
condition as any one-form does. Time-dependent one-forms ``A(q, t)`` are refused (the
structure would change along the step).

The discrete velocity ``q_k⁺`` (``q_{k+1}⁻``) is set to ``q_{k+1}`` (``q_k``), which makes
the condition ``q_{k+1} = q_k⁺`` hold by construction. Nothing here calls the
integrator's equations: the check uses only the ``DiracSystem`` protocol
(``constraint_forms``, ``n``), the rule's discrete momenta
(:func:`~diracvi.discretization.maps.discrete_momenta`) and the structure's membership
code.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.maps import discrete_constraints, discrete_momenta
from ..discretization.rules import RULES, get_rule
from ..errors import ModelError
from ._discrete import InducedDiscrete, combine
from ._staged import staged_parts
from ._stagewise import stagewise_parts
from ._tulczyjew import as_rule


def _rule(name):
    """The rule of a trajectory: a staged one is checked by :mod:`._staged`, a two-point one
    by the structure ``D^{d±}_Δ`` (:func:`~diracvi.dirac._tulczyjew.as_rule`)."""
    return get_rule(name) if name in RULES and get_rule(name).stages else as_rule(name)


class StepResiduals(NamedTuple):
    """The pieces of ``(X_d^k, 𝔇^±L_d) ∈ D^{d±}_Δ`` per step (arrays over steps k).

    Attributes:
        total: ``max(‖constraint‖∞, ‖base‖∞, ‖fiber‖₂)``, shape (K,).
        constraint: ``ω_{d±}(q_k, q_{k+1})``, shape (K, m).
        base: base point of ``𝔇^±`` minus that of ``X_d^k``: ``P⁺ − p_{k+1}`` (plus) or
            ``P⁻ − p_k`` (minus) in the momentum slot, zero in the ``q`` slot; shape (K, 2n)
            in the base point's ordering ``(q, p⁺)`` / ``(p⁻, q)``.
        fiber: the part of ``α − Ω^♭_{d±}(X_d^k)`` outside ``Δ°_{Q×Q*}`` (``Δ°_{Q*×Q}``),
            shape (K, 2n); for a staged rule the least-squares residual of the known
            end's momentum line, the stage lines and the stage rows, (K, 3n + 2m), or,
            for a run that kept its stages, the Dirac condition at each of the three
            nodes, (K, 3n) (:mod:`._stagewise`; ``constraint`` is then (K, 3m), the rows
            at every node, and ``base`` the discrete step relation of the momenta).
        multipliers: the multipliers ``μ`` (least squares) in the library's convention
            ``p_k = P⁻ + A(q_k)ᵀμ`` (plus) or ``p_{k+1} = P⁺ + A(q_{k+1})ᵀμ`` (minus),
            shape (K, m); comparable with ``Trajectory.multipliers``.
    """

    total: np.ndarray
    constraint: np.ndarray
    base: np.ndarray
    fiber: np.ndarray
    multipliers: np.ndarray


def _pairs(traj):
    q, p = np.asarray(traj.q), np.asarray(traj.p)
    if traj.scheme == "plus":
        return q[:-1], p[:-1], q[1:], p[1:]
    if traj.scheme == "minus":  # stored backward in time: row j is q_{k+1}, row j+1 is q_k
        return q[1:], p[1:], q[:-1], p[:-1]
    raise ModelError(f"traj.scheme={traj.scheme!r} must be 'plus' or 'minus'.")


def step_residuals(system, traj) -> StepResiduals:
    r"""All pieces of the membership ``(X_d^k, 𝔇^±L_d(q_k, q_{k+1})) ∈ D^{d±}_Δ``.

    Uses ``traj.scheme`` for the side, ``traj.discretization`` for ``L_d``, ``f_d^±`` and
    ``ω_{d±}``, and ``traj.dt`` for ``h``. ``system`` is any ``DiracSystem``.
    """
    n = int(system.n)
    if traj.q.ndim != 2 or traj.q.shape[1] != n:
        raise ModelError(
            f"traj has states of shape {traj.q.shape[1:]} but system has n = {n} "
            f"coordinates {tuple(system.coords)}: pass the system that produced traj."
        )
    if tuple(traj.coords) and tuple(traj.coords) != tuple(system.coords):
        raise ModelError(
            f"traj.coords={tuple(traj.coords)} differ from system.coords="
            f"{tuple(system.coords)}: pass the system that produced traj."
        )
    if getattr(system, "constraints_time_dependent", False):
        raise ModelError(
            f"system {getattr(system, 'name', '')!r} has time-dependent constraints A(q, t) or "
            "g(q, t): the discrete Dirac structure D^{d±}_Δ is defined for a fixed "
            "distribution Δ, so this diagnostic does not apply; check "
            "traj.constraint_residual (each step's constraints) instead."
        )
    rule, h, side = _rule(traj.discretization), float(traj.dt), traj.scheme
    q0, p0, q1, p1 = _pairs(traj)
    if q0.shape[0] == 0:
        empty = np.zeros((0, 2 * n))
        return StepResiduals(np.zeros(0), np.zeros((0, system.m)), empty, empty, empty[:, :0])
    t = np.asarray(traj.t)
    tk = t[:-1] if side == "plus" else t[1:]  # each step's earlier end
    if rule.stages:
        stages = getattr(traj, "stages", None)
        if stages is not None and getattr(type(system), "discrete_momenta", None) is None:
            # the kept stages, checked node by node (see _stagewise)
            parts = stagewise_parts(
                system,
                rule,
                side,
                h,
                q0,
                p0,
                q1,
                p1,
                tk,
                stages,
                np.asarray(traj.multipliers),
                traj.stage_multipliers,
            )
        else:  # the stages are re-solved from the stored states (see _staged)
            parts = staged_parts(system, rule, side, h, q0, p0, q1, p1, tk)
        zeros = np.zeros_like(parts["base"])
        slot = [zeros, parts["base"]] if side == "plus" else [parts["base"], zeros]
        parts["base"] = np.concatenate(slot, axis=1)  # the base point's (q, p⁺) / (p⁻, q)
        return StepResiduals(total=combine(parts), **parts)

    momenta = jax.jit(jax.vmap(lambda a, b, s: discrete_momenta(rule, system, a, b, h, s)))
    p_minus, p_plus = (
        np.asarray(x) for x in momenta(jnp.asarray(q0), jnp.asarray(q1), jnp.asarray(tk))
    )
    if side == "plus":  # 𝔇⁺ = (q_k, P⁺ | P⁻, q_{k+1})
        alpha = np.concatenate([q0, p_plus, p_minus, q1], axis=1)
    else:  # 𝔇⁻ = (P⁻, q_{k+1} | −q_k, −P⁺)
        alpha = np.concatenate([p_minus, q1, -q0, -p_plus], axis=1)

    structure = InducedDiscrete(system.constraint_forms, rule, h=h, side=side, n=n)
    parts = structure.batched_parts(q0, p0, q1, p1, alpha)
    if getattr(system, "affine_constraints", False):
        # holonomic rows g(q_end)/h and affine terms b: the system's own discrete rows
        rows = jax.jit(
            jax.vmap(lambda a, b, s: discrete_constraints(rule, system, side, a, b, h, s))
        )
        parts["constraint"] = np.asarray(rows(jnp.asarray(q0), jnp.asarray(q1), jnp.asarray(tk)))
    # Δ° coefficients ν: plus has P⁻ − p_k = Aᵀν, i.e. μ = −ν; minus has p_{k+1} − P⁺ = Aᵀν
    mu = -parts["nu"] if side == "plus" else parts["nu"]

    return StepResiduals(
        total=combine(parts),
        constraint=parts["constraint"],
        base=parts["base"],
        fiber=parts["fiber"],
        multipliers=mu,
    )


def trajectory_residual(system, traj) -> np.ndarray:
    r"""Residual of ``(X_d^k, 𝔇^±L_d(q_k, q_{k+1})) ∈ D^{d±}_Δ`` for every step, shape (K,).

    The largest of ``|ω_{d±}(q_k, q_{k+1})|``, the base-point mismatch of the momenta and
    the distance of ``α − Ω^♭_{d±}(X_d^k)`` from ``Δ°`` (least squares over the
    multipliers); absolute, in the trajectory's units. A trajectory of the integrator
    gives round-off; see :class:`StepResiduals` for the pieces. Covers every rule: the
    two-point rules ``"retraction"`` and ``"midpoint"`` through the structure itself, and
    ``"lobatto"`` node by node from its kept stages (``simulate(..., keep_stages=True)``,
    :mod:`diracvi.dirac._stagewise`) or, without them, through its stage-reduced relation
    with the stages re-solved from the stored states (:mod:`diracvi.dirac._staged`).
    """
    return step_residuals(system, traj).total
