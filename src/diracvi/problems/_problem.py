"""A canonical problem: a system, its initial state and step, and what is known about it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..model.system import DiracSystem


@dataclass(frozen=True)
class Problem:
    """A ready-to-run model.

    Attributes:
        name: registry name (``diracvi run NAME``).
        description: one line for ``diracvi list``.
        system: the Lagrange–Dirac system (single or interconnected).
        q0: initial positions, in ``system.coords`` order.
        p0: initial momenta, in ``system.coords`` order.
        dt: the step the source uses.
        steps: the number of steps the source uses.
        t0: the initial time (driven models: pass it on as ``simulate(..., t0=)``).
        exact: ``exact(t) -> q`` with shape (len(t), n), where a closed form is known.
        numerical_solution: ``numerical_solution(t) -> q`` of shape (len(t), n) where no
            closed form exists: an independent reduced-coordinate reference (SciPy
            ``solve_ivp``, DOP853, ``rtol = atol = 1e-12``) that does not use diracvi.
        discretizations: the rules whose step equations are solvable for this model.
        reference: where the model comes from.
        notes: anything a user should know (deviations from the source, caveats).
        reduced: for a torn (interconnected) model, the hand-built model without the extra
            port variables.
        shared: torn coordinate → the reduced model's coordinate it must equal.
        ports: coordinate pairs the interconnection keeps equal (position level, given
            equal initial values).
    """

    name: str
    description: str
    system: DiracSystem
    q0: np.ndarray
    p0: np.ndarray
    dt: float
    steps: int
    exact: Callable[[np.ndarray], np.ndarray] | None = None
    t0: float = 0.0
    numerical_solution: Callable[[np.ndarray], np.ndarray] | None = None
    discretizations: tuple[str, ...] = ("retraction", "midpoint")
    reference: str = ""
    notes: str = ""
    parameters: dict = field(default_factory=dict)
    reduced: Problem | None = None
    shared: dict[str, str] = field(default_factory=dict)
    ports: tuple[tuple[str, str], ...] = ()


def linear_flow(generator: np.ndarray, state0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``x(t) = exp(t G) x0`` for each t (the exact solution of ``ẋ = G x``), shape (T, d)."""
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    # one batched expm (SciPy takes stacks of matrices) instead of a call per instant
    import scipy.linalg  # only for an exact solution: not imported with diracvi.problems

    return scipy.linalg.expm(t[:, None, None] * generator[None]) @ state0


def mass_spring_generator(mass: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    """``G`` of ``d/dt (q, v) = (v, −M⁻¹K q)``."""
    n = mass.shape[0]
    gen = np.zeros((2 * n, 2 * n))
    gen[:n, n:] = np.eye(n)
    gen[n:, :n] = -np.linalg.solve(mass, stiffness)
    return gen
