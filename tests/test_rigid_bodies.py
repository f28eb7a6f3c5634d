"""Rigid bodies in director form, joints between frames, and their references.

Fast: the director kinetic energy is Euler's ``½ m|v_c|² + ½ Ω·JΩ``; the torque covector
does the torque's work; each joint's rows vanish on the motions it allows, not on the
ones it forbids, and are independent; bad input is refused by name. Slow (each compiles a
12- to 60-coordinate step): a free body against Euler's equations by SciPy (orthonormality,
angular momentum and energy to round-off; order 2), the heavy top against the
Euler–Poisson equations (order 2), the spatial double pendulum against MuJoCo (order 2)
and torn ≡ monolithic.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg

import diracvi as dv
from _kkt import constrained_accelerations
from conftest import loglog_slope
from diracvi.components import Multibody, RigidBody
from diracvi.components.joints import JOINTS
from diracvi.components.rigid_body import angular_momentum
from diracvi.errors import ModelError
from diracvi.problems.rigid_bodies import (
    LINKS,
    _turned,
    euler_solution,
    free_rigid_body,
    heavy_top,
    spatial_double_pendulum,
)

MIDPOINT = {"discretization": "midpoint", "solver": dv.NewtonSolver()}


def _random_rotation(rng):
    return _turned(rng.normal(size=3))


# -- the model, without stepping -----------------------------------------------------------
def test_director_kinetic_energy_is_eulers(rng):
    """½ tr(Ẏᵀ M̄ Ẏ) = ½ m |v_c|² + ½ Ω·JΩ for any pose, ω and centre of mass."""
    a = rng.normal(size=(3, 3))
    j = a @ a.T + 3.0 * np.eye(3)  # symmetric, dominant diagonal: a physical tensor
    c = rng.normal(size=3)
    body = RigidBody(1.7, j, name="b", com=c)
    r, w, v = _random_rotation(rng), rng.normal(size=3), rng.normal(size=3)
    q, qd = body.state(rng.normal(size=3), r, v, w)
    kinetic = float(body.inertial(jnp.asarray(q), jnp.asarray(qd)))
    omega_body = r.T @ w
    v_com = v + np.cross(w, r @ c)
    expected = 0.5 * 1.7 * v_com @ v_com + 0.5 * omega_body @ j @ omega_body
    assert kinetic == pytest.approx(expected, rel=1e-13)


def test_loads_do_the_work_of_a_force_and_a_torque(rng):
    """The covector of a force f at X and a torque τ pairs with ḋᵢ = ω × dᵢ, ẋ to
    f·(ẋ + ω × RX) + τ·ω (the power of the loads)."""
    f, tau, at = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    body = RigidBody(1.0, (2.0, 3.0, 4.0), name="b", force=f, torque=tau, force_at=at)
    r, w, v = _random_rotation(rng), rng.normal(size=3), rng.normal(size=3)
    q, qd = body.state(rng.normal(size=3), r, v, w)
    cov = np.asarray(body.loads(jnp.asarray(q), jnp.asarray(qd), 0.0))
    assert cov @ qd == pytest.approx(f @ (v + np.cross(w, r @ at)) + tau @ w, rel=1e-13)


#: motions each joint allows (b's pose relative to a), and one it forbids
ALLOWED = {
    "spherical": [("turn", (0.3, -0.2, 0.5))],
    "revolute": [("turn", (0.0, 0.0, 0.7))],
    "universal": [("turn", (0.4, 0.0, 0.0)), ("turn_b", (0.0, 0.5, 0.0))],
    "cylindrical": [("turn", (0.0, 0.0, 0.7)), ("slide", (0.0, 0.0, 0.3))],
    "prismatic": [("slide", (0.0, 0.0, 0.3))],
    "fixed": [],
}
FORBIDDEN = {
    "spherical": ("slide", (0.1, 0.0, 0.0)),
    "revolute": ("turn", (0.2, 0.0, 0.0)),
    "universal": ("turn", (0.0, 0.0, 0.3)),
    "cylindrical": ("slide", (0.1, 0.0, 0.0)),
    "prismatic": ("turn", (0.0, 0.0, 0.3)),
    "fixed": ("turn", (0.0, 0.0, 0.1)),
}


def _pair(motion, amount, base):
    ra, ea = np.array([0.2, -0.1, 0.4]), base
    rb, eb = ra.copy(), base.copy()
    if motion == "turn":  # b turned about a's axes
        eb = ea @ _turned(amount)
    elif motion == "turn_b":  # about b's own axes after a's first-axis turn
        eb = ea @ _turned((0.4, 0.0, 0.0)) @ _turned(amount)
    else:
        rb = ra + ea @ np.asarray(amount)
    return ra, ea, rb, eb


@pytest.mark.parametrize("kind", sorted(JOINTS))
def test_joint_rows_allow_exactly_their_motions(kind, rng):
    fn, names = JOINTS[kind]
    base = _random_rotation(rng)
    aligned = np.asarray(fn(*_pair("turn", (0.0, 0.0, 0.0), base)))
    assert aligned.shape == (len(names),) and np.max(np.abs(aligned)) < 1e-15
    for motion, amount in ALLOWED[kind]:
        assert np.max(np.abs(np.asarray(fn(*_pair(motion, amount, base))))) < 1e-14, motion
    assert np.max(np.abs(np.asarray(fn(*_pair(*FORBIDDEN[kind], base))))) > 1e-3
    # independent rows: the Jacobian over b's pose (r, E) has full row rank when aligned
    ra, ea, rb, eb = _pair("turn", (0.0, 0.0, 0.0), base)
    jac = jax.jacfwd(lambda y: fn(ra, ea, y[:3], y[3:].reshape(3, 3)))(
        jnp.concatenate([rb, eb.reshape(9)])
    )
    # rotations of b: δE = Ŵ E; the rows' rank over (δr, W) is the joint's constraint count
    basis = [np.concatenate([np.eye(3)[i], np.zeros(9)]) for i in range(3)]
    for i in range(3):
        w = np.zeros((3, 3))
        w[[2, 0, 1][i], [1, 2, 0][i]], w[[1, 2, 0][i], [2, 0, 1][i]] = 1.0, -1.0
        basis.append(np.concatenate([np.zeros(3), (w @ eb).reshape(9)]))
    assert np.linalg.matrix_rank(np.asarray(jac) @ np.array(basis).T, tol=1e-12) == len(names)


def test_orthonormality_rows_are_exact_to_twice_the_working_precision(rng):
    """The six rows ``dᵢ·dⱼ − δᵢⱼ`` against exact rational arithmetic: within 1e-30
    (rounded plainly they are off by ~1e-16, with a bias that drifts a long run's angular
    momentum); their Jacobian is the plain ``∂(DDᵀ)``."""
    from fractions import Fraction

    from diracvi.components._gram import GRAM_PAIRS, gram_rows

    d = np.stack([_random_rotation(rng).T for _ in range(50)])
    got = np.asarray(jax.jit(gram_rows)(jnp.asarray(d)))
    worst = 0.0
    for b in range(len(d)):
        for row, (i, j) in enumerate(zip(*GRAM_PAIRS, strict=True)):
            exact = sum(Fraction(d[b, i, a]) * Fraction(d[b, j, a]) for a in range(3))
            exact -= int(i == j)
            worst = max(worst, abs(float(Fraction(got[b, row]) - exact)))
    assert worst < 1e-30
    jac = jax.jacfwd(gram_rows)(jnp.asarray(d[0]))
    plain = jax.jacfwd(lambda x: (x @ x.T)[GRAM_PAIRS])(jnp.asarray(d[0]))
    assert np.array_equal(np.asarray(jac), np.asarray(plain))


def test_torn_and_monolithic_builds_share_body_coordinates():
    mono = spatial_double_pendulum()
    torn = spatial_double_pendulum(torn=True)
    assert mono.system.n == 24 and torn.system.n == 24 + 12 + 24  # copies at both joints
    np.testing.assert_array_equal(torn.q0[:24], mono.q0)
    np.testing.assert_array_equal(torn.p0[:24], mono.p0)


def test_bad_inertia_is_refused_with_the_triangle_inequality():
    with pytest.raises(ModelError, match=r"Jᵢ < Jⱼ \+ Jₖ"):
        RigidBody(1.0, (1.0, 2.0, 3.0), name="plate")
    with pytest.raises(ModelError, match="mass"):
        RigidBody(-1.0, (2.0, 3.0, 4.0), name="b")


def test_bad_orientation_is_refused():
    body = RigidBody(1.0, (2.0, 3.0, 4.0), name="b")
    with pytest.raises(ModelError, match="orientation is not a rotation"):
        body.state(orientation=np.diag([1.0, 1.0, -1.0]))


def test_inconsistent_joint_names_the_joint_and_its_rows():
    mb = Multibody("m")
    mb.add(RigidBody(1.0, (2.0, 3.0, 4.0), name="b", frames={"tip": (0.0, 0.0, 1.0)}))
    mb.joint("revolute", "b.tip", "world", name="hinge")
    with pytest.raises(ModelError, match=r"joint 'hinge' \(revolute\): rows \{'dz': -1\.0\}"):
        mb.build()


def test_unknown_frame_and_joint_kind():
    mb = Multibody("m")
    mb.add(RigidBody(1.0, (2.0, 3.0, 4.0), name="b"))
    with pytest.raises(ModelError, match="has no frame 'tip'"):
        mb.joint("spherical", "b.tip", "world")
    with pytest.raises(ModelError, match="names no body or world frame"):
        mb.joint("spherical", "c.origin", "world")
    with pytest.raises(ModelError, match="joint kind='hinge' is unknown"):
        mb.joint("hinge", "b.origin", "world")


def test_double_pendulum_forward_dynamics_is_mujocos():
    """The director model's constrained accelerations at the initial state against MuJoCo's
    forward dynamics: the ball joint's body-axis angular acceleration ``R₁ᵀ ω̇₁`` and the
    hinge's ``(ω̇₂ − ω̇₁)·a`` (``ω̇ = ½ Σ dᵢ × d̈ᵢ``) to 1e-10 — the model, with no step."""
    pytest.importorskip("mujoco")
    from _mujoco_pendulum import mujoco_accelerations

    r0, omega0, rate = _turned((0.6, 0.2, 0.0)), np.array([0.3, -0.4, 1.0]), 2.0
    prob = spatial_double_pendulum(rotvec0=(0.6, 0.2, 0.0), omega0=omega0, hinge_rate=rate)
    model = prob.system
    # velocities from the momenta: p = (M̄ ⊗ I₃) v per body
    links = [RigidBody(m, j, name=f"l{i}") for i, (m, j, _, _) in enumerate(LINKS)]
    mass = scipy.linalg.block_diag(*(np.kron(b.mbar, np.eye(3)) for b in links))
    v0 = np.linalg.solve(mass, prob.p0)
    acc = constrained_accelerations(model, prob.q0, v0, mass)

    def omega_dot(i):
        d = prob.q0[12 * i + 3 : 12 * i + 12].reshape(3, 3)
        return 0.5 * np.cross(d, acc[12 * i + 3 : 12 * i + 12].reshape(3, 3)).sum(axis=0)

    hinge_axis = r0 @ np.array([1.0, 0.0, 0.0])
    ours = np.concatenate([r0.T @ omega_dot(0), [(omega_dot(1) - omega_dot(0)) @ hinge_axis]])
    theirs = mujoco_accelerations(r0, omega0, rate)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-10 * np.max(np.abs(theirs)))


# -- dynamics against references ------------------------------------------------------------
def _body_omega(q, p, inertia):
    """Ω_k = J⁻¹ R_kᵀ L_k with L = Σ dᵢ × p_{dᵢ} (the exact relation at the nodes)."""
    r = np.swapaxes(q[:, 3:12].reshape(-1, 3, 3), 1, 2)
    ang = angular_momentum(np.concatenate([0 * q[:, :3], q[:, 3:12]], 1), p[:, :12])
    return np.einsum("ij,kmj,km->ki", np.linalg.inv(inertia), r, ang)


def _free_body_invariants(rule):
    """The free body over 10⁴ steps of 0.01 under ``rule``: ``(problem, trajectory,
    max ‖DDᵀ − I‖, max |L − L₀| / |L₀|)``."""
    prob = free_rigid_body(dt=0.01, steps=10_000)
    traj = dv.simulate(prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps, **rule)
    d = traj.q[:, 3:12].reshape(-1, 3, 3)
    ang = angular_momentum(traj.q, traj.p)
    orth = np.max(np.abs(d @ np.swapaxes(d, 1, 2) - np.eye(3)))
    return prob, traj, orth, np.max(np.abs(ang - ang[0])) / np.linalg.norm(ang[0])


@pytest.mark.slow
def test_free_body_conserves_and_matches_eulers_equations():
    """10⁴ steps: ‖RᵀR − I‖ ≤ 1e-13, |L| to 1e-12 relative, energy band ≤ 1e-12 relative
    with no trend; body Ω against SciPy's Euler solution at order 2."""
    prob, traj, orth, drift = _free_body_invariants(MIDPOINT)
    assert orth < 1e-13
    assert drift < 1e-12
    energy = traj.energy
    assert np.ptp(energy) < 1e-12 * abs(energy[0])

    inertia = np.diag(prob.parameters["J"])
    errors, hs = [], [0.02, 0.01, 0.005]
    for h in hs:
        p = free_rigid_body(dt=h, steps=round(4.0 / h))
        tr = dv.simulate(p.system, p.q0, p.p0, dt=h, steps=p.steps, **MIDPOINT)
        omega0 = np.array(p.parameters["Omega0"])
        ref_omega, _ = euler_solution(inertia, omega0, _turned((0.3, -0.2, 0.5)), tr.t)
        errors.append(np.max(np.abs(_body_omega(tr.q, tr.p, inertia) - ref_omega)))
    assert loglog_slope(hs, errors) == pytest.approx(2.0, abs=0.05)
    assert errors[-1] < 1e-3


@pytest.mark.slow
def test_free_body_momentum_holds_over_a_hundred_thousand_steps():
    """10⁵ steps of 0.01: the spatial angular momentum within 1e-13 relative (measured
    1.7e-14; 8.9e-13 when the momentum line carried the positions' rounding and the
    orthonormality rows were rounded plainly, 1.4e-13 with the first fixed alone);
    ‖RᵀR − I‖ at round-off."""
    prob = free_rigid_body(dt=0.01, steps=100_000)
    traj = dv.simulate(
        prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps, save_every=100, **MIDPOINT
    )
    ang = angular_momentum(traj.q, traj.p)
    assert np.max(np.linalg.norm(ang - ang[0], axis=1)) < 1e-13 * np.linalg.norm(ang[0])
    d = traj.q[:, 3:12].reshape(-1, 3, 3)
    assert np.max(np.abs(d @ np.swapaxes(d, 1, 2) - np.eye(3))) < 1e-15


@pytest.mark.slow
def test_heavy_top_precesses_and_nutates_as_euler_poisson():
    """The top's directors against the Euler–Poisson reference: order 2 (midpoint)."""
    hs, errors = [0.004, 0.002, 0.001], []
    for h in hs:
        prob = heavy_top(dt=h, steps=round(0.4 / h), spin=5.0)
        tr = dv.simulate(prob.system, prob.q0, prob.p0, dt=h, steps=prob.steps, **MIDPOINT)
        errors.append(np.max(np.abs(tr.q[:, :12] - prob.numerical_solution(tr.t))))
        pin = tr.q[:, :3]
        assert np.max(np.abs(pin)) < 1e-13  # the spherical joint holds to round-off
    assert loglog_slope(hs, errors) == pytest.approx(2.0, abs=0.05)
    assert errors[-1] < 2e-5


@pytest.mark.slow
def test_spatial_double_pendulum_against_mujoco():
    """Both links' centres of mass after 1 s against MuJoCo (RK4, 1e-4 s): order 2."""
    pytest.importorskip("mujoco")
    from _mujoco_pendulum import centre_errors

    hs = [0.01, 0.005, 0.0025]
    errors = centre_errors(hs, "midpoint")
    assert loglog_slope(hs, errors) == pytest.approx(2.0, abs=0.05)
    assert errors[-1] < 1e-5


@pytest.mark.slow
def test_torn_double_pendulum_is_the_monolithic_one():
    """One subsystem per body and joint ≡ the monolithic system to 1e-12, joints and
    orthonormality held to round-off in both."""
    runs = []
    for torn in (False, True):
        prob = spatial_double_pendulum(torn=torn, dt=0.01, steps=300)
        tr = dv.simulate(prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps, **MIDPOINT)
        runs.append(tr.q[:, :24])
        g = jax.vmap(prob.system.position_constraints)(jnp.asarray(tr.q))
        assert np.max(np.abs(np.asarray(g))) < 1e-12
    assert np.max(np.abs(runs[0] - runs[1])) < 1e-12


def _loaded_body(h, steps):
    """A free body under a time-dependent force at its centre of mass and torque."""
    body = RigidBody(
        1.5,
        (2.0, 3.0, 4.0),
        name="b",
        force=lambda t: jnp.stack([jnp.sin(t), 0.5 + 0.0 * t, -jnp.cos(2.0 * t)]),
        torque=lambda t: jnp.stack([0.3 * jnp.cos(t), 0.2 + 0.0 * t, 0.4 * jnp.sin(3.0 * t)]),
    )
    mb = Multibody("loaded")
    mb.add(body, orientation=_turned((0.3, -0.2, 0.5)), omega=(0.5, 1.0, -0.3))
    model = mb.build()
    return dv.simulate(model.system, model.q0, model.p0, dt=h, steps=steps, **MIDPOINT)


@pytest.mark.slow
def test_applied_force_and_torque_change_the_momenta_by_their_impulses():
    """Linear momentum ``m ẋ`` and angular momentum about the centre of mass change by
    ``∫ f dt`` and ``∫ τ dt`` (closed forms): order 2, 1e-5 at h = 0.0025."""
    end = 2.0
    impulse_f = np.array([1.0 - np.cos(end), 0.5 * end, -np.sin(2.0 * end) / 2.0])
    impulse_t = np.array([0.3 * np.sin(end), 0.2 * end, 0.4 * (1.0 - np.cos(3.0 * end)) / 3.0])
    hs, errors = [0.01, 0.005, 0.0025], []
    for h in hs:
        tr = _loaded_body(h, round(end / h))
        q, p = tr.q, tr.p
        spin = angular_momentum(np.concatenate([0 * q[:, :3], q[:, 3:]], 1), p)
        errors.append(
            max(
                np.max(np.abs(p[-1, :3] - p[0, :3] - impulse_f)),
                np.max(np.abs(spin[-1] - spin[0] - impulse_t)),
            )
        )
    assert loglog_slope(hs, errors) == pytest.approx(2.0, abs=0.1)
    assert errors[-1] < 1e-5


def _sprung(damping, torn):
    """Two bodies on a spring–damper, the first hung from the world by a spherical joint."""
    g = (0.0, 0.0, -9.81)
    a = RigidBody(1.0, (0.1, 0.1, 0.05), name="a", gravity=g, frames={"top": (0.0, 0.0, 0.3)})
    b = RigidBody(0.5, (0.05, 0.06, 0.04), name="b", gravity=g, frames={"hook": (0.1, 0.0, 0.2)})
    mb = Multibody("sprung")
    mb.add(a, position=(0.0, 0.0, -0.3), omega=(0.0, 1.0, 0.0), velocity=(-0.3, 0.0, 0.0))
    mb.add(b, position=(0.2, 0.1, -1.0), orientation=_turned((0.2, 0.1, 0.0)))
    mb.joint("spherical", "a.top", "world")
    mb.spring("a.origin", "b.hook", stiffness=40.0, rest_length=0.4, damping=damping)
    model = mb.build(torn=torn)
    return dv.simulate(model.system, model.q0, model.p0, dt=0.005, steps=400, **MIDPOINT)


@pytest.mark.slow
def test_spring_damper_dissipates_and_tears():
    """With c = 0 the energy keeps a band of 1e-3 relative; with c > 0 it never rises by more
    than that band in a step and ends far below it; torn ≡ monolithic to 1e-12."""
    free = _sprung(0.0, False).energy
    band = np.ptp(free)
    assert band < 1e-3 * np.max(np.abs(free))
    damped = _sprung(2.0, False)
    assert np.all(np.diff(damped.energy) < band)
    assert damped.energy[-1] < free.min() - 100.0 * band
    torn = _sprung(2.0, True)
    assert np.max(np.abs(torn.q[:, :24] - damped.q)) < 1e-12


def _ry(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _four_joints(torn):
    """Four bodies, each joined to its own world frame by another joint kind: a universal
    pendulum, a cylindrical axle along world x, a prismatic slider on a 45° incline, a
    fixed body; gravity −9.81 e_z; 200 steps of 5 ms."""
    g = (0.0, 0.0, -9.81)
    slope, axle = _ry(np.pi / 4), _ry(np.pi / 2)  # the slider's e₃ up the incline; axle's e₃ = x

    def body(name, frames):
        return RigidBody(1.0, (0.2, 0.3, 0.25), name=name, gravity=g, frames=frames)

    mb = Multibody("four_joints")
    w_u = np.array([0.5, 0.7, 0.0])  # about world x (a's e₁) and the body's y (b's f₂)
    mb.add(
        body("u", {"pivot": (0.0, 0.0, 0.5)}),
        position=(0.0, 0.0, -0.5),
        omega=w_u,
        velocity=np.cross(w_u, [0.0, 0.0, -0.5]),
    )
    mb.add(
        body("c", {"axle": ((0.0, 0.0, 0.3), axle)}),
        position=(2.0, 0.0, -0.3),
        omega=(1.0, 0.0, 0.0),
        velocity=(0.4, 0.3, 0.0),
    )
    mb.add(
        body("p", {"slider": ((0.0, 0.0, 0.0), slope)}),
        position=(4.0, 0.0, 0.0),
        velocity=0.5 * slope[:, 2],
    )
    mb.add(
        body("f", {"weld": (0.0, 0.0, 0.2)}),
        position=(6.0, 0.0, -0.2),
        orientation=_turned((0.1, 0.2, 0.3)),
    )
    mb.joint("universal", mb.world_frame("u"), "u.pivot")
    mb.joint("cylindrical", mb.world_frame("c", (2.0, 0.0, 0.0), axle), "c.axle")
    mb.joint("prismatic", mb.world_frame("p", (4.0, 0.0, 0.0), slope), "p.slider")
    weld = _turned((0.1, 0.2, 0.3))  # the welded body's pose: its frame at the world's
    mb.joint(
        "fixed", mb.world_frame("f", [6.0, 0.0, -0.2] + weld @ [0.0, 0.0, 0.2], weld), "f.weld"
    )
    model = mb.build(torn=torn)
    traj = dv.simulate(model.system, model.q0, model.p0, dt=0.005, steps=200, **MIDPOINT)
    return model, traj


@pytest.mark.slow
def test_universal_cylindrical_prismatic_and_fixed_joints():
    """Every row to 1e-12; the slider slides down the incline as ``s = 0.5 t − g t²/(2√2)``
    and the axle slides at 0.4 (the midpoint rule is exact for constant forces); the welded
    body stays put; energy band 1e-4 relative; torn ≡ monolithic to 1e-12."""
    model, traj = _four_joints(False)
    g = jax.vmap(lambda q: model.system.position_constraints(q, 0.0))(jnp.asarray(traj.q))
    assert np.max(np.abs(np.asarray(g))) < 1e-12
    t = traj.t
    slide = (model.body(traj.q, "p")[:, :3] - [4.0, 0.0, 0.0]) @ _ry(np.pi / 4)[:, 2]
    np.testing.assert_allclose(slide, 0.5 * t - 9.81 * t**2 / (2 * np.sqrt(2)), atol=1e-12)
    np.testing.assert_allclose(
        model.rotation(traj.q, "p"), np.broadcast_to(np.eye(3), (len(t), 3, 3)), atol=1e-12
    )
    np.testing.assert_allclose(model.body(traj.q, "c")[:, 0], 2.0 + 0.4 * t, atol=1e-12)
    np.testing.assert_allclose(
        model.body(traj.q, "f"),
        np.broadcast_to(model.body(model.q0, "f"), (len(t), 12)),
        atol=1e-12,
    )
    assert np.ptp(traj.energy) < 1e-4 * np.max(np.abs(traj.energy))
    _, torn = _four_joints(True)
    assert np.max(np.abs(torn.q[:, :48] - traj.q)) < 1e-12
