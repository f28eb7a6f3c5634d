"""The (−) scheme runs backward in time, and (paper §3) (+) and (−) give the same
positions when their discrete constraints agree."""

import numpy as np
import pytest

import diracvi as dv
from conftest import run
from diracvi import problems


def forward_then_backward(problem, discretization, steps=300):
    fwd = run(problem, steps=steps, discretization=discretization)
    back = dv.simulate(
        problem.system,
        fwd.q[-1],
        fwd.p[-1],
        dt=problem.dt,
        steps=steps,
        scheme="minus",
        discretization=discretization,
        t0=fwd.t[-1],
    )
    return fwd, back


def test_minus_runs_backward_in_time():
    problem = problems.get("spring-chain")
    traj = run(problem, scheme="minus", steps=50)
    np.testing.assert_allclose(traj.t, -problem.dt * np.arange(51), atol=1e-15)
    assert np.max(np.abs(traj.q - problem.exact(traj.t))) < 0.05


@pytest.mark.parametrize(
    ("name", "discretization"),
    [
        ("spring-chain-torn", "retraction"),  # constant one-form dq² − dq̄²
        ("rlc-torn", "midpoint"),  # constant one-forms, forces, degenerate L
        ("rolling-disk", "midpoint"),  # q-dependent one-forms, but ω_{d+} = ω_{d−}
    ],
)
def test_plus_and_minus_give_the_same_positions_when_constraints_agree(name, discretization):
    fwd, back = forward_then_backward(problems.get(name), discretization)
    np.testing.assert_allclose(back.t, fwd.t[::-1], atol=1e-12)
    scale = max(1.0, np.max(np.abs(fwd.q)))
    assert np.max(np.abs(back.q - fwd.q[::-1])) < 1e-11 * scale
    # the multipliers are the same up to the sign convention of where they act
    if fwd.multipliers.shape[1]:
        lam = np.max(np.abs(fwd.multipliers))
        assert np.max(np.abs(back.multipliers[::-1][:-1] + fwd.multipliers[1:])) < 1e-9 * lam


def test_plus_and_minus_differ_when_the_discrete_constraints_differ():
    """Left-point rule, q-dependent one-forms: A(q_k) v_k ≠ A(q_{k+1}) v_k → O(h) apart."""
    fwd, back = forward_then_backward(problems.get("rolling-disk"), "retraction")
    assert np.max(np.abs(back.q - fwd.q[::-1])) > 1e-5
