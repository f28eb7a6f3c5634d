"""Andrews' squeezing mechanism (``problems.andrews``) against the published test set.

External references (Hairer & Wanner vol. II §VII.7; the Bari/CWI IVP test set
"andrews", nobody here wrote them): the consistent initial state with its accelerations
and multipliers, and the angles at t = 0.03 (PSIDE at tolerance 1e-14).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.problems.andrews import Q0, REFERENCE_Q

#: the test set's INITIAL: q̈(0) (first two; the rest are 0) and λ(0) (first two; rest 0)
ACCELERATION0 = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415])
MULTIPLIER0 = np.array([98.5668703962410896057654982170, -6.12268834425566265503114393122])


def test_the_model_at_rest_has_the_published_accelerations_and_multipliers():
    """At the consistent rest state, ``M q̈ = ∂L/∂q + F − Gᵀλ``, ``G q̈ = 0`` (Lagrange's
    equations of the model's own L, F, g) give the test set's ``q̈(0)`` and ``λ(0)``."""
    system = problems.get("andrews").system

    @jax.jit  # one program: eager, each autodiff operation would be dispatched alone
    def at_rest(q):
        v = jnp.zeros(7)
        mass = jax.hessian(system.lagrangian, argnums=1)(q, v)
        forcing = jax.grad(system.lagrangian, argnums=0)(q, v) + system.force(q, v)
        jac = jax.jacfwd(system.position_constraints)(q)
        kkt = jnp.block([[mass, jac.T], [jac, jnp.zeros((6, 6))]])
        rhs = jnp.concatenate([forcing, jnp.zeros(6)])
        return system.position_constraints(q), jnp.linalg.solve(kkt, rhs)

    residual, sol = (np.asarray(a) for a in at_rest(jnp.asarray(Q0)))
    np.testing.assert_allclose(residual, 0.0, atol=1e-15)
    acc, lam = sol[:7], sol[7:]
    np.testing.assert_allclose(acc[:2], ACCELERATION0, rtol=1e-9)
    np.testing.assert_allclose(acc[2:], 0.0, atol=1e-9 * np.abs(ACCELERATION0).max())
    np.testing.assert_allclose(lam[:2], MULTIPLIER0, rtol=1e-9)
    np.testing.assert_allclose(lam[2:], 0.0, atol=1e-9 * np.abs(MULTIPLIER0).max())


@pytest.mark.slow
def test_lobatto_and_midpoint_reach_the_published_solution_at_their_orders():
    """At t = 0.03 (β has turned ≈ 16 rad): lobatto at 300 steps within 2e-6 of the
    published angles (measured 8e-7); midpoint's error falls as h² (fitted order 2)."""
    problem = problems.get("andrews")
    t_end = problem.dt * problem.steps
    assert t_end == pytest.approx(0.03)

    def error(rule, steps):
        traj = dv.simulate(
            problem.system, problem.q0, problem.p0, dt=t_end / steps, steps=steps,
            discretization=rule,
        )  # fmt: skip
        return np.max(np.abs(np.asarray(traj.q[-1]) - REFERENCE_Q))

    assert error("lobatto", problem.steps) < 2e-6
    coarse, fine = error("midpoint", 300), error("midpoint", 600)
    assert np.log2(coarse / fine) == pytest.approx(2.0, abs=0.1)
