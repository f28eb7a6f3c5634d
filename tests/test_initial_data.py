"""Inconsistent initial data are reported with their size and can be projected away;
float64 is enforced."""

import jax
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems


def test_port_mismatch_is_reported_and_projected():
    problem = problems.get("spring-chain-torn")
    q0 = problem.q0.copy()
    q0[2] += 0.25  # right.q2bar no longer at left.q2
    with pytest.warns(dv.InconsistentInitialDataWarning, match=r"up to 2\.500e-01") as info:
        bad = dv.simulate(problem.system, q0, problem.p0, dt=0.01, steps=50)
    assert "project_initial=True" in str(info[0].message)
    assert "left.q2" in str(info[0].message)
    assert np.allclose(bad["left.q2"] - bad["right.q2bar"], -0.25)  # the offset persists
    fixed = dv.simulate(problem.system, q0, problem.p0, dt=0.01, steps=50, project_initial=True)
    np.testing.assert_allclose(fixed.q[0, 1:3], [1.125, 1.125])
    assert np.max(np.abs(fixed["left.q2"] - fixed["right.q2bar"])) < 1e-13


def test_momenta_outside_the_legendre_image_are_reported_and_projected():
    """L ∥ C1 ∥ C2: p^{C1} must vanish up to the KCL multiplier (p^{C1} = p^{C2} = −μ)."""
    problem = problems.get("lc")
    p0 = problem.p0 + np.array([0.0, 0.3, 0.0])
    kwargs = {"dt": 0.01, "steps": 200, "discretization": "midpoint"}
    with pytest.warns(dv.InconsistentInitialDataWarning, match="momenta a degenerate"):
        dv.simulate(problem.system, problem.q0, p0, **kwargs)
    q, p = dv.project_initial_state(problem.system, problem.q0, p0)
    np.testing.assert_array_equal(q, problem.q0)  # no ports: positions untouched
    assert abs(p[1] - p[2]) < 1e-14  # equal capacitor momenta: a pure multiplier
    fixed = dv.simulate(problem.system, problem.q0, p0, project_initial=True, **kwargs)
    np.testing.assert_allclose(fixed.p[0], p, atol=1e-14)


def test_consistent_built_in_problems_raise_no_warning(recwarn):
    for name in ("rlc-torn", "dc-motor", "double-pendulum-torn"):
        problem = problems.get(name)
        dv.simulate(problem.system, problem.q0, problem.p0, dt=problem.dt, steps=5)
    assert not [w for w in recwarn if issubclass(w.category, dv.InconsistentInitialDataWarning)]


def test_float64_is_switched_back_on_loudly():
    problem = problems.get("spring-chain")
    jax.config.update("jax_enable_x64", False)
    try:
        with pytest.warns(RuntimeWarning, match="float64"):
            traj = dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps=5)
        assert jax.config.jax_enable_x64
        assert traj.q.dtype == np.float64
    finally:
        jax.config.update("jax_enable_x64", True)
