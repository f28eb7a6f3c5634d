"""The quadrotor (``components/rotorcraft.py``, ``problems/quadrotor.py``).

Fast: the force port's covector does the virtual work of the thrusts and torques on any
rigid displacement; ``Ω₃`` from the directors is ``d₃·ω``; the closed-form momenta are
``∂L/∂v`` of the system's Lagrangian; the controller's mixing is the plant's wrench and
holds the hover; bad input is refused by name. Slow (each compiles a 12- or
16-coordinate step, 10–40 s): the motion under prescribed inputs against the
Newton–Euler (gyrostat) equations by SciPy's DOP853 at rtol 1e-12 (order 2, ‖RᵀR − I‖
to round-off), the power bookkeeping of the force port (order 2), and ``jax.grad`` of a
tracking loss through ``dv.simulate`` against central differences, with gradient
descent lowering the loss.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi.components import MotorPropeller, RigidBody, rotorcraft
from diracvi.components.rigid_body import angular_velocity
from diracvi.components.rotorcraft import Propellers, momenta, spin_rate
from diracvi.errors import ModelError
from diracvi.problems import quadrotor as Q
from diracvi.problems.rigid_bodies import _turned

RNG = np.random.default_rng(33)


def _state(omega=(0.3, -0.7, 1.1), velocity=(0.2, -0.1, 0.4)):
    body = Q.frame()
    return body.state((0.1, -0.2, 0.3), _turned((0.4, -0.3, 0.8)), velocity, omega)


def _port():
    return Propellers(
        tuple(map(tuple, Q.ARMS.tolist())), tuple(Q.SENSES.tolist()), Q.THRUST, Q.DRAG
    )


def _hover_command(motors):
    value = float(Q.MOTOR.voltage(Q.hover_speed(), Q.DRAG)) if motors else Q.hover_speed() ** 2
    return lambda qf, vf, t: jnp.full(4, value) + 0.0 * t


def test_force_port_does_the_virtual_work_of_thrusts_and_torques():
    q, _ = _state()
    u = np.array([2.0e5, 2.6e5, 1.7e5, 3.1e5])
    port = _port()
    cov = np.asarray(port.frame_force(jnp.asarray(q), jnp.asarray(u)))
    r = q[3:12].reshape(3, 3).T
    for _ in range(3):
        dx, dth = RNG.normal(size=3), RNG.normal(size=3)
        dq = np.concatenate([dx, np.cross(dth, r.T).reshape(9)])
        work = 0.0
        for arm, s, ui in zip(Q.ARMS, Q.SENSES, u, strict=True):
            f = Q.THRUST * ui * r[:, 2]
            work += f @ (dx + np.cross(dth, r @ arm)) - s * Q.DRAG * ui * r[:, 2] @ dth
        assert cov @ dq == pytest.approx(work, rel=1e-13)


def test_spin_rate_is_the_axial_angular_velocity():
    q, v = _state()
    omega = angular_velocity(q, v)
    assert float(spin_rate(jnp.asarray(q), jnp.asarray(v))) == pytest.approx(
        omega @ q[9:12], rel=1e-14
    )


def test_momenta_are_the_lagrangian_gradient():
    system, _, _ = Q.quadrotor(_hover_command(True), motors=True)
    qf, vf = _state()
    q = np.concatenate([qf, RNG.normal(size=4)])
    v = np.concatenate([vf, 480.0 + 30.0 * RNG.normal(size=4)])
    p = momenta(Q.frame(), Q.SENSES, Q.MOTOR, q, v)
    ref = jax.grad(lambda w: system.lagrangian(jnp.asarray(q), w, 0.0))(jnp.asarray(v))
    np.testing.assert_allclose(p, np.asarray(ref), rtol=1e-13, atol=1e-15)


def test_controller_mixing_is_the_plants_wrench_and_holds_the_hover():
    thrusts = np.array([2.1, 2.7, 2.3, 2.5])
    port = _port()
    qf, _ = Q.frame().state()  # level: body and world axes agree
    cov = np.asarray(port.frame_force(jnp.asarray(qf), jnp.asarray(thrusts / Q.THRUST)))
    # at R = I the directors' rows of a torque τ are ½ τ × eⱼ: read M back from them
    d = cov[3:12].reshape(3, 3)
    moment = np.sum(np.cross(np.eye(3), d), axis=0)  # Σ eⱼ × (½ τ × eⱼ + Xⱼ f) = τ + Σ X × f
    np.testing.assert_allclose(Q.MIXING @ thrusts, np.r_[cov[2], moment], rtol=1e-13, atol=1e-15)
    for motors, expect in ((False, Q.hover_speed() ** 2), (True, None)):
        command = Q.geometric_controller(Q.GAINS, (0.0, 0.0, 0.0), motors=motors)
        out = np.asarray(command(jnp.asarray(qf), jnp.zeros(12), 0.0))
        if expect is None:
            expect = float(Q.MOTOR.voltage(Q.hover_speed(), Q.DRAG))
        np.testing.assert_allclose(out, expect, rtol=1e-12)


def test_bad_input_is_refused_by_name():
    body, cmd = Q.frame(), _hover_command(False)
    args = (Q.ARMS, Q.SENSES, Q.THRUST, Q.DRAG, cmd)
    with pytest.raises(ModelError, match="senses"):
        rotorcraft(body, Q.ARMS, (1, -1, 1, 0.5), Q.THRUST, Q.DRAG, cmd)
    with pytest.raises(ModelError, match="arms"):
        rotorcraft(body, np.zeros((4, 2)), Q.SENSES, Q.THRUST, Q.DRAG, cmd)
    with pytest.raises(ModelError, match="thrust"):
        rotorcraft(body, Q.ARMS, Q.SENSES, -1.0, Q.DRAG, cmd)
    with pytest.raises(ModelError, match=r"shape \(4,\)"):
        rotorcraft(body, Q.ARMS, Q.SENSES, Q.THRUST, Q.DRAG, lambda q, v, t: jnp.zeros(3))
    loaded = RigidBody(1.0, (0.01, 0.01, 0.018), name="f", torque=(0.0, 0.0, 1.0))
    with pytest.raises(ModelError, match="own applied loads"):
        rotorcraft(loaded, *args)
    with pytest.raises(ModelError, match="resistance"):
        MotorPropeller(3e-5, 0.01, 0.0)


# -- slow: runs -----------------------------------------------------------------------

AMP, FREQ = np.array([0.05, -0.03, 0.04, 0.02]), np.array([3.0, 5.0, 7.0, 2.0])


def _prescribed(motors):
    base = float(Q.MOTOR.voltage(Q.hover_speed(), Q.DRAG)) if motors else Q.hover_speed() ** 2

    def jax_inputs(qf, vf, t):
        return base * (1.0 + jnp.asarray(AMP) * jnp.sin(jnp.asarray(FREQ) * t))

    return jax_inputs, lambda t: base * (1.0 + AMP * np.sin(FREQ * t))


def _energy_closure(system, traj, h):
    """``(E_end − E_start) − Σ (trapezoid of the steps' works h F(q̄, v)·v)`` and the
    total |work|: the force port's bookkeeping (``traj.energy`` is at the step nodes)."""
    q = np.asarray(traj.q)
    mid, vel = 0.5 * (q[1:] + q[:-1]), np.diff(q, axis=0) / h
    tm = np.asarray(traj.t[:-1]) + 0.5 * h
    force = jax.vmap(system.force)(jnp.asarray(mid), jnp.asarray(vel), jnp.asarray(tm))
    work = h * np.sum(np.asarray(force) * vel, axis=1)
    energy = np.asarray(traj.energy)[1:]  # steps 1 … N (index 0: no step ends there)
    trapezoid = 0.5 * (work[:-1] + work[1:])
    return energy[-1] - energy[0] - np.sum(trapezoid), np.sum(np.abs(work)), work


@pytest.mark.slow
@pytest.mark.parametrize("motors", [False, True])
def test_motion_under_prescribed_inputs_matches_newton_euler(motors):
    jax_inputs, np_inputs = _prescribed(motors)
    system, q0, p0 = Q.quadrotor(jax_inputs, motors=motors)
    errors, closures = [], []
    for h in (0.01, 0.005):
        traj = dv.simulate(
            system,
            q0,
            p0,
            dt=h,
            steps=round(1.0 / h),
            discretization="midpoint",
            solver=dv.NewtonSolver(rtol=1e-16),
        )
        q = np.asarray(traj.q)
        x, r, rates = Q.newton_euler(np_inputs, np.asarray(traj.t), motors=motors)
        rot = np.swapaxes(q[:, 3:12].reshape(-1, 3, 3), 1, 2)
        err = max(np.max(np.abs(q[:, :3] - x)), np.max(np.abs(rot - r)))
        if motors:  # the rotors' speeds at the steps' midpoints
            mid = 0.5 * (rates[1:] + rates[:-1])
            err = max(err, np.max(np.abs(np.diff(q[:, 12:], axis=0) / h - mid)) / Q.hover_speed())
        errors.append(err)
        # a rotor turns ~5 rad per step, and Newton's test is relative to the step's
        # largest increment: rtol=1e-16 holds the frame's rows at ~1e-14 (2e-16 without
        # rotors; the default test 1.4e-12 and 3.3e-15)
        orth = np.max(np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3)))
        assert orth < (5e-14 if motors else 1e-15), orth
        gap, total, work = _energy_closure(system, traj, h)
        closures.append((gap, total))
        if motors:  # the port's work, step by step, is the documented split of it
            terms = Q.power_terms(q, h, np_inputs)
            scale = np.abs(terms["input"]) + np.abs(terms["rotors"])
            split = sum(terms.values())
            assert np.max(np.abs(split - work) / scale) < 1e-12
            assert np.all(terms["winding"] < 0) and np.all(terms["rotors"] < 0)
    order = np.log2(errors[0] / errors[1])
    assert 1.9 < order < 2.1, (errors, order)
    assert errors[1] < 1e-4
    # the port's bookkeeping closes at the scheme's order (module docs: rigid bodies keep
    # their energy in an O(h²) band, as the constraint reactions act at a step's end)
    (gap0, total0), (gap1, _) = closures
    assert abs(gap1) < 1e-3 * total0
    assert 1.8 < np.log2(abs(gap0) / abs(gap1)) < 2.2, closures


@pytest.mark.slow
def test_gradient_through_simulate_matches_central_differences_and_tunes_the_gains():
    loss = jax.jit(lambda g: Q.tracking_loss(g, dt=0.02, duration=1.0)[0])
    value_and_grad = jax.jit(jax.value_and_grad(lambda g: Q.tracking_loss(g, 0.02, 1.0)[0]))
    theta = jnp.log(jnp.asarray(Q.GAINS))
    value, grad = value_and_grad(theta)
    assert float(value) == pytest.approx(float(loss(theta)), rel=1e-12)
    eps = 1e-5
    for i in range(4):
        fd = (loss(theta.at[i].add(eps)) - loss(theta.at[i].add(-eps))) / (2 * eps)
        assert float(grad[i]) == pytest.approx(float(fd), rel=1e-6), i
    _, history, _ = Q.tune(theta, iterations=4, dt=0.02, duration=1.0)
    assert history[-1] < 0.9 * history[0]
