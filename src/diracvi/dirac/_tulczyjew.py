r"""The discrete Tulczyjew triple and the discrete Dirac differentials (paper §2.3).

Coordinates (paper §2.3, after Leok & Ohsawa 2011)::

    κ^d_Q     : ((q₀, p₀), (q₁, p₁)) ↦ (q₀, q₁, −p₀, p₁)      T*Q × T*Q → T*(Q × Q)
    Ω^♭_{d+}  : ((q₀, p₀), (q₁, p₁)) ↦ (q₀, p₁, p₀, q₁)       T*Q × T*Q → T*(Q × Q*)
    Ω^♭_{d−}  : ((q₀, p₀), (q₁, p₁)) ↦ (p₀, q₁, −q₀, −p₁)     T*Q × T*Q → T*(Q* × Q)

and ``γ^{d±}_Q = Ω^♭_{d±} ∘ (κ^d_Q)^{-1}``. Since ``(κ^d_Q)^{-1}(q₀, q₁, a₀, a₁) =
((q₀, −a₀), (q₁, a₁))``,

    γ^{d+}_Q(q₀, q₁, a₀, a₁) = (q₀, a₁, −a₀, q₁),
    γ^{d−}_Q(q₀, q₁, a₀, a₁) = (−a₀, q₁, −q₀, −a₁).

Every map returns one flat array of length 4n: the first 2n entries are the base point,
the last 2n the fibre (covector) components, in the order the paper writes them.

**Discrete Dirac differentials.** With ``dL_d(q, q⁺) = (q, q⁺, D₁L_d, D₂L_d)``,

    𝔇⁺L_d(q, q⁺) = γ^{d+}(dL_d) = (q, D₂L_d, −D₁L_d, q⁺)     at ẑ = (q, p⁺ = D₂L_d),
    𝔇⁻L_d(q⁻, q) = γ^{d−}(dL_d) = (−D₁L_d, q, −q⁻, −D₂L_d)  at z̃ = (p⁻ = −D₁L_d, q).

Check against the (+) equations: ``(X_d^k, 𝔇⁺L_d(q_k, q_k⁺)) ∈ D^{d+}_Δ`` with
``X_d^k = ((q_k, p_k), (q_{k+1}, p_{k+1}))`` needs (i) equal base points
``ẑ = (q_k, p_{k+1}) = (q_k, D₂L_d)``, i.e. ``p_{k+1} = D₂L_d``; (ii) ``α − Ω^♭_{d+}(X_d^k)
= (−D₁L_d − p_k, q_k⁺ − q_{k+1}) ∈ Δ°_{Q×Q*} = {(β, 0) | β ∈ Δ°(q_k)}``, i.e.
``q_{k+1} = q_k⁺`` and ``p_k = −D₁L_d + A(q_k)ᵀμ``; (iii) ``ω_{d+}(q_k, q_{k+1}) = 0``. These
are exactly eqs. (pDiracEqns). The (−) case gives ``p_k = −D₁L_d``, ``q_k = q_{k+1}⁻`` and
``p_{k+1} = D₂L_d + A(q_{k+1})ᵀμ``, eqs. (mDiracEqns).

**Forces.** The continuous forced system uses ``𝔇L − F̃`` (paper §2.1). Discretely the
force is the one-form ``F_d = (q₀, q₁, f_d^−, f_d^+)`` on ``Q × Q`` of the discrete
Lagrange–d'Alembert principle, and the forced differential is ``γ^{d±}(dL_d + F_d)``:

    𝔇⁺(L_d, f_d) = (q, D₂L_d + f_d^+, −D₁L_d − f_d^−, q⁺),
    𝔇⁻(L_d, f_d) = (−D₁L_d − f_d^−, q, −q⁻, −D₂L_d − f_d^+),

which reproduces DESIGN.md's forced equations. Unlike the continuous ``F̃`` (which only
shifts the fibre), ``f_d^±`` also moves the base point through ``γ^{d±}``. The entries
``(−D₁L_d − f_d^−, D₂L_d + f_d^+)`` are exactly what
:func:`~diracvi.discretization.maps.discrete_momenta` returns, which
:func:`system_dirac_differential` uses.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.maps import discrete_momenta
from ..discretization.rules import QuadratureRule, get_rule
from ..errors import ModelError

SIDES = ("plus", "minus")


def _point(arg: str, z) -> tuple[np.ndarray, np.ndarray]:
    """``z = (q, p)`` as a pair or as one array of length 2n → ``(q, p)``."""
    if isinstance(z, tuple | list) and len(z) == 2:
        q, p = (np.asarray(a, dtype=np.float64).ravel() for a in z)
    else:
        flat = np.asarray(z, dtype=np.float64).ravel()
        if flat.size % 2:
            raise ModelError(
                f"{arg} has {flat.size} entries: pass (q, p) or one array (q, p) of length 2n."
            )
        q, p = flat[: flat.size // 2], flat[flat.size // 2 :]
    if q.shape != p.shape:
        raise ModelError(f"{arg}: q has {q.size} entries but p has {p.size}; they must match.")
    return q, p


def kappa_d(z0, z1) -> np.ndarray:
    """``κ^d_Q((q₀, p₀), (q₁, p₁)) = (q₀, q₁, −p₀, p₁)``."""
    (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
    return np.concatenate([q0, q1, -p0, p1])


def kappa_d_inverse(w) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """``(κ^d_Q)^{-1}(q₀, q₁, a₀, a₁) = ((q₀, −a₀), (q₁, a₁))``."""
    q0, q1, a0, a1 = _quarters("w", w)
    return (q0, -a0), (q1, a1)


def omega_flat_plus(z0, z1) -> np.ndarray:
    """``Ω^♭_{d+}((q₀, p₀), (q₁, p₁)) = (q₀, p₁, p₀, q₁)`` (base ẑ = (q₀, p₁))."""
    (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
    return np.concatenate([q0, p1, p0, q1])


def omega_flat_minus(z0, z1) -> np.ndarray:
    """``Ω^♭_{d−}((q₀, p₀), (q₁, p₁)) = (p₀, q₁, −q₀, −p₁)`` (base z̃ = (p₀, q₁))."""
    (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
    return np.concatenate([p0, q1, -q0, -p1])


def gamma_d_plus(w) -> np.ndarray:
    """``γ^{d+}_Q = Ω^♭_{d+} ∘ (κ^d_Q)^{-1}``: ``(q₀, q₁, a₀, a₁) ↦ (q₀, a₁, −a₀, q₁)``."""
    return omega_flat_plus(*kappa_d_inverse(w))


def gamma_d_minus(w) -> np.ndarray:
    """``γ^{d−}_Q = Ω^♭_{d−} ∘ (κ^d_Q)^{-1}``: ``(q₀, q₁, a₀, a₁) ↦ (−a₀, q₁, −q₀, −a₁)``."""
    return omega_flat_minus(*kappa_d_inverse(w))


def _quarters(arg: str, w):
    w = np.asarray(w, dtype=np.float64).ravel()
    if w.size % 4:
        raise ModelError(f"{arg} has {w.size} entries; a point of T*(Q×Q) has 4n.")
    return np.split(w, 4)


def split_base(w) -> tuple[np.ndarray, np.ndarray]:
    """A flat ``(base, covector)`` array of length 4n → ``(base (2n,), covector (2n,))``."""
    w = np.asarray(w, dtype=np.float64).ravel()
    return w[: w.size // 2], w[w.size // 2 :]


def _differential(gamma, discrete_lagrangian: Callable, q0, q1, discrete_force):
    q0 = jnp.asarray(q0, dtype=jnp.float64)
    q1 = jnp.asarray(q1, dtype=jnp.float64)
    d1, d2 = jax.grad(discrete_lagrangian, argnums=(0, 1))(q0, q1)
    if discrete_force is not None:
        f_minus, f_plus = discrete_force(q0, q1)
        d1, d2 = d1 + f_minus, d2 + f_plus
    return gamma(np.concatenate([q0, q1, d1, d2]))


def dirac_differential_plus(
    discrete_lagrangian: Callable, q, q_plus, discrete_force: Callable | None = None
) -> np.ndarray:
    r"""``𝔇⁺L_d(q, q⁺) = γ^{d+}(dL_d) = (q, D₂L_d, −D₁L_d, q⁺)`` (see module docs).

    ``discrete_lagrangian(q0, q1)`` must be JAX-differentiable; with
    ``discrete_force(q0, q1) -> (f_d^−, f_d^+)`` the forced differential
    ``γ^{d+}(dL_d + F_d) = (q, D₂L_d + f_d^+, −D₁L_d − f_d^−, q⁺)`` is returned.
    """
    return _differential(gamma_d_plus, discrete_lagrangian, q, q_plus, discrete_force)


def dirac_differential_minus(
    discrete_lagrangian: Callable, q_minus, q, discrete_force: Callable | None = None
) -> np.ndarray:
    r"""``𝔇⁻L_d(q⁻, q) = γ^{d−}(dL_d) = (−D₁L_d, q, −q⁻, −D₂L_d)`` (see module docs)."""
    return _differential(gamma_d_minus, discrete_lagrangian, q_minus, q, discrete_force)


def as_rule(rule) -> QuadratureRule:
    """The two-point rule ``rule`` names; the Dirac-structure constructions cover
    ``"retraction"`` and ``"midpoint"`` only (a staged rule such as ``"lobatto"`` is refused
    by name; its trajectories are checked by :mod:`diracvi.dirac._staged`)."""
    if not isinstance(rule, QuadratureRule):
        try:
            rule = get_rule(rule)
        except (KeyError, TypeError):
            raise ModelError(
                f"rule={rule!r} is not a discretization: use 'retraction' or 'midpoint' "
                "(or a dv.QuadratureRule instance)."
            ) from None
    if rule.stages:
        raise ModelError(
            f"discretization={rule.name!r} is not covered by the discrete Dirac-structure "
            "constructions (D^{d±}_Δ, 𝔇^±L_d), which cover the two-point rules 'retraction' "
            "and 'midpoint': they are defined for L_d(q_k, q_(k+1)), and this rule's step "
            "also has internal stages. Fix: check a run of it with traj.dirac_residual(system) "
            "or diracvi.dirac.step_residuals (they re-solve the stages), or build the "
            "structure with 'midpoint'."
        )
    return rule


def check_side(side: str) -> str:
    if side not in SIDES:
        raise ModelError(f"side={side!r} must be 'plus' or 'minus'.")
    return side


def system_dirac_differential(system, q0, q1, *, h, rule="retraction", side="plus"):
    r"""The forced ``𝔇^±(L_d, f_d)`` of a :class:`~diracvi.DiracSystem` at ``(q₀, q₁)``.

    Built from ``discrete_momenta(rule, system, q0, q1, h) = (−D₁L_d − f_d^−,
    D₂L_d + f_d^+) =: (P⁻, P⁺)``: ``side="plus"`` gives ``(q₀, P⁺, P⁻, q₁)``,
    ``side="minus"`` gives ``(P⁻, q₁, −q₀, −P⁺)``.
    """
    rule, side = as_rule(rule), check_side(side)
    q0 = jnp.asarray(q0, dtype=jnp.float64)
    q1 = jnp.asarray(q1, dtype=jnp.float64)
    p_minus, p_plus = (np.asarray(a) for a in discrete_momenta(rule, system, q0, q1, h))
    q0, q1 = np.asarray(q0), np.asarray(q1)
    if side == "plus":
        return np.concatenate([q0, p_plus, p_minus, q1])
    return np.concatenate([p_minus, q1, -q0, -p_plus])
