"""A two-point rule written and registered from a test module, editing no library file:
the θ-rule, nodes at ``q_k + θ (q_{k+1} − q_k)``, ``t_k + θ h`` (docs/architecture.md).

The registry (``diracvi.discretization.rules``) is the documented way in for a new rule."""

import numpy as np
import pytest

import diracvi as dv
from diracvi.discretization.rules import register_rule, unregister_rule


class _Theta(dv.QuadratureRule):
    """``L_d = h L(q_θ, v_k, t_θ)`` with ``q_θ = (1 − θ) q_k + θ q_{k+1}``; the force
    splits ``(1 − θ, θ)`` between the ends, as ``∂q_θ/∂(q_k, q_{k+1})`` does."""

    theta = 0.5

    def __init__(self):
        self.name = f"theta-{self.theta:g}"
        self.order = 2 if self.theta == 0.5 else 1

    def node(self, qk, qk1):
        return qk + self.theta * (qk1 - qk)

    def time_node(self, tk, h):
        return tk + self.theta * h

    def constraint_node(self, side, qk, qk1):
        return self.node(qk, qk1)

    def constraint_time(self, side, tk, h):
        return self.time_node(tk, h)

    def force_weights(self):
        return 1.0 - self.theta, self.theta

    def impulse_share(self):
        return self.theta


class _ThetaQuarter(_Theta):
    theta = 0.25


@pytest.fixture
def theta_rules():
    rules = [register_rule(_Theta), register_rule(_ThetaQuarter)]
    yield [r().name for r in rules]
    for r in rules:
        unregister_rule(r().name)


def _oscillator():
    return dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v - 0.5 * q @ q)


def _error(rule, dt, horizon=2.0):
    traj = dv.simulate(_oscillator(), [1.0], [0.0], dt=dt, steps=round(horizon / dt),
                       discretization=rule)  # fmt: skip
    return float(np.max(np.abs(traj.q[:, 0] - np.cos(traj.t)))), traj


def test_a_registered_two_point_rule_runs_and_has_its_order(theta_rules):
    half, quarter = theta_rules
    assert half in dv.discretization.rules.rule_names()
    # θ = ½ is the midpoint rule written another way: the same run to round-off
    _, theta_run = _error(half, 0.05)
    mid = dv.simulate(_oscillator(), [1.0], [0.0], dt=0.05, steps=40, discretization="midpoint")
    np.testing.assert_allclose(theta_run.q, mid.q, rtol=0, atol=1e-12)
    # against cos t: order 2 for θ = ½, order 1 for θ = ¼ (log-log slope of the error)
    for name, order in ((half, 2.0), (quarter, 1.0)):
        coarse, _ = _error(name, 0.04)
        fine, _ = _error(name, 0.02)
        slope = np.log2(coarse / fine)
        assert abs(slope - order) < 0.15, (name, slope)


def test_registering_a_name_twice_or_a_non_rule_is_refused(theta_rules):
    class Other(_Theta):
        pass

    with pytest.raises(dv.ModelError, match="registered already"):
        register_rule(Other)
    with pytest.raises(dv.ModelError, match="QuadratureRule"):
        register_rule(object)
    with pytest.raises(dv.ModelError, match="built-in"):
        unregister_rule("midpoint")
