"""The affine step map on the run's invariant subspace (``ReducedMap``) is the full map:
the same states, momenta and multipliers to 1e-13 over the paper's horizons, the
constraints kept to round-off over long runs, and no reduction where none applies."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi._discretize import get_rule
from diracvi._plan import get_plan
from diracvi._stepping import chunk_runner


def plan_of(problem, discretization="retraction"):
    rule = get_rule(discretization)
    return rule, get_plan(problem.system, rule, "plus", problem.dt, None, problem.q0, problem.p0)


def states(problem, rule, step_map, steps, save_every=1):
    """Saved ``(q, p, μ, constraint residual)`` of one chunk stepped by ``step_map``."""
    system = problem.system
    runner = chunk_runner(system, rule, "plus", step_map, save_every, True, steps // save_every)
    carry = (problem.q0, problem.p0, problem.q0, jnp.zeros(system.m))
    _, fail, saved = jax.jit(runner)(problem.dt, jnp.array([0.0, 0.0]), carry)
    assert int(fail[0]) == 0
    return {k: np.asarray(saved[k]) for k in ("q", "p", "mu", "con")}


def rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


@pytest.mark.parametrize("discretization", ["retraction", "midpoint"])
@pytest.mark.parametrize(
    ("name", "dims"),
    # (dim z = 2n, dim of the invariant subspace) under each rule
    [("spring-chain-torn", (8, 6, 6)), ("rlc-torn", (10, 2, 3)), ("dc-motor", (14, 3, 3))],
)
def test_reduced_map_equals_the_full_map(name, dims, discretization):
    problem = problems.get(name)
    rule, plan = plan_of(problem, discretization)
    reduced = plan.step_map.reduced
    size, rank = dims[0], dims[1 if discretization == "retraction" else 2]
    assert reduced is not None and reduced.basis.shape == (size, rank)
    full_map = eqx.tree_at(lambda m: m.reduced, plan.step_map, None)
    for save_every in (1, 100):  # whole-chunk steps, and blocks of 100 steps
        small = states(problem, rule, plan.step_map, 1000, save_every)
        full = states(problem, rule, full_map, 1000, save_every)
        for key in ("q", "p", "mu"):
            assert rel(small[key], full[key]) <= 1e-13, (key, save_every)


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
        ("spring-chain", "retraction", "the hand-built chain's increments span all of z"),
        ("dc-motor-driven", "retraction", "a driven model's offsets move with t"),
        ("spring-chain-torn", "lobatto", "a staged rule keeps the full map"),
    ],
)
def test_no_reduction_where_it_does_not_apply(name, discretization, why):
    problem = problems.get(name)
    _, plan = plan_of(problem, discretization)
    assert plan.step_map is not None and plan.step_map.reduced is None, why
    traj = dv.simulate(
        problem.system,
        problem.q0,
        problem.p0,
        dt=problem.dt,
        steps=200,
        discretization=discretization,
    )
    assert traj.success and traj.solver == "affine step map"


def test_a_nonlinear_model_has_no_step_map():
    problem = problems.get("double-pendulum-torn")
    _, plan = plan_of(problem)
    assert plan.step_map is None
