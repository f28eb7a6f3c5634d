r"""Residuals of the (+) and (−) discrete Lagrange–Dirac equations.

(+) equations, forward in time: given ``(q_k, p_k)`` solve for ``x = (q_{k+1}, μ_k)``::

    p_k     = −D₁L_d(q_k, q_{k+1}) − f_d^−(q_k, q_{k+1}) + A(q_k)ᵀ μ_k
    0       =  ω_{d+}(q_k, q_{k+1})
    p_{k+1} =  D₂L_d(q_k, q_{k+1}) + f_d^+(q_k, q_{k+1})

(−) equations, backward in time: given ``(q_{k+1}, p_{k+1})`` solve for ``x = (q_k, μ)``::

    p_{k+1} =  D₂L_d + f_d^+ + A(q_{k+1})ᵀ μ
    0       =  ω_{d−}(q_k, q_{k+1})
    p_k     = −D₁L_d − f_d^−

Each residual function returns the stacked residual of the first two lines; the third
line is the explicit update :func:`new_momentum`. The same code serves a single system
and an interconnection, because both implement :class:`~diracvi._system.DiracSystem`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ._discretize import QuadratureRule
from ._system import DiracSystem

SCHEMES = ("plus", "minus")


def split(system: DiracSystem, x):
    """``x = (q_other, μ)`` → its two parts."""
    return x[: system.n], x[system.n :]


def residual(system: DiracSystem, rule: QuadratureRule, scheme: str, h, q, p, x):
    """Residual of the step equations at unknowns ``x`` from the known state ``(q, p)``.

    For ``scheme="plus"``, ``(q, p) = (q_k, p_k)`` and ``x = (q_{k+1}, μ_k)``; for
    ``"minus"``, ``(q, p) = (q_{k+1}, p_{k+1})`` and ``x = (q_k, μ)``.
    """
    q_other, mu = split(system, x)
    if scheme == "plus":
        qk, qk1 = q, q_other
        p_left, _ = system.discrete_momenta(rule, qk, qk1, h)
        r_mom = p_left + system.multiplier_force(qk, mu) - p
    else:
        qk, qk1 = q_other, q
        _, p_right = system.discrete_momenta(rule, qk, qk1, h)
        r_mom = p_right + system.multiplier_force(qk1, mu) - p
    r_con = system.discrete_constraints(rule, scheme, qk, qk1, h)
    return jnp.concatenate([r_mom, r_con])


def new_momentum(system: DiracSystem, rule: QuadratureRule, scheme: str, h, q, x):
    """The explicit line: ``p_{k+1} = D₂L_d + f_d^+`` (plus) or ``p_k = −D₁L_d − f_d^−``."""
    q_other, _ = split(system, x)
    if scheme == "plus":
        return system.discrete_momenta(rule, q, q_other, h)[1]
    return system.discrete_momenta(rule, q_other, q, h)[0]


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

    @property
    def size(self) -> int:
        return self.system.n + self.system.m

    def residual(self, x):
        return residual(self.system, self.rule, self.scheme, self.h, self.q, self.p, x)

    def momentum(self, x):
        return new_momentum(self.system, self.rule, self.scheme, self.h, self.q, x)

    def scale(self):
        """The size against which Newton's relative tolerance is measured."""
        return jnp.max(jnp.abs(self.q), initial=0.0)
