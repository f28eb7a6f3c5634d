"""The affine step map on the run's invariant subspace (``ReducedMap``) is the full map:
the same states, momenta and multipliers to 1e-13 over the paper's horizons, the
constraints kept to round-off over long runs, and no reduction where none applies."""

import jax
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi._discretize import get_rule
from diracvi._plan import get_plan


def plan_of(problem, discretization="retraction"):
    rule = get_rule(discretization)
    return rule, get_plan(problem.system, rule, "plus", problem.dt, None, problem.q0, problem.p0)


def iterated(step_map, z0, steps):
    """``z_1 … z_steps`` of the full map ``z ← z + Δ z + b``, in extended precision."""
    wide = np.longdouble
    delta, offset = (np.asarray(a).astype(wide) for a in (step_map.delta, step_map.offset))
    z, out = z0.astype(wide), []
    for _ in range(steps):
        z = z + (delta @ z + offset)
        out.append(z)
    return np.array(out)


def rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("discretization", ["retraction", "midpoint"])
@pytest.mark.parametrize(
    ("name", "dims"),
    # (dim z = 2n, dim of the invariant subspace) under each rule
    [("spring-chain-torn", (8, 6, 6)), ("rlc-torn", (10, 2, 3)), ("dc-motor", (14, 3, 3))],
)
def test_reduced_map_equals_the_full_map(name, dims, discretization):
    """States, momenta and multipliers of the paper's horizon (and of a run shorter than
    one block) against the full map iterated in extended precision, to 1e-13."""
    problem = problems.get(name)
    _, plan = plan_of(problem, discretization)
    step_map = plan.step_map
    reduced = step_map.reduced
    size, rank = dims[0], dims[1 if discretization == "retraction" else 2]
    assert reduced is not None and reduced.basis.shape == (size, rank)
    z0 = np.concatenate([problem.q0, problem.p0])
    mu_map, mu_offset = np.asarray(step_map.mu_map), np.asarray(step_map.mu_offset)
    for steps in (problem.steps, 7):
        small = np.asarray(jax.jit(lambda z, k=steps: reduced.states(step_map, z, k))(z0))
        exact = iterated(step_map, z0, steps).astype(np.float64)
        assert rel(small, exact) <= 1e-13
        # μ of each step is C z_from + c: the same product of states for both
        mus = np.concatenate([z0[None], small[:-1]]) @ mu_map.T + mu_offset
        exact_mus = np.concatenate([z0[None], exact[:-1]]) @ mu_map.T + mu_offset
        assert rel(mus, exact_mus) <= 1e-13


@pytest.mark.parametrize("name", ["spring-chain-torn", "rlc-torn", "dc-motor"])
def test_reduced_runs_keep_the_constraints_over_a_long_run(name):
    """10⁵ steps: every step's constraint residual (the violation covers each step of
    an interval) stays at round-off; joined ports stay equal to the bit."""
    problem = problems.get(name)
    _, plan = plan_of(problem)
    assert plan.step_map.reduced is not None
    traj = dv.simulate(
        problem.system, problem.q0, problem.p0, dt=problem.dt, steps=100_000, save_every=500
    )
    assert traj.solver == "affine step map"
    scale = max(1.0, float(np.max(np.abs(traj.q))))
    assert np.max(traj.constraint_violation) <= 1e-12 * scale
    assert np.all(np.abs(traj.constraint_residual) <= 1e-12 * scale)
    checker = plan.checker
    for group in checker.groups:  # joined ports: identical coordinates
        assert np.all(traj.q[:, group] == traj.q[:, group[:1]])


@pytest.mark.parametrize(
    ("name", "discretization", "why"),
    [
        ("dc-motor-driven", "retraction", "a driven model's offsets move with t"),
        ("spring-chain-torn", "lobatto", "a staged rule keeps the full map"),
    ],
)
def test_no_reduction_where_it_does_not_apply(name, discretization, why):
    problem = problems.get(name)
    _, plan = plan_of(problem, discretization)
    assert plan.step_map is not None and plan.step_map.reduced is None, why


def test_a_model_without_a_smaller_subspace_keeps_all_of_z():
    """The hand-built chain's increments span all of z: T = I, the full block maps
    evaluated in two levels, equal to the full map iterated in extended precision."""
    problem = problems.get("spring-chain")
    _, plan = plan_of(problem)
    reduced = plan.step_map.reduced
    np.testing.assert_array_equal(reduced.basis, np.eye(6))
    z0 = np.concatenate([problem.q0, problem.p0])
    run = np.asarray(jax.jit(lambda z: reduced.states(plan.step_map, z, 1000))(z0))
    assert rel(run, iterated(plan.step_map, z0, 1000).astype(np.float64)) <= 1e-13


def test_a_nonlinear_model_has_no_step_map():
    problem = problems.get("double-pendulum-torn")
    _, plan = plan_of(problem)
    assert plan.step_map is None
