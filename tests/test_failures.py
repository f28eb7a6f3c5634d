"""A step that cannot be solved stops the run with a status and a message that says where,
with what residual, and what to try — and keeps every step computed before it."""

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv


def cliff():
    """A particle rolling into a potential that is undefined past q = 1 (NaN there)."""
    return dv.LagrangeDiracSystem(("q",), lambda q, v: 0.5 * v @ v + jnp.sqrt(1.0 - q[0]))


def test_nan_stops_the_run_and_keeps_the_steps_before_it():
    traj = dv.simulate(cliff(), [0.0], [2.0], dt=0.01, steps=500, throw=False)
    assert traj.status == dv.SolveStatus.NONFINITE
    assert 0 < traj.steps < 500 and traj.steps_requested == 500
    assert np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.energy))
    # it stopped at the cliff: within a step or two of q = 1 (speed ≤ 2.5, h = 0.01)
    assert abs(traj.q[-1, 0] - 1.0) <= 2 * 0.01 * 2.5
    assert f"at step {traj.steps}" in traj.message and "NaN or Inf" in traj.message
    assert "smaller dt" in traj.message
    # the partial run is exactly the start of an unbroken run
    head = dv.simulate(cliff(), [0.0], [2.0], dt=0.01, steps=traj.steps)
    np.testing.assert_array_equal(head.q, traj.q)


def test_default_raises_with_the_partial_trajectory():
    with pytest.raises(dv.StepFailure) as info:
        dv.simulate(cliff(), [0.0], [2.0], dt=0.01, steps=500)
    partial = info.value.trajectory
    assert partial.status == dv.SolveStatus.NONFINITE and partial.steps > 0
    assert str(info.value) == partial.message


def test_newton_iteration_cap_reports_step_and_residual():
    pendulum = dv.LagrangeDiracSystem(("theta",), lambda q, v: 0.5 * v @ v + jnp.cos(q[0]))
    traj = dv.simulate(
        pendulum,
        [1.0],
        [0.0],
        dt=0.1,
        steps=10,
        discretization="midpoint",
        solver=dv.NewtonSolver(max_steps=1),
        throw=False,
    )
    assert traj.status == dv.SolveStatus.MAX_ITERATIONS and traj.steps == 0
    assert "Newton did not converge at step 0" in traj.message
    assert "after 1 iterations" in traj.message and "residual ‖r‖∞ = " in traj.message
    assert "max_steps" in traj.message
