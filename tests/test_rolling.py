"""Rolling contact of a disk or a ball on a plane: a nonholonomic joint on directors.

Fast: the two rolling one-forms vanish on every rolling motion (any pose, any angular
velocity) and measure the slip of a slipping one; the touching row stays 0 to first order
along rolling; bad contacts and slipping initial velocities are refused by name. Slow: the
upright disk (the same physical disk as :func:`diracvi.problems.rolling_disk`) follows the
closed-form circle at order 2, agrees with the generalized-coordinate model to the
scheme's order, keeps its energy and its constraints to round-off, and tears; a Chaplygin
ball keeps its angular momentum about the contact point to round-off and its energy to
order 2.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope
from diracvi.components import Multibody, RigidBody
from diracvi.components.rolling import contact_offset, contact_rows, rolling_forms
from diracvi.errors import ModelError
from diracvi.problems import rolling_disk
from diracvi.problems.rigid_bodies import _turned

MIDPOINT = {"discretization": "midpoint", "solver": dv.NewtonSolver()}
PLANE = np.eye(3)  # the world plane z = 0, normal +z


def _touching(shape, radius, rotation, frame_point, frame_axes):
    """Body coordinates ``q`` with the contact on the plane z = 0 at the origin."""
    ea = jnp.asarray(rotation @ frame_axes)
    centre = -np.asarray(contact_offset(shape, radius, ea, jnp.asarray(PLANE)))
    x = centre - rotation @ frame_point
    return np.concatenate([x, rotation.T.reshape(9)]), centre


@pytest.mark.parametrize("shape", ["disk", "ball"])
def test_rolling_forms_vanish_on_rolling_and_measure_slip(shape, rng):
    """For any tilted pose and angular velocity ω, the director velocity of rolling
    (``ẋ_c = −ω × s``, ``ḋᵢ = ω × dᵢ``) is annihilated by the two one-forms and keeps the
    touching row at 0 to first order; adding a slip ``w`` in the plane gives ``A q̇ = w``."""
    radius, point, axes = 0.3, rng.normal(size=3), _turned(rng.normal(size=3))
    rot = _turned(rng.normal(size=3))
    q, _ = _touching(shape, radius, rot, point, axes)
    rows, _ = contact_rows(shape, radius, upright=False)

    def touch(y):
        d = y[3:12].reshape(3, 3).T
        return rows(y[0:3] + d @ point, d @ axes, jnp.zeros(3), jnp.asarray(PLANE))

    @jax.jit
    def check(q, qdot):  # the one-forms, the touching row and its rate, in one program
        forms = rolling_forms(shape, radius, point, axes, q, jnp.asarray(PLANE))
        return forms, touch(q), jax.jvp(touch, (q,), (qdot,))[1]

    s = np.asarray(contact_offset(shape, radius, jnp.asarray(rot @ axes), jnp.asarray(PLANE)))
    assert s[2] < 0.0  # the contact is below the centre
    for _ in range(5):
        omega = rng.normal(size=3)
        v_centre = -np.cross(omega, s)
        v_ref = v_centre - np.cross(omega, rot @ point)  # the reference point x
        qdot = np.concatenate([v_ref, np.cross(omega, rot.T).reshape(9)])
        forms, height, rate = (np.asarray(x) for x in check(jnp.asarray(q), jnp.asarray(qdot)))
        assert np.max(np.abs(forms @ qdot)) < 1e-14
        assert np.max(np.abs(height)) < 1e-15 and np.max(np.abs(rate)) < 1e-14
        slip = np.array([rng.normal(), rng.normal(), 0.0])
        slipping = qdot + np.concatenate([slip, np.zeros(9)])
        np.testing.assert_allclose(forms @ slipping, slip[:2], atol=1e-14)


def _disk_body(prob):
    par = prob.parameters
    return RigidBody(par["m"], (par["J"], par["J"], par["I"]), name="disk", gravity=(0, 0, -9.81))


def _upright_disk(prob, torn=False, slip=0.0):
    r"""The disk of ``prob`` (a :func:`rolling_disk`) as a rigid body: axis ``d₃``
    horizontal, ``d₁`` the heading ``(cos φ₀, sin φ₀, 0)``, ``ω = Ω â + ω_turn e_z``."""
    par, phi = prob.parameters, prob.q0[3]
    heading = np.array([np.cos(phi), np.sin(phi), 0.0])
    axle = np.array([-np.sin(phi), np.cos(phi), 0.0])
    mb = Multibody("disk")
    mb.add(
        _disk_body(prob),
        position=(0.0, 0.0, par["R"]),
        orientation=np.column_stack([heading, [0.0, 0.0, -1.0], axle]),
        omega=par["Omega"] * axle + par["omega"] * np.array([0.0, 0.0, 1.0]),
        velocity=par["R"] * par["Omega"] * heading + slip * axle,
    )
    mb.rolling("disk.origin", par["R"], upright=True, name="contact")
    return mb.build(torn=torn)


def _slip(traj, shape, radius):
    """``max |A(q̄) (q_{k+1} − q_k)| / h``: the discrete rolling rows of every step (the
    body's coordinates first in ``q``; its frame at the reference point)."""
    q = jnp.asarray(traj.q[:, :12])
    mid, dq = 0.5 * (q[1:] + q[:-1]), q[1:] - q[:-1]
    forms = jax.vmap(lambda y: rolling_forms(shape, radius, np.zeros(3), np.eye(3), y, PLANE))
    return float(jnp.max(jnp.abs(jnp.einsum("kij,kj->ki", forms(mid), dq)))) / traj.dt


def test_slipping_start_and_bad_contacts_are_refused():
    prob = rolling_disk(inertia_turn=0.3)
    with pytest.raises(ModelError, match=r"joint 'contact' \(rolling\): the initial velocities"):
        _upright_disk(prob, slip=0.1)
    mb = Multibody("m")
    mb.add(_disk_body(prob))
    with pytest.raises(ModelError, match=r"radius=-1 must be a finite number > 0"):
        mb.rolling("disk.origin", -1)
    with pytest.raises(ModelError, match=r"upright=True is for a disk"):
        mb.rolling("disk.origin", 1.0, shape="ball", upright=True)
    with pytest.raises(ModelError, match=r"plane='floor' is not a world frame"):
        mb.rolling("disk.origin", 1.0, plane="floor")
    mb.rolling("disk.origin", 1.0, shape="ball", name="c")
    with pytest.raises(ModelError, match=r"joint 'c' \(rolling\): rows \{'touch': -1\.0\}"):
        mb.build()  # the ball's centre is on the plane: it does not touch


@pytest.mark.slow
def test_upright_disk_rolls_on_the_closed_form_circle():
    """The upright disk's contact point against the circle ``R Ω/ω`` (Bloch §1.4): order 2;
    the same disk in generalized coordinates (:func:`rolling_disk`) agrees to the scheme's
    order; energy band ≤ 1e-12 relative; touching, upright and orthonormality rows ≤ 1e-13;
    torn into body + contact ≡ monolithic to 1e-12."""
    prob = rolling_disk(inertia_turn=0.3)  # I = 0.5 about the axle, J = 0.3 about a diameter
    model = _upright_disk(prob)
    hs, errors, gaps = [0.02, 0.01, 0.005], [], []
    for h in hs:
        steps = round(2.0 / h)
        traj = dv.simulate(model.system, model.q0, model.p0, dt=h, steps=steps, **MIDPOINT)
        exact = prob.exact(traj.t)[:, :2]
        errors.append(np.max(np.abs(traj.q[:, :2] - exact)))  # centre above the contact
        gen = dv.simulate(prob.system, prob.q0, prob.p0, dt=h, steps=steps, **MIDPOINT)
        gaps.append(np.max(np.abs(traj.q[:, :2] - gen.q[:, :2])))
        assert np.ptp(traj.energy) < 1e-12 * abs(traj.energy[0])
        g = jax.vmap(model.system.position_constraints)(jnp.asarray(traj.q))
        assert np.max(np.abs(np.asarray(g))) < 1e-13
        assert _slip(traj, "disk", prob.parameters["R"]) < 1e-12
    assert loglog_slope(hs, errors) == pytest.approx(2.0, abs=0.05)
    assert loglog_slope(hs, gaps) == pytest.approx(2.0, abs=0.1)
    torn = _upright_disk(prob, torn=True)
    tr = dv.simulate(torn.system, torn.q0, torn.p0, dt=0.01, steps=200, **MIDPOINT)
    mono = dv.simulate(model.system, model.q0, model.p0, dt=0.01, steps=200, **MIDPOINT)
    assert np.max(np.abs(tr.q[:, :12] - mono.q)) < 1e-12


def _chaplygin_ball(h, steps):
    """A ball of radius 0.5 with its centre of mass at the centre and three different
    principal moments, rolling and spinning on the plane under gravity."""
    radius, mass = 0.5, 2.0
    ball = RigidBody(mass, (0.2, 0.25, 0.3), name="ball", gravity=(0.0, 0.0, -9.81))
    mb = Multibody("ball")
    omega = np.array([1.5, -0.7, 2.0])
    mb.add(
        ball,
        position=(0.0, 0.0, radius),
        orientation=_turned((0.4, -0.3, 0.2)),
        omega=omega,
        velocity=radius * np.cross(omega, [0.0, 0.0, 1.0]),
    )
    mb.rolling("ball.origin", radius, shape="ball")
    model = mb.build()
    traj = dv.simulate(model.system, model.q0, model.p0, dt=h, steps=steps, **MIDPOINT)
    return model, traj, radius


@pytest.mark.slow
def test_chaplygin_ball_keeps_energy_and_momentum_about_the_contact():
    r"""A rolling Chaplygin ball conserves its energy and its angular momentum about the
    contact point ``K = Σ dᵢ × p_{dᵢ} + ρ n × p_x`` (gravity and the contact force act on
    the vertical through it). Over 4 s: the midpoint steps keep ``K`` to round-off
    (≤ 1e-12 relative: a discrete conservation law), the height and orthonormality rows to
    1e-13, and the energy in a band that falls at order 2, with no trend."""
    bands, hs = [], [0.02, 0.01, 0.005]
    for h in hs:
        model, traj, radius = _chaplygin_ball(h, round(4.0 / h))
        q, p = traj.q, traj.p
        spin = np.cross(q[:, 3:12].reshape(-1, 3, 3), p[:, 3:12].reshape(-1, 3, 3)).sum(axis=1)
        k = spin + radius * np.cross([0.0, 0.0, 1.0], p[:, 0:3])
        assert np.max(np.linalg.norm(k - k[0], axis=1)) < 1e-12 * np.linalg.norm(k[0])
        g = jax.vmap(model.system.position_constraints)(jnp.asarray(q))
        assert np.max(np.abs(np.asarray(g))) < 1e-13
        assert _slip(traj, "ball", radius) < 1e-12
        energy = traj.energy
        bands.append(np.ptp(energy) / abs(energy[0]))
        half = len(energy) // 2
        assert abs(np.mean(energy[half:]) - np.mean(energy[:half])) < 0.25 * np.ptp(energy)
    assert loglog_slope(hs, bands) == pytest.approx(2.0, abs=0.1)
    assert bands[-1] < 3e-6


def _tilted_disk(h, steps, tilt=0.3):
    """A thick disk (radius 0.5, moments 0.07 about a diameter, 0.125 about its axis)
    tilted by ``tilt`` from the vertical plane, spinning at 12 rad/s about its axis and
    turning at 1 rad/s, free to lean (no upright row) under gravity."""
    radius, c, s = 0.5, np.cos(tilt), np.sin(tilt)
    rot = np.column_stack([[1.0, 0.0, 0.0], [0.0, s, -c], [0.0, c, s]])  # d₃ = axis
    _, centre = _touching("disk", radius, rot, np.zeros(3), np.eye(3))
    axis = rot[:, 2]
    omega = 12.0 * axis + np.array([0.0, 0.0, 1.0])
    offset = -centre  # the contact is at the origin: s = −centre
    mb = Multibody("tilted")
    disk = RigidBody(1.0, (0.07, 0.07, 0.125), name="disk", gravity=(0.0, 0.0, -9.81))
    mb.add(disk, position=centre, orientation=rot, omega=omega, velocity=-np.cross(omega, offset))
    mb.rolling("disk.origin", radius)
    model = mb.build()
    traj = dv.simulate(model.system, model.q0, model.p0, dt=h, steps=steps, **MIDPOINT)
    return model, traj, radius


@pytest.mark.slow
def test_leaning_disk_rolls_without_slip_and_keeps_its_energy():
    """A spinning disk leaning 0.3 rad rolls and precesses for 2 s without falling: the
    touching and orthonormality rows ≤ 1e-13, the discrete rolling rows ≤ 1e-12, the
    energy band falling at order 2 with no trend."""
    bands, hs = [], [0.01, 0.005]
    for h in hs:
        model, traj, radius = _tilted_disk(h, round(2.0 / h))
        g = jax.vmap(model.system.position_constraints)(jnp.asarray(traj.q))
        assert np.max(np.abs(np.asarray(g))) < 1e-13
        assert _slip(traj, "disk", radius) < 1e-12
        lean = np.arcsin(np.abs(traj.q[:, 11]))  # n·â = d₃z
        assert np.max(lean) < 1.0  # it does not fall
        energy = traj.energy
        bands.append(np.ptp(energy) / abs(energy[0]))
        half = len(energy) // 2
        assert abs(np.mean(energy[half:]) - np.mean(energy[:half])) < 0.25 * np.ptp(energy)
    assert loglog_slope(hs, bands) == pytest.approx(2.0, abs=0.2)
