r"""Residuals of the (+) and (−) discrete Lagrange–Dirac equations.

Every step covers ``[t_k, t_k + h]``; ``t`` below is always ``t_k``, the earlier end,
whichever way the scheme runs (the rule picks its own nodes from it).

(+) equations, forward in time: given ``(q_k, p_k)`` solve for ``x = (q_{k+1}, μ_k)``::

    p_k     = −D₁L_d(q_k, q_{k+1}) − f_d^−(q_k, q_{k+1}) + A(q_k)ᵀ μ_k
    0       =  ω_{d+}(q_k, q_{k+1})
    p_{k+1} =  D₂L_d(q_k, q_{k+1}) + f_d^+(q_k, q_{k+1})

(−) equations, backward in time: given ``(q_{k+1}, p_{k+1})`` solve for ``x = (q_k, μ)``::

    p_{k+1} =  D₂L_d + f_d^+ + A(q_{k+1})ᵀ μ
    0       =  ω_{d−}(q_k, q_{k+1})
    p_k     = −D₁L_d − f_d^−

Each residual function returns the stacked residual of the first two lines; the third
line is the explicit update :func:`new_momentum`.

A rule with ``s = rule.stages`` internal stages (``"lobatto"``: 2) has the unknowns
``x = (q_other, μ, S₁ … S_s, ν₁ … ν_s)``: its stage positions (for Lobatto the stage at
the known end and the middle one) and the multipliers of the stage rows follow, so the first
``n + m`` entries mean what they mean for every rule. Its multipliers act at the stages
(``r_j = −b_j A(Q_j)ᵀ μ_j``, pulled back to the step's variables like the forces, see
:class:`~diracvi.discretization.rules.Lobatto`)::

    p_known = ∓(D_known L_d + f_known + r_known)    (−D₁… for (+), +D₂… for (−))
    0       = D_Q L_d + f_Q + r_Q                     (the stages' variations)
    0       = c_end,  0 = c_a, c_b                    (the one-forms at every stage)
    p_new   = the other end's line, with its reactions

The same code serves a single system
and an interconnection, because both implement :class:`~diracvi.model.system.DiracSystem`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..model.roundoff import force_roundoff
from ..model.system import DiracSystem
from ..runtime.roundoff import UNIT
from .maps import discrete_constraints, discrete_momenta, reactions
from .rules import QuadratureRule

SCHEMES = ("plus", "minus")


def split(system: DiracSystem, x):
    """``x = (q_other, μ)`` → its two parts (for a staged rule the second part is the
    whole tail ``(μ, S₁, S₂, ν)``; :func:`split_stage` takes it apart)."""
    return x[: system.n], x[system.n :]


def unknown_count(system: DiracSystem, rule: QuadratureRule) -> int:
    """``len(x)``: ``n + m``, and as much again per internal stage of the rule."""
    return (system.n + system.m) * (1 + rule.stages)


def split_stage(system: DiracSystem, x, stages: int = 2):
    """``x = (q_other, μ, S₁ … S_s, ν₁ … ν_s)`` of a rule with ``s = stages`` internal stages
    → ``(q_other, μ, S, ν)`` with the stage unknowns ``S`` of shape (n, s) and ``ν`` of
    shape (m, s)."""
    n, m = system.n, system.m
    stage = x[n + m : n + m + stages * n].reshape(stages, n).T
    nu = x[n + m + stages * n : (n + m) * (1 + stages)].reshape(stages, m).T
    return x[:n], x[n : n + m], stage, nu


def stage_of(system: DiracSystem, rule: QuadratureRule, scheme: str, qk, qk1, x):
    """The internal stages ``[Q₁ Q₂]`` (shape (n, 2)) of a staged rule's step ``x`` between
    ``q_k`` and ``q_{k+1}``, else ``None``."""
    unknowns = split_stage(system, x, rule.stages)[2]
    return rule.stage_from_unknowns(scheme, qk, qk1, unknowns)


def first_guess(system: DiracSystem, rule: QuadratureRule, q, q_other, mu):
    """A starting ``x`` from guesses of ``q_other`` and ``μ`` (stages: the rule's guess
    between the ends, every stage multiplier ``= μ``)."""
    if not rule.stages:  # nothing to append: the guess is (q_other, μ) as it is
        return jnp.concatenate([q_other, mu])
    stage = rule.stage_guess(q, q_other).T.ravel()
    return jnp.concatenate([q_other, mu, stage, jnp.tile(mu, rule.stages)])


def residual(system: DiracSystem, rule: QuadratureRule, scheme: str, h, q, p, x, t=0.0):
    """Residual of the step equations at unknowns ``x`` from the known state ``(q, p)``.

    For ``scheme="plus"``, ``(q, p) = (q_k, p_k)`` and ``x = (q_{k+1}, μ_k)``; for
    ``"minus"``, ``(q, p) = (q_{k+1}, p_{k+1})`` and ``x = (q_k, μ)``. ``t = t_k``.
    """
    if rule.stages:
        return _staged_residual(system, rule, scheme, h, q, p, x, t)
    q_other, mu = split(system, x)
    if scheme == "plus":
        qk, qk1 = q, q_other
        p_left, _ = discrete_momenta(rule, system, qk, qk1, h, t)
        r_mom = p_left + system.multiplier_force(qk, mu, t) - p
    else:
        qk, qk1 = q_other, q
        _, p_right = discrete_momenta(rule, system, qk, qk1, h, t)
        r_mom = p_right + system.multiplier_force(qk1, mu, t + h) - p
    r_con = discrete_constraints(rule, system, scheme, qk, qk1, h, t)
    return jnp.concatenate([r_mom, r_con])


def _staged_lines(system, rule, scheme, h, q, x, t):
    """``(q_k, q_{k+1}, left, right, stage lines)`` of a staged rule: ``left = −D₁L_d −
    f_d^− − r^−``, ``right = D₂L_d + f_d^+ + r^+``, ``stage = D_Q L_d + f_Q + r_Q``,
    with ``r`` the pull-back of the stage reactions."""
    q_other, mu, unknowns, nu = split_stage(system, x, rule.stages)
    qk, qk1 = ordered(scheme, q, q_other)
    stage = rule.stage_from_unknowns(scheme, qk, qk1, unknowns)
    p_left, p_right, p_stage = discrete_momenta(rule, system, qk, qk1, h, t, stage=stage)
    r_left, r_stage, r_right = rule.pullback(
        reactions(rule, system, scheme, qk, stage, qk1, h, t, mu, nu)
    )
    return qk, qk1, p_left - r_left, p_right + r_right, p_stage + r_stage, stage


def _staged_residual(system, rule, scheme, h, q, p, x, t):
    """:func:`residual` of a staged rule: ``[momentum; c_end; stage lines; stage rows]``."""
    qk, qk1, left, right, lines, stage = _staged_lines(system, rule, scheme, h, q, x, t)
    r_mom = (left if scheme == "plus" else right) - p
    c_end, c_stage = discrete_constraints(rule, system, scheme, qk, qk1, h, t, stage=stage)
    return jnp.concatenate([r_mom, c_end, lines.T.ravel(), c_stage.T.ravel()])


def new_momentum(system: DiracSystem, rule: QuadratureRule, scheme: str, h, q, x, t=0.0):
    """The explicit line: ``p_{k+1} = D₂L_d + f_d^+`` (plus) or ``p_k = −D₁L_d − f_d^−``
    (a staged rule adds its stage reactions' share)."""
    if rule.stages:
        _, _, left, right, _, _ = _staged_lines(system, rule, scheme, h, q, x, t)
        return right if scheme == "plus" else left
    q_other, _ = split(system, x)
    if scheme == "plus":
        return discrete_momenta(rule, system, q, q_other, h, t)[1]
    return discrete_momenta(rule, system, q_other, q, h, t)[0]


def reaction_impulse(system: DiracSystem, scheme: str, h, q, mu, t=0.0):
    """The constraint impulse ``A(q_known, t_known)ᵀμ`` on the known end's momentum line."""
    return system.multiplier_force(q, mu, t if scheme == "plus" else t + h)


def nodal_momentum(
    system: DiracSystem, rule: QuadratureRule, scheme: str, h, q, mu, p_new, t, first
):
    r"""The momentum at the new node to the rule's order: ``p_new − s·C`` with ``C`` the
    step's constraint impulse and ``s`` = :meth:`QuadratureRule.impulse_share`.

    The (±) equations put the whole impulse ``C = A(·)ᵀμ`` on the known end's line, so
    the stepped momenta lag the true ones by ``s·C`` (for a symmetric rule, half the
    impulse belongs to each end). On the first step of a run the given momentum carries
    no lag, so the multiplier absorbed only ``(1 − s)`` of the impulse: there
    ``C/(1 − s)`` is the impulse. Only directions in ``range A(·)ᵀ`` change, so this
    momentum and ``p_new`` step to the same positions.
    """
    share = rule.impulse_share()
    impulse = reaction_impulse(system, scheme, h, q, mu, t)
    scale = jnp.where(first, share / (1.0 - share), share)
    return p_new - scale * impulse


def ordered(scheme: str, q, q_other):
    """``(q_k, q_{k+1})`` in time order, whichever end the scheme starts from."""
    return (q, q_other) if scheme == "plus" else (q_other, q)


class StepEquations(eqx.Module):
    """One time step's equations, from the known state ``(q, p)``: what a step solver sees.

    ``residual(x)`` is the implicit part (``x = (q_other, μ)``), ``momentum(x)`` the
    explicit line. Solvers that exploit structure (the partitioned solver) read
    ``system``, ``rule`` and ``scheme``; plain Newton only calls ``residual``.
    """

    system: DiracSystem
    rule: QuadratureRule
    scheme: str = eqx.field(static=True)
    h: jax.Array
    q: jax.Array
    p: jax.Array
    t: jax.Array | float = 0.0  # t_k, the earlier end of the step

    @property
    def size(self) -> int:
        return unknown_count(self.system, self.rule)

    def residual(self, x):
        return residual(self.system, self.rule, self.scheme, self.h, self.q, self.p, x, self.t)

    def momentum(self, x):
        return new_momentum(self.system, self.rule, self.scheme, self.h, self.q, x, self.t)

    def carried_momentum(self, line, x):
        r"""The new momentum in increment form, ``p_new = line − r``: the explicit line
        ``line`` (:meth:`momentum`, at ``x``) less the known end's momentum residual
        ``r = P_known(x) + A(q_known)ᵀμ − p`` (the first ``n`` rows of :meth:`residual`).

        For the (+) equations this is ``p_{k+1} = p_k + (D₂L_d + D₁L_d + f_d^+ + f_d^−)
        − A(q_k)ᵀμ_k``: the same number when the step is solved exactly, but at a
        solved ``x`` whose positions are rounded to ``ulp(q)``, ``r ≈ (M/h) δq`` is a
        hundred ulps of ``p`` at ``h = 0.01``, and the plain line ``D₂L_d ≈ p* + (M/h)
        δq`` carries it into the state, step after step. In increment form the ``M/h``
        parts cancel (``D₂L_d`` and ``−D₁L_d`` move alike with ``q_{k+1}``), so ``p_new``
        is the exact step's momentum to ``O(h δq)`` plus its own rounding; a symmetry's
        momentum map (``Σ qᵢ × pᵢ`` of a free rigid body) then changes by ``−Σ Δq × r``
        per step instead of ``Σ q_k × r`` — ``h|v|/|q|`` times less.

        A staged rule keeps its plain line: its two ends' lines are formed from the
        stages by different weights, so ``D₂L_d + D₁L_d`` of a free translation is not
        zero to the bit, and the momentum then walks by its rounding (the free body
        under ``"lobatto"``: the centre of mass off by 8.6e-14 after 400 steps, against
        1e-15 with the plain line, and its angular momentum no closer).
        """
        if self.rule.stages:
            return line
        r = self.residual(x)[: self.system.n]
        return line - r

    @property
    def bounds_forces(self) -> bool:
        """Whether :meth:`force_sizes` has anything to say (a static answer)."""
        return force_roundoff(self.system) is not None and not self.rule.stages

    def force_sizes(self, x):
        r"""Per equation, the size of the force terms a law computes, or None where no
        part bounds its force's round-off (:mod:`diracvi.model.roundoff`): ``h E/u`` on
        each momentum line, ``E`` the bound at the step's centre (``q̄ = (q + q_other)/2``,
        ``v = ±(q_other − q)/h``), ``u`` the unit round-off. A law whose terms cancel
        (``β y − ½β(|y + V_t| − |y − V_t|)``, 0 below ``V_t``) computes to ``u`` times its
        terms, and its Jacobian, ``β − β``, is 0 there: the linearized sizes Newton
        measures a residual at round-off against (:class:`~diracvi.NewtonSolver`'s
        ``residual_rtol``) miss those terms, and each iterate's residual, scattered by
        the law's round-off, was never within them (the step failed, then every step
        down to the smallest)."""
        bound = force_roundoff(self.system)
        if bound is None or self.rule.stages:
            return None
        q_other, _ = split(self.system, x)
        sign = 1.0 if self.scheme == "plus" else -1.0
        velocity = sign * (q_other - self.q) / self.h
        t = self.t + 0.5 * self.h  # (t is the step's earlier end in both schemes)
        forces = self.h * bound(0.5 * (self.q + q_other), velocity, t) / UNIT
        pad = jnp.zeros(self.size - forces.shape[0], dtype=forces.dtype)
        return jnp.concatenate([forces, pad])

    def scale(self):
        """The size against which Newton's relative tolerance is measured."""
        return jnp.max(jnp.abs(self.q), initial=0.0)

    def reference(self):
        """The known state as unknowns — ``q_other = q``, stages at ``q``, every
        multiplier 0 — from which a step's increment ``x − reference`` is measured."""
        zero = jnp.zeros(self.system.m, dtype=self.q.dtype)
        return first_guess(self.system, self.rule, self.q, self.q, zero)
