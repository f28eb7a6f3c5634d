"""Shared instances for the Dirac-structure tests: the paper's torn examples and a
generator of random (possibly configuration-dependent) one-forms."""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np


@dataclass
class Instance:
    """Subsystem one-forms ``forms[i]`` on ``Q_i`` (dims[i]) and interaction ``sigma`` on Q."""

    forms: list
    dims: list
    sigma: object
    name: str = ""

    @property
    def n(self) -> int:
        return sum(self.dims)


def spring_chain_torn() -> Instance:
    """Paper §5.1: Q1 = (q1, q2), Q2 = (q2bar, q3), Δ_i = TQ_i, Σ° = span{dq2 − dq2bar}."""
    return Instance(
        forms=[np.zeros((0, 2)), np.zeros((0, 2))],
        dims=[2, 2],
        sigma=np.array([[0.0, 1.0, -1.0, 0.0]]),
        name="spring chain (torn)",
    )


def rlc_torn() -> Instance:
    """Paper §5.2: Q1 = (qR, qL, qS1), ω1 = (1, −1, −1); Q2 = (qS2, qC), ω2 = (−1, 1);
    Σ° = span{dqS1 − dqS2}."""
    return Instance(
        forms=[np.array([[1.0, -1.0, -1.0]]), np.array([[-1.0, 1.0]])],
        dims=[3, 2],
        sigma=np.array([[0.0, 0.0, 1.0, -1.0, 0.0]]),
        name="RLC (torn)",
    )


def varying_forms(rng: np.random.Generator, rows: int, cols: int, varying: bool):
    """``A(q) = C₀ + C₁ cos(w·q) + C₂ (u·q)`` (JAX-traceable) or a constant C₀."""
    c0 = rng.standard_normal((rows, cols))
    if not varying:
        return c0
    c1 = 0.5 * rng.standard_normal((rows, cols))
    c2 = 0.3 * rng.standard_normal((rows, cols))
    w, u = rng.standard_normal(cols), rng.standard_normal(cols)
    c0j, c1j, c2j, wj, uj = (jnp.asarray(a) for a in (c0, c1, c2, w, u))

    def forms(q):
        return c0j + c1j * jnp.cos(wj @ q) + c2j * (uj @ q)

    return forms


def random_instance(seed: int, dims, rows, sigma_rows: int, varying: bool) -> Instance:
    rng = np.random.default_rng(seed)
    forms = [varying_forms(rng, m, d, varying) for d, m in zip(dims, rows, strict=True)]
    sigma = varying_forms(rng, sigma_rows, sum(dims), varying)
    return Instance(forms=forms, dims=list(dims), sigma=sigma, name=f"random({seed})")
