"""An affine run in blocks (the blocks' starts by a recursion, every state from its
block's start) is the single-step recursion ``z_{k+1} = z_k + Δ z_k + b``, whatever the
block length and however the run's length falls on the blocks.

White-box: reads internals of ``diracvi.discretization.rules``,
``diracvi.driver.simulate``, ``diracvi.solvers``."""

import jax
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.discretization.rules import get_rule
from diracvi.driver.simulate import check_run, prepared_plan
from diracvi.solvers import affine


@pytest.mark.parametrize(
    ("block", "steps"),
    [
        (1, 1),  # one step
        (1, 4),  # blocks of one step: a map too large for longer blocks
        (5, 1),
        (5, 13),  # three blocks of 5, the last one partly used
        (64, 130),  # the default: three blocks of 44 (equal widths), two starts
    ],
)
def test_blocks_are_the_single_step_recursion(monkeypatch, block, steps):
    monkeypatch.setattr(affine, "MAX_BLOCK", block)  # read when the plan builds its map
    prob = problems.spring_chain_torn(dt=0.01, steps=steps)  # a fresh system: a fresh plan
    q0, p0 = np.asarray(prob.q0, float), np.asarray(prob.p0, float)
    traj = dv.simulate(prob.system, q0, p0, dt=prob.dt, steps=steps, solver=dv.AffineSolver())
    run = check_run(prob.system, "plus", "retraction", prob.dt, steps, 1, dv.AffineSolver())
    step_map = prepared_plan(prob.system, run, dv.AffineSolver(), q0, p0).step_map
    assert step_map.powers.shape[0] == block
    assert traj.solver == "affine step map"  # every step verified: no fallback to Newton

    offsets = np.broadcast_to(np.asarray(step_map.offset), (steps, 2 * prob.system.n))
    assert_single_steps(traj, step_map, np.concatenate([q0, p0]), offsets, step_map.mu_offset)


def assert_single_steps(traj, step_map, z0, offsets, mu_offsets):
    """``traj`` is ``z_{k+1} = z_k + Δ z_k + offsets[k]`` from ``z0``, with multipliers
    ``μ_k = C z_k + mu_offsets[k]``, to round-off (1e-13 of the largest value)."""
    delta = np.asarray(step_map.delta)
    z = [z0]
    for b in offsets:
        z.append(z[-1] + (delta @ z[-1] + b))
    z = np.array(z)
    n = z0.shape[0] // 2
    scale = np.max(np.abs(z))
    np.testing.assert_allclose(traj.q, z[:, :n], rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(traj.p, z[:, n:], rtol=0, atol=1e-13 * scale)
    mu = z[:-1] @ np.asarray(step_map.mu_map).T + np.asarray(mu_offsets)
    np.testing.assert_allclose(traj.multipliers, mu, rtol=0, atol=1e-13 * np.max(np.abs(mu)))


@pytest.mark.parametrize(
    ("block", "steps"),
    [(1, 1), (1, 4), (5, 1), (5, 13), (64, 130)],
)
def test_driven_blocks_are_the_single_step_recursion(monkeypatch, block, steps):
    """A driven model's blocks carry their own offsets b_j = Σ_{i<j} (I+Δ)^{j−1−i} b(t_i)
    (:meth:`AffineStepMap.block_offsets`): still ``z_{k+1} = z_k + Δ z_k + b(t_k)``."""
    monkeypatch.setattr(affine, "MAX_BLOCK", block)
    prob = problems.rlc_sine(dt=0.01, steps=steps)
    q0, p0, h, t0 = np.asarray(prob.q0, float), np.asarray(prob.p0, float), prob.dt, 0.3
    args = dict(dt=h, steps=steps, t0=t0, discretization="midpoint")
    traj = dv.simulate(prob.system, q0, p0, solver=dv.AffineSolver(), **args)
    run = check_run(prob.system, "plus", "midpoint", h, steps, 1, dv.AffineSolver())
    step_map = prepared_plan(prob.system, run, dv.AffineSolver(), q0, p0, t0).step_map
    assert step_map.driven and step_map.powers.shape[0] == block
    assert traj.solver == "affine step map"  # every step verified: no fallback to Newton

    times = t0 + h * np.arange(steps)  # each step's start; the map evaluates its node
    offsets = jax.jit(
        lambda t: step_map.offsets_at(prob.system, get_rule("midpoint"), "plus", h, t)
    )
    b, mu_b = (np.asarray(a) for a in offsets(times))
    assert_single_steps(traj, step_map, np.concatenate([q0, p0]), b, mu_b)
