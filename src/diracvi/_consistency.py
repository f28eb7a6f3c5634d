r"""Consistent initial data: joined ports at equal positions, momenta in the Legendre image.

Two things an initial state ``(q₀, p₀)`` must satisfy that the step equations cannot
repair on their own:

* **ports** joined by :func:`~diracvi.connect` hold ``ẋ = ẏ``; the position-level
  interconnection ``x = y`` then holds for all time only if it holds at t = 0;
* **momenta** of a degenerate Lagrangian satisfy the primary constraint
  ``p₀ ∈ ∂L/∂v(q₀, ·) + span A(q₀)ᵀ``. For L quadratic in v (mechanics, circuits,
  gyrators) that set is the affine space ``∂L/∂v(q₀, 0) + range W + range A(q₀)ᵀ`` with
  ``W = ∂²L/∂v²``, which is what is measured (and projected onto) here.
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np

from ._system import DiracSystem


class InconsistentInitialDataWarning(UserWarning):
    """The initial state violates an interconnection or the primary constraint."""


def _ports(system: DiracSystem, prefix: str = "") -> list[tuple[str, str]]:
    pairs = [(prefix + a, prefix + b) for a, b in getattr(system, "ports", ())]
    for sub in getattr(system, "subsystems", ()):
        pairs += _ports(sub, f"{prefix}{sub.name}.")
    return pairs


def _port_groups(system) -> list[list[int]]:
    """Coordinates tied together by chains of connections (union–find)."""
    index = {c: i for i, c in enumerate(system.coords)}
    parent = list(range(system.n))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in _ports(system):
        parent[root(index[a])] = root(index[b])
    groups: dict[int, list[int]] = {}
    for i in range(system.n):
        groups.setdefault(root(i), []).append(i)
    return [g for g in groups.values() if len(g) > 1]


@jax.jit
def _legendre_pieces(system, q):
    zero = jnp.zeros_like(q)
    g = jax.grad(system.lagrangian, argnums=1)(q, zero)
    w = jax.hessian(system.lagrangian, argnums=1)(q, zero)
    return g, w, system.constraint_forms(q)


def _momentum_projection(system, q, p):
    g, w, forms = (np.asarray(a) for a in _legendre_pieces(system, jnp.asarray(q)))
    basis = np.concatenate([w, forms.T], axis=1)
    if basis.size == 0:
        return g
    coef, *_ = np.linalg.lstsq(basis, p - g, rcond=None)
    return g + basis @ coef


def violations(system: DiracSystem, q0, p0) -> dict[str, float]:
    """``{"ports": max |x − y|, "momenta": distance of p₀ from the consistent set}``."""
    q0, p0 = np.asarray(q0), np.asarray(p0)
    ports = max((np.ptp(q0[g]) for g in _port_groups(system)), default=0.0)
    momenta = float(np.max(np.abs(p0 - _momentum_projection(system, q0, p0)), initial=0.0))
    return {"ports": float(ports), "momenta": momenta}


def project(system: DiracSystem, q0, p0):
    """The nearest consistent state: joined ports at their mean, then p₀ projected."""
    q = np.array(q0, dtype=np.float64)
    for group in _port_groups(system):
        q[group] = q[group].mean()
    return q, _momentum_projection(system, q, np.asarray(p0, dtype=np.float64))


def check(system: DiracSystem, q0, p0, *, project_initial: bool):
    """Warn about (or, with ``project_initial``, repair) inconsistent initial data."""
    found = violations(system, q0, p0)
    q_scale = max(1.0, float(np.max(np.abs(q0))))
    p_scale = max(1.0, float(np.max(np.abs(p0))))
    bad_q = found["ports"] > 1e-12 * q_scale
    bad_p = found["momenta"] > 1e-10 * p_scale
    if not (bad_q or bad_p):
        return q0, p0
    if project_initial:
        q, p = project(system, q0, p0)
        return jnp.asarray(q), jnp.asarray(p)
    parts = []
    if bad_q:
        groups = [[system.coords[i] for i in g] for g in _port_groups(system)]
        parts.append(
            f"joined ports differ in position by up to {found['ports']:.3e} "
            f"(groups {groups}); their interconnection x = y will be off by that forever"
        )
    if bad_p:
        parts.append(
            f"p0 is {found['momenta']:.3e} away from the momenta a degenerate Lagrangian "
            "allows (∂L/∂v + Aᵀμ); the scheme will carry a spurious oscillation"
        )
    warnings.warn(
        "Inconsistent initial data: " + "; ".join(parts) + ". Pass project_initial=True to "
        "simulate() to start from the nearest consistent state (dv.project_initial_state).",
        InconsistentInitialDataWarning,
        stacklevel=3,
    )
    return q0, p0
