"""Discrete constraints hold to round-off at every step, for every built-in problem."""

import numpy as np
import pytest

from conftest import one_rule_each, run
from diracvi import problems

# Every built-in problem, built once per process: the parametrizations below read their
# rules and ports from these, and the tests run them (a built problem is not changed by a
# run), so a problem is not built again per test — nor twice at collection, in each worker.
BUILT = {name: problems.get(name) for name in problems.REGISTRY}

# every built-in problem, with one of its rules by default (the others with -m slow)
CASES = one_rule_each(list(BUILT), lambda name: BUILT[name].discretizations)


@pytest.mark.parametrize(("name", "discretization"), CASES)
def test_constraint_residual_at_round_off(name, discretization):
    problem = BUILT[name]
    traj = run(problem, discretization=discretization, steps=min(problem.steps, 500))
    assert traj.success
    assert traj.constraint_residual.shape == (traj.steps, problem.system.m)
    if problem.system.m:
        # velocity-level residuals: 1e-12 relative to the largest velocity in the run, plus
        # the floor of a difference quotient of positions of size |q|, a few ε |q| / h
        # (it dominates when the positions are large against a step's change)
        speed = max(1.0, np.max(np.abs(np.diff(traj.q, axis=0))) / problem.dt)
        floor = 50 * np.finfo(float).eps * np.max(np.abs(traj.q)) / problem.dt
        assert np.max(np.abs(traj.constraint_residual)) <= 1e-12 * speed + floor
    assert np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.p))


@pytest.mark.parametrize("name", [n for n in BUILT if BUILT[n].ports])
def test_ports_stay_joined(name):
    """q² = q̄², q^{S1} = q^{S2}, …: the position-level interconnection holds to round-off."""
    problem = BUILT[name]
    traj = run(problem)
    scale = max(1.0, np.max(np.abs(traj.q)))
    for a, b in problem.ports:
        assert np.max(np.abs(traj[a] - traj[b])) <= 1e-13 * scale * traj.steps**0.5
