"""Order of accuracy against exact solutions: the fitted log–log slope is the rule's order."""

import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope
from diracvi import problems

HS = np.array([0.04, 0.02, 0.01, 0.005])
ORDER = {"retraction": 1, "midpoint": 2}

#: the error constant C of error ≈ C h^p, measured (it is the same at every h of HS to
#: within 1.5 %); the tests allow 20 % above it. A scheme with the right order but a wrong
#: constant (a force or a node weighted wrongly) fails here, not on the slope.
CONSTANT = {
    ("spring-chain", "retraction"): 0.502,
    ("spring-chain", "midpoint"): 0.565,
    ("lc", "midpoint"): 0.0582,
    ("rlc", "retraction"): 1.293,
    ("rlc", "midpoint"): 0.267,
    ("rolling-disk", "retraction"): 0.832,
    ("rolling-disk", "midpoint"): 0.123,
    ("damped-oscillator", "retraction"): 0.431,
    ("damped-oscillator", "midpoint"): 0.131,
    ("dc-motor", "retraction"): 1.606,
    ("dc-motor", "midpoint"): 0.546,
    ("spring-chain", "retraction", "minus"): 0.501,
}
MARGIN = 1.2


def assert_error_constant(key, hs, errors, order):
    constants = np.asarray(errors) / np.asarray(hs) ** order
    assert np.all(constants <= MARGIN * CONSTANT[key]), (key, constants)
    assert np.all(constants >= CONSTANT[key] / MARGIN), (key, constants)


def global_error(problem, discretization, h, horizon, scheme="plus"):
    steps = round(horizon / h)
    traj = dv.simulate(
        problem.system,
        problem.q0,
        problem.p0,
        dt=h,
        steps=steps,
        discretization=discretization,
        scheme=scheme,
    )
    return np.max(np.abs(traj.q - problem.exact(traj.t)))


@pytest.mark.parametrize(
    ("name", "discretization", "horizon"),
    [
        ("spring-chain", "retraction", 2.0),
        ("spring-chain", "midpoint", 2.0),
        ("lc", "midpoint", 2.0),
        ("rlc", "retraction", 2.0),
        ("rlc", "midpoint", 2.0),
        ("rolling-disk", "retraction", 2.0),
        ("rolling-disk", "midpoint", 2.0),
        ("damped-oscillator", "retraction", 2.0),
        ("damped-oscillator", "midpoint", 2.0),
        ("dc-motor", "retraction", 0.2),
        ("dc-motor", "midpoint", 0.2),
    ],
)
def test_convergence_order(name, discretization, horizon):
    problem = problems.get(name)
    hs = HS * (0.1 if name == "dc-motor" else 1.0)
    errors = [global_error(problem, discretization, h, horizon) for h in hs]
    slope = loglog_slope(hs, errors)
    assert abs(slope - ORDER[discretization]) < 0.15, (slope, errors)
    assert_error_constant((name, discretization), hs, errors, ORDER[discretization])


def test_minus_scheme_converges_backward_in_time():
    problem = problems.get("spring-chain")
    errors = [global_error(problem, "retraction", h, 2.0, scheme="minus") for h in HS]
    assert abs(loglog_slope(HS, errors) - 1) < 0.15
    assert_error_constant(("spring-chain", "retraction", "minus"), HS, errors, 1)


def test_lc_circuit_under_the_left_point_rule_is_reported_unsolvable():
    """A capacitor loop leaves q_{k+1} of both capacitors undetermined (see circuits.py)."""
    problem = problems.get("lc")
    with pytest.raises(dv.UnsolvableStepError) as info:
        dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps=10)
    message = str(info.value)
    assert "not solvable at this state" in message
    assert "q_{k+1}[qC1]" in message and "q_{k+1}[qC2]" in message
    assert "midpoint" in message
