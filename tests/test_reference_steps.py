"""The (+) and (−) steps of dv.simulate against independent hand-written references.

The references (tests/_references.py) are NumPy only: the paper's equations (DESIGN.md §1)
with hand-derived gradients, hand-written one-forms and a hand Newton iteration. diracvi is
only called through ``dv.simulate`` and compared with them to ~1e-10.
"""

from __future__ import annotations

import numpy as np
import pytest

import diracvi as dv
from _references import (
    C_DAMP,
    MASS,
    STIFF,
    THETA,
    HandModel,
    damped_model,
    disk_model,
    pendulum_model,
)
from diracvi import problems


def assert_matches(traj, ref, atol):
    q, p, mu = ref
    scale = max(1.0, np.max(np.abs(q)), np.max(np.abs(p)))
    np.testing.assert_allclose(traj.q, q, rtol=0, atol=atol * scale, err_msg="q")
    np.testing.assert_allclose(traj.p, p, rtol=0, atol=atol * scale, err_msg="p")
    mu_scale = max(1.0, np.max(np.abs(mu), initial=0.0))
    np.testing.assert_allclose(traj.multipliers, mu, rtol=0, atol=atol * mu_scale, err_msg="μ")


# ------------------------------------------------------------ rolling disk: A(q)
SLOW = pytest.mark.slow  # each case compiles a run (~4 s); CI keeps the distinct nodes


@pytest.mark.parametrize(
    ("rule", "scheme"),
    [
        ("retraction", "plus"),
        ("retraction", "minus"),
        ("midpoint", "plus"),
        pytest.param("midpoint", "minus", marks=SLOW),
    ],
)
def test_rolling_disk_matches_the_hand_reference(rule, scheme):
    """Configuration-dependent one-forms: A at q_k (+), q_{k+1} (−), q̄ (midpoint); the
    reaction A(q_k)ᵀμ (+) / A(q_{k+1})ᵀμ (−). h is large so a wrong node is O(h) off."""
    prob = problems.get("rolling-disk")
    h, steps = 0.2, 25
    traj = dv.simulate(
        prob.system, prob.q0, prob.p0, dt=h, steps=steps, scheme=scheme, discretization=rule
    )
    ref = disk_model(prob).run(rule, scheme, h, prob.q0, prob.p0, steps)
    assert_matches(traj, ref, 1e-10)
    # the (−) constraint residual is ω_{d−}: A(q_{k+1}) v_k at the steps' right ends
    assert np.max(np.abs(traj.constraint_residual)) < 1e-12


# ------------------------------------------------- torn double pendulum: B(q)
@pytest.mark.parametrize(
    ("rule", "scheme"),
    [
        ("retraction", "plus"),
        ("retraction", "minus"),
        pytest.param("midpoint", "plus", marks=SLOW),
        pytest.param("midpoint", "minus", marks=SLOW),
    ],
)
def test_torn_double_pendulum_matches_the_hand_reference(rule, scheme):
    """An interaction B(q) depending on θ₁, a degenerate lower Lagrangian: q, p and the
    interaction multipliers λ agree with the hand-written (±) equations."""
    prob = problems.get("double-pendulum-torn")
    h, steps = 0.05, 20
    traj = dv.simulate(
        prob.system, prob.q0, prob.p0, dt=h, steps=steps, scheme=scheme, discretization=rule
    )
    ref = pendulum_model(prob).run(rule, scheme, h, prob.q0, prob.p0, steps)
    assert_matches(traj, ref, 1e-10)
    assert np.max(np.abs(ref[2])) > 1.0  # the joint carries a real force


# --------------------------------------------- a forced (damped) DEL reference
def damped_lagrangian(q, v):
    return 0.5 * v @ MASS @ v - 0.5 * q @ STIFF @ q - 0.1 * q[0] ** 4


def damped_force_jax(q, v):
    return -(1.0 + 0.5 * q[1] ** 2) * (C_DAMP @ v)  # configuration-dependent damping


@pytest.mark.parametrize("scheme", ["plus", "minus"])
@pytest.mark.parametrize("rule", ["retraction", "midpoint"])
def test_damped_del_matches_the_hand_reference(rule, scheme):
    """Forces enter with the rule's weights ((1, 0) left point, (½, ½) midpoint) at its node;
    the energy is E(q_θ, v_k) of each step, in the order the trajectory stores the steps."""
    system = dv.LagrangeDiracSystem(("a", "b"), damped_lagrangian, force=damped_force_jax)
    q0, p0, h, steps = np.array([0.7, -0.9]), np.array([0.2, 0.5]), 0.1, 40
    traj = dv.simulate(system, q0, p0, dt=h, steps=steps, scheme=scheme, discretization=rule)
    ref = damped_model().run(rule, scheme, h, q0, p0, steps)
    assert_matches(traj, ref, 1e-10)
    # energy of step j, between traj.q[j] and traj.q[j+1], in time order (q_k, q_{k+1})
    qa, qb = ref[0][:-1], ref[0][1:]
    qk, qk1 = (qa, qb) if scheme == "plus" else (qb, qa)
    v = (qk1 - qk) / h
    node = qk + THETA[rule] * (qk1 - qk)
    energy = 0.5 * np.einsum("ki,ij,kj->k", v, MASS, v)
    energy += 0.5 * np.einsum("ki,ij,kj->k", node, STIFF, node) + 0.1 * node[:, 0] ** 4
    np.testing.assert_allclose(traj.energy, energy, rtol=1e-11, atol=1e-12)
    # the damper removes energy in the direction of time
    assert (
        traj.energy[-1] < traj.energy[0] if scheme == "plus" else traj.energy[-1] > traj.energy[0]
    )


def test_unforced_and_forced_references_differ():
    """The reference itself sees the force (guards the test above against a zero force)."""
    q0, p0 = np.array([0.7, -0.9]), np.array([0.2, 0.5])
    forced = damped_model().run("retraction", "plus", 0.1, q0, p0, 5)[0]
    free = HandModel(2, damped_model().l_q, damped_model().l_v).run(
        "retraction", "plus", 0.1, q0, p0, 5
    )[0]
    assert np.max(np.abs(forced - free)) > 1e-3
