r"""One-form matrices ``A(q)`` (rows ω^a spanning ``Δ°(q)``): evaluation and regularity.

A Dirac structure is a *bundle*: the fibre at one point is only meaningful if the
distribution has locally constant rank there (Jacobs–Yoshimura require the intersection
``(Δ_{Q1} ⊕ Δ_{Q2}) ∩ Σ_Q`` to be *clean*, i.e. of locally constant rank). Pointwise linear
algebra cannot see this — at a single point ``D_{Δ1⊕Δ2} ⊠ D_int`` always equals
``D_{(Δ1⊕Δ2)∩Σ}`` — so :func:`check_regular` compares the rank at ``q`` with the rank at
small random perturbations of ``q`` and refuses a point where it jumps.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.validate import check_forms_array
from ._linalg import rank


class RedundantFormsWarning(UserWarning):
    """The one-forms are linearly dependent (fewer independent rows than rows)."""


def as_forms_function(arg: str, forms, n: int | None = None) -> tuple[Callable, int | None]:
    """``forms`` (callable ``A(q)``, constant (m, n) array, or ``None`` = no constraint)
    → ``(q ↦ A(q) as a JAX array, n or None if unknown)``."""
    if forms is None:
        if n is None:
            raise ModelError(
                f"{arg}=None means 'no one-forms', but then the dimension is unknown: "
                f"pass n=<dim Q> as well, or an explicit (0, n) array."
            )
        return (lambda q: jnp.zeros((0, n), dtype=jnp.float64)), n
    if callable(forms):
        return forms, n
    mat = check_forms_array(arg, forms, n)
    const = jnp.asarray(mat)
    return (lambda q: const), mat.shape[1]


def evaluate(arg: str, forms, q=None, n: int | None = None) -> np.ndarray:
    """The one-form matrix at ``q`` as a float64 (m, n) NumPy array."""
    if callable(forms):
        if q is None:
            raise ModelError(
                f"{arg} is a callable A(q); pass the point q=... at which to evaluate it."
            )
        q = np.asarray(q, dtype=np.float64)
        mat = np.asarray(forms(jnp.asarray(q)), dtype=np.float64)
        if mat.ndim != 2 or mat.shape[1] != q.shape[0]:
            raise ModelError(
                f"{arg}(q) returned shape {mat.shape} for q of shape {q.shape}: it must "
                f"return an (m, {q.shape[0]}) matrix whose rows are one-forms."
            )
        if not np.all(np.isfinite(mat)):
            raise ModelError(f"{arg}(q) returned NaN or Inf at q={q.tolist()}.")
        return mat
    fn, _ = as_forms_function(arg, forms, n)
    dim = n if n is not None else np.atleast_2d(np.asarray(forms)).shape[1]
    return np.asarray(fn(jnp.zeros(dim)), dtype=np.float64)


def check_regular(
    arg: str,
    forms,
    q=None,
    *,
    samples: int = 6,
    radius: float = 1e-4,
    seed: int = 0,
    warn_redundant: bool = True,
) -> int:
    r"""Rank of ``A(q)``, after checking the distribution ``ker A`` is regular at ``q``.

    For a callable ``A``, the rank at ``q`` is compared with the rank at ``samples``
    random points within ``radius`` of ``q``; a difference means the distribution (for an
    interconnection: the intersection ``(⊕Δ_i) ∩ Σ``) is not clean at ``q`` and raises
    :class:`ModelError`. Linearly dependent rows of constant rank are allowed (the
    annihilator is their span) but flagged with :class:`RedundantFormsWarning`, since
    their multipliers are not unique.
    """
    mat = evaluate(arg, forms, q)
    r = rank(mat)
    if callable(forms) and q is not None:
        q = np.asarray(q, dtype=np.float64)
        rng = np.random.default_rng(seed)
        scale = radius * max(1.0, float(np.max(np.abs(q), initial=0.0)))
        for _ in range(samples):
            qs = q + scale * rng.uniform(-1.0, 1.0, size=q.shape)
            r_near = rank(evaluate(arg, forms, qs))
            if r_near != r:
                raise ModelError(
                    f"{arg}: the one-forms have rank {r} at q={q.tolist()} but rank {r_near} "
                    f"at a point within {scale:.1e} of it, so the distribution is not regular "
                    "there (for an interconnection: (Δ1 ⊕ Δ2) ∩ Σ is not a clean "
                    "intersection) and the Dirac structure at q is not the limit of the "
                    "nearby ones. Fix: evaluate at a point where the rank is locally "
                    "constant, or change the one-forms so that it is."
                )
    if warn_redundant and r < mat.shape[0]:
        warnings.warn(
            f"{arg}: {mat.shape[0]} one-forms but only {r} are linearly independent "
            "(redundant one-forms). The annihilator is their span, so the Dirac structure "
            "is well defined, but their multipliers are not unique; drop the dependent rows "
            "if you integrate this system.",
            RedundantFormsWarning,
            stacklevel=3,
        )
    return r


def is_clean(forms, q, *, samples: int = 6, radius: float = 1e-4, seed: int = 0) -> bool:
    """``True`` iff :func:`check_regular` accepts ``forms`` at ``q`` (no warning issued)."""
    try:
        check_regular(
            "forms", forms, q, samples=samples, radius=radius, seed=seed, warn_redundant=False
        )
    except ModelError:
        return False
    return True
