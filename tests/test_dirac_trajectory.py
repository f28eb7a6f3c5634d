"""Every step of the integrator satisfies (X_d^k, 𝔇^±L_d) ∈ D^{d±}_Δ to round-off; a
perturbed state is caught at exactly the steps that use it.

Bound: ``max_k residual_k ≤ 1e-10 · max(1, max |p|)`` — the residual mixes momenta and
discrete constraint values ``A v_k``, both O(max |p|) for these problems."""

from __future__ import annotations

import copy

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import ModelError, problems
from diracvi.dirac import step_residuals, system_dirac_differential, trajectory_residual

BOUND = 1e-10

# (problem, discretization, scheme): every built-in problem with constraints or forces,
# each rule it supports, forward; plus backward ("minus") runs
CASES = [
    ("spring-chain", "retraction", "plus"),
    ("rlc", "retraction", "plus"),
    ("rlc", "midpoint", "minus"),
    ("lc", "midpoint", "plus"),
    ("damped-oscillator", "retraction", "plus"),
    ("damped-oscillator", "midpoint", "minus"),
    ("rolling-disk", "retraction", "plus"),
    ("rolling-disk", "midpoint", "plus"),
    ("rolling-disk", "retraction", "minus"),
    # interconnected models: the diagnostic sees only the DiracSystem protocol
    ("spring-chain-torn", "retraction", "plus"),
    ("rlc-torn", "retraction", "plus"),
    ("rlc-torn", "midpoint", "minus"),
    ("double-pendulum-torn", "retraction", "plus"),
    ("double-pendulum-torn", "midpoint", "plus"),
    ("dc-motor", "midpoint", "plus"),
]

_CACHE: dict = {}


def _run(name, rule, scheme, steps=200):
    key = (name, rule, scheme, steps)
    if key not in _CACHE:
        prob = problems.get(name)
        traj = dv.simulate(
            prob.system,
            prob.q0,
            prob.p0,
            dt=prob.dt,
            steps=steps,
            scheme=scheme,
            discretization=rule,
        )
        _CACHE[key] = (prob.system, traj)
    return _CACHE[key]


def _scale(traj):
    return max(1.0, float(np.max(np.abs(traj.p))))


@pytest.mark.parametrize(("name", "rule", "scheme"), CASES)
def test_every_step_is_in_the_discrete_dirac_structure(name, rule, scheme):
    system, traj = _run(name, rule, scheme)
    res = trajectory_residual(system, traj)
    assert res.shape == (traj.steps,)
    assert np.max(res) <= BOUND * _scale(traj)
    # the method on Trajectory delegates to the same diagnostic
    np.testing.assert_array_equal(traj.dirac_residual(system), res)


@pytest.mark.parametrize(("name", "rule", "scheme"), CASES)
def test_recovered_multipliers_are_the_integrators(name, rule, scheme):
    """The least-squares multipliers of the membership (independent of Newton) equal the
    integrator's μ_k: the Dirac-structure view and the equations agree on everything."""
    system, traj = _run(name, rule, scheme)
    parts = step_residuals(system, traj)
    assert parts.multipliers.shape == traj.multipliers.shape
    if traj.multipliers.size:
        scale = max(1.0, float(np.max(np.abs(traj.multipliers))))
        assert np.max(np.abs(parts.multipliers - traj.multipliers)) <= 1e-10 * scale


def _perturbed(traj, which, j, coord, delta=1e-6):
    bad = copy.copy(traj)
    bad.q, bad.p = traj.q.copy(), traj.p.copy()
    getattr(bad, which)[j, coord] += delta
    return bad


@pytest.mark.parametrize(
    ("name", "rule", "scheme", "which", "coord"),
    [
        ("spring-chain", "retraction", "plus", "q", 1),
        ("spring-chain", "retraction", "plus", "p", 2),
        ("rolling-disk", "midpoint", "plus", "q", 3),
        ("rolling-disk", "retraction", "plus", "p", 0),
        ("rlc", "retraction", "plus", "q", 2),
        ("rlc", "midpoint", "minus", "p", 1),
        ("damped-oscillator", "retraction", "plus", "q", 0),
    ],
)
def test_perturbation_is_caught_at_exactly_the_steps_that_use_it(name, rule, scheme, which, coord):
    system, traj = _run(name, rule, scheme)
    j = 57  # state index (row of traj.q / traj.p); rows j−1 → j and j → j+1 use it
    bad = _perturbed(traj, which, j, coord)
    res = trajectory_residual(system, bad)
    tol = BOUND * _scale(traj)
    flagged = set(np.nonzero(res > tol)[0].tolist())
    assert flagged == {j - 1, j}
    # and the size is the perturbation's, far above round-off
    assert np.min(res[[j - 1, j]]) > 10 * tol
    assert np.min(res[[j - 1, j]]) > 1e-7  # the size of the 1e-6 shift, not round-off


def test_a_p_change_at_the_start_or_end_is_caught_by_one_step():
    system, traj = _run("rolling-disk", "retraction", "plus")
    assert set(np.nonzero(trajectory_residual(system, _perturbed(traj, "p", 0, 2)) > 1e-9)[0]) == {
        0
    }
    last = traj.steps
    flagged = np.nonzero(trajectory_residual(system, _perturbed(traj, "p", last, 2)) > 1e-9)[0]
    assert flagged.tolist() == [last - 1]


def test_residual_pieces_by_hand_for_the_damped_oscillator():
    """L = ½ m v² − ½ k q², F = −c v, retraction rule: P⁻ = m v_k + h k q_k − h(−c v_k)·(−1)…
    computed here directly: P⁻ = −D₁L_d − f⁻ = m v_k + h k q_k + h c v_k, P⁺ = m v_k."""
    system, traj = _run("damped-oscillator", "retraction", "plus")
    m, k, c = 1.0, 1.0, 0.1
    h = traj.dt
    bad = _perturbed(traj, "p", 10, 0, delta=0.5)
    parts = step_residuals(system, bad)
    qk, qk1 = bad.q[10, 0], bad.q[11, 0]
    v = (qk1 - qk) / h
    p_minus = m * v + h * k * qk + h * c * v
    # step 10: fibre residual P⁻ − p_10 (no constraints: Δ° = 0)
    assert parts.fiber[10, 0] == pytest.approx(p_minus - bad.p[10, 0], rel=1e-9)
    assert parts.fiber[10, 0] == pytest.approx(-0.5, rel=1e-6)
    # step 9: base mismatch P⁺(q_9, q_10) − p_10
    v9 = (bad.q[10, 0] - bad.q[9, 0]) / h
    assert parts.base[9, 1] == pytest.approx(m * v9 - bad.p[10, 0], rel=1e-9)


def test_the_diagnostic_refuses_a_foreign_system():
    _, traj = _run("rolling-disk", "retraction", "plus")
    other = problems.get("rlc").system
    with pytest.raises(ModelError, match="system"):
        trajectory_residual(other, traj)


class _TornDampedChain(dv.DiracSystem):
    """A bare protocol implementation (not a LagrangeDiracSystem): the torn spring chain
    (q1, q2 | q2bar, q3) joined by dq2 − dq2bar, a damper on q3, and the discrete momenta
    assembled piece by piece as an interconnection does."""

    @property
    def coords(self):
        return ("left.q1", "left.q2", "right.q2bar", "right.q3")

    @property
    def constraint_names(self):
        return ("λ0",)

    @staticmethod
    def _left(q, v):
        return 0.5 * (v[0] ** 2 + v[1] ** 2) - 0.5 * q[0] ** 2 - 0.5 * (q[1] - q[0]) ** 2

    @staticmethod
    def _right(q, v):
        return 0.5 * v[1] ** 2 - 0.5 * (q[1] - q[0]) ** 2

    def lagrangian(self, q, v, t=0.0):
        return self._left(q[:2], v[:2]) + self._right(q[2:], v[2:])

    def force(self, q, v, t=0.0):
        return jnp.array([0.0, 0.0, 0.0, -0.3]) * v

    def constraint_forms(self, q, t=0.0):
        return jnp.array([[0.0, 1.0, -1.0, 0.0]])

    def discrete_momenta(self, rule, qk, qk1, h, tk=0.0):
        def piece(lag, a, b):
            return jax.grad(
                lambda x, y: rule.discrete_lagrangian(lambda q, v, t: lag(q, v), x, y, h, tk),
                argnums=(0, 1),
            )(a, b)

        l1, l2 = piece(self._left, qk[:2], qk1[:2])
        r1, r2 = piece(self._right, qk[2:], qk1[2:])
        f_minus, f_plus = rule.discrete_forces(self.force, qk, qk1, h, tk)
        return -jnp.concatenate([l1, r1]) - f_minus, jnp.concatenate([l2, r2]) + f_plus


@pytest.mark.parametrize(("rule", "scheme"), [("retraction", "plus"), ("midpoint", "minus")])
def test_any_dirac_system_protocol_implementation_works(rule, scheme):
    system = _TornDampedChain()
    traj = dv.simulate(
        system,
        [0.0, 1.0, 1.0, 2.0],
        [0.0, 0.0, 0.0, 3.0],
        dt=0.01,
        steps=100,
        scheme=scheme,
        discretization=rule,
    )
    parts = step_residuals(system, traj)
    assert np.max(parts.total) <= BOUND * _scale(traj)
    assert np.max(np.abs(parts.multipliers - traj.multipliers)) <= 1e-10
    assert np.max(trajectory_residual(system, _perturbed(traj, "q", 40, 3))) > 1e-5


@pytest.mark.parametrize(
    ("name", "scheme"),
    [("rlc", "plus"), pytest.param("rlc-torn", "minus", marks=pytest.mark.slow)],
)
def test_the_staged_rule_is_checked_with_its_stages_resolved(name, scheme):
    """A "lobatto" trajectory stores no stages; the diagnostic re-solves them from the
    states and checks the rule's (±) relation: round-off on the integrator's steps, the
    stored multipliers recovered, and large on a perturbed state or on a midpoint run
    presented as a lobatto one (a wrong scheme)."""
    problem = problems.get(name)

    def run(rule):
        return dv.simulate(
            problem.system,
            problem.q0,
            problem.p0,
            dt=0.05,
            steps=40,
            scheme=scheme,
            discretization=rule,
        )

    traj = run("lobatto")
    parts = step_residuals(problem.system, traj)
    assert np.max(parts.total) <= BOUND * _scale(traj)
    assert np.max(np.abs(parts.multipliers - traj.multipliers)) <= 1e-10
    assert np.max(traj.dirac_residual(problem.system)) <= BOUND * _scale(traj)
    assert np.max(trajectory_residual(problem.system, _perturbed(traj, "q", 20, 0))) > 1e-5
    wrong = copy.copy(run("midpoint"))
    wrong.discretization = "lobatto"
    assert np.max(trajectory_residual(problem.system, wrong)) > 1e-3


def test_the_two_point_structures_refuse_the_staged_rule_by_name():
    problem = problems.get("spring-chain")
    with pytest.raises(dv.ModelError, match="'lobatto' is not covered") as info:
        system_dirac_differential(
            problem.system, problem.q0, problem.q0 + 0.1, h=0.1, rule="lobatto"
        )
    message = str(info.value)  # it names the rules it covers, and the fix
    assert "'retraction' and 'midpoint'" in message and "Fix:" in message
