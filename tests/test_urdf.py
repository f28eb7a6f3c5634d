"""URDF input against MuJoCo, which reads the same file itself.

Fast: the arm's poses, centres of mass and inertias are MuJoCo's; its joint angles come
back from the directors; its accelerations at a state are MuJoCo's forward dynamics (no
step); a prismatic joint likewise; bad files are refused naming the link or joint. Slow:
the joint angles over 2 s against MuJoCo's forward dynamics integrated by DOP853 at
1e-12 — order 2, and 1e-6 at a small step; order 4 under ``"lobatto"``, 1e-6 at h = 0.01.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

import diracvi as dv
from _kkt import constrained_accelerations
from conftest import loglog_slope
from diracvi.components import read_urdf
from diracvi.components.joints import revolute_angle
from diracvi.components.urdf import parse_urdf, rpy_matrix
from diracvi.errors import ModelError

mujoco = pytest.importorskip("mujoco")
from _mujoco_arm import mujoco_accelerations, mujoco_joint_angles  # noqa: E402

ARM = Path(__file__).parent / "data" / "urdf" / "spatial_arm.urdf"
#: an initial state that swings the arm through a large spatial motion in 2 s
POSITIONS = {"shoulder": 2.5, "elbow": -0.8}
RATES = {"yaw": 1.5, "shoulder": -1.0}


def _arm(positions=POSITIONS, rates=RATES, source=ARM):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the note on the ignored <limit>
        return read_urdf(source, positions, rates).build()


def _mujoco_state(path_or_xml, positions, rates):
    model = (
        mujoco.MjModel.from_xml_string(path_or_xml)
        if str(path_or_xml).lstrip().startswith("<")
        else mujoco.MjModel.from_xml_path(str(path_or_xml))
    )
    data = mujoco.MjData(model)
    for i in range(model.njnt):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, i)
        data.qpos[model.jnt_qposadr[i]] = positions.get(name, 0.0)
        data.qvel[model.jnt_dofadr[i]] = rates.get(name, 0.0)
    mujoco.mj_forward(model, data)
    return model, data


@pytest.fixture(scope="module")
def arm():
    """The arm at its initial state, read and built once for the module's fast tests."""
    with pytest.warns(UserWarning, match=r"joint 'shoulder': <limit> ignored"):
        return read_urdf(ARM, POSITIONS, RATES).build()


def test_arm_is_read_with_mujocos_poses_masses_and_inertias(arm):
    """Link frames, centres of mass and world inertia tensors at a turned pose equal
    MuJoCo's (``xpos``, ``xmat``, ``xipos``, ``ximat``·diag(``body_inertia``)·ximatᵀ)."""
    model = arm
    assert list(model.bodies) == ["turret", "upper_arm", "forearm"]
    assert {k: c.kind for k, c in model.joints.items()} == dict.fromkeys(
        ("yaw", "shoulder", "elbow"), "revolute"
    )
    mj, data = _mujoco_state(ARM, POSITIONS, RATES)
    for i, name in enumerate(model.bodies, start=1):
        assert mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, i) == name
        rot = model.rotation(model.q0, name)
        part = model.parts[name]
        com = part.mbar[0, 1:] / part.mbar[0, 0]
        np.testing.assert_allclose(model.body(model.q0, name)[:3], data.xpos[i], atol=1e-14)
        np.testing.assert_allclose(rot, data.xmat[i].reshape(3, 3), atol=1e-14)
        np.testing.assert_allclose(model.q0[model.bodies[name]][:3] + rot @ com, data.xipos[i])
        euler = part.mbar[1:, 1:] - part.mbar[0, 0] * np.outer(com, com)
        inertia = np.trace(euler) * np.eye(3) - euler  # J = tr(E) I − E
        ximat = data.ximat[i].reshape(3, 3)
        theirs = ximat @ np.diag(mj.body_inertia[i]) @ ximat.T
        np.testing.assert_allclose(rot @ inertia @ rot.T, theirs, atol=1e-14)
        assert part.mbar[0, 0] == mj.body_mass[i]
    # the massless tool link on a fixed joint is a frame of the forearm (MuJoCo fuses it)
    assert model.parts["forearm"].frame("tool")[0].tolist() == [0.2, 0.0, 0.35]
    for name, angle in {"yaw": 0.0, **POSITIONS}.items():
        assert model.joint_position(model.q0, name) == pytest.approx(angle, abs=1e-14)


def test_revolute_angle_is_the_turn_about_the_common_axis(rng):
    """Frames b = a turned by θ about a's third axis give back θ, for any a."""
    theta = rng.uniform(-np.pi, np.pi, size=20)
    ea = np.stack([rpy_matrix(rng.normal(size=3)) for _ in theta])
    turn = np.stack([rpy_matrix((0.0, 0.0, t)) for t in theta])
    np.testing.assert_allclose(revolute_angle(ea, ea @ turn), theta, atol=1e-14)


def _velocities(model):
    names = list(model.bodies)
    mass = scipy.linalg.block_diag(*(np.kron(model.parts[b].mbar, np.eye(3)) for b in names))
    return mass, np.linalg.solve(mass, model.p0)


def _joint_accelerations(model, acc):
    r"""``θ̈ = (ω̇_child − ω̇_parent)·â`` with ``ω̇ = ½ Σ dᵢ × d̈ᵢ`` (the term
    ``(ω_c − ω_p)·(ω_p × â)`` vanishes since ``ω_c − ω_p ∥ â``); a slide's ``s̈`` is the
    second derivative of ``(r_b − r_a)·e₃`` along the accelerations, by finite differences of
    a quadratic — exact."""

    def omega_dot(body):
        if body is None:
            return np.zeros(3)
        s = model.bodies[body]
        d, dd = model.q0[s][3:].reshape(3, 3), acc[s][3:].reshape(3, 3)
        return 0.5 * np.cross(d, dd).sum(axis=0)

    out = {}
    for name, conn in model.joints.items():
        _, ea = model.frame_pose(model.q0, conn.a)
        out[name] = (omega_dot(conn.b.body) - omega_dot(conn.a.body)) @ ea[:, 2]
    return out


def test_arm_forward_dynamics_is_mujocos(arm):
    """The director model's constrained accelerations, as joint accelerations, equal
    MuJoCo's ``qacc`` at the initial state to 1e-10 relative (the model, with no step)."""
    model = arm
    mass, v0 = _velocities(model)
    ours = _joint_accelerations(model, constrained_accelerations(model.system, model.q0, v0, mass))
    theirs = mujoco_accelerations(ARM, POSITIONS, RATES)
    scale = max(abs(x) for x in theirs.values())
    for name, value in theirs.items():
        assert ours[name] == pytest.approx(value, abs=1e-10 * scale), name


SLIDER = """<robot name="slider">
  <link name="ground"/>
  <joint name="rail" type="prismatic">
    <parent link="ground"/><child link="carriage"/>
    <origin xyz="0.1 0 0.3" rpy="0.3 0.2 0"/><axis xyz="1 1 0"/>
  </joint>
  <link name="carriage">
    <inertial><origin xyz="0 0 -0.1" rpy="0 0.5 0"/><mass value="2.0"/>
      <inertia ixx="0.03" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.04"/></inertial>
  </link>
  <joint name="hinge" type="continuous">
    <parent link="carriage"/><child link="bob"/>
    <origin xyz="0 0 -0.2"/><axis xyz="0 1 0.3"/>
  </joint>
  <link name="bob">
    <inertial><origin xyz="0 0 -0.4"/><mass value="0.7"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.005"/></inertial>
  </link>
</robot>"""


def test_prismatic_joint_slides_as_mujocos():
    """A carriage on a tilted rail carrying a pendulum: the slide comes back from the
    frames, and both joints' accelerations equal MuJoCo's (the same XML text)."""
    positions, rates = {"rail": 0.25, "hinge": 0.6}, {"rail": -0.4, "hinge": 1.1}
    model = _arm(positions, rates, SLIDER)
    assert model.joint_position(model.q0, "rail") == pytest.approx(0.25, abs=1e-14)
    assert model.joint_position(model.q0, "hinge") == pytest.approx(0.6, abs=1e-14)
    _, data = _mujoco_state(SLIDER, positions, rates)
    for i, name in enumerate(model.bodies, start=1):
        np.testing.assert_allclose(model.body(model.q0, name)[:3], data.xpos[i], atol=1e-14)
    mass, v0 = _velocities(model)
    acc = constrained_accelerations(model.system, model.q0, v0, mass)
    # the slide's acceleration: the carriage origin's acceleration along the rail
    # (the ground is the world, so (r_b − r_a)·e₃ is linear in q)
    axis = model.frame_pose(model.q0, model.joints["rail"].a)[1][:, 2]
    ours = {
        "rail": acc[model.bodies["carriage"]][:3] @ axis,
        "hinge": _joint_accelerations(model, acc)["hinge"],
    }
    scale = np.max(np.abs(data.qacc))
    np.testing.assert_allclose([ours["rail"], ours["hinge"]], data.qacc, atol=1e-10 * scale)


def _broken(old: str, new: str) -> str:
    text = ARM.read_text()
    assert old in text
    return text.replace(old, new)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (_broken('<parent link="turret"/>', '<parent link="turet"/>'), r"joint 'shoulder'.*turet"),
        (_broken('type="continuous"', 'type="planar"'), r"joint 'yaw': type='planar'"),
        (_broken('<mass value="0.5"/>', '<mass value="0"/>'), r"link 'forearm' has no mass"),
        (_broken('ixx="0.008"', 'ixx="0.02"'), r"link 'forearm'.*Jᵢ < Jⱼ \+ Jₖ"),
        (_broken('xyz="0 0.05 0.5"', 'xyz="0 0.05"'), r"joint 'elbow' <origin>: xyz="),
        (_broken('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'), r"joint 'shoulder'.*zero"),
        (_broken('<child link="tool"/>', '<child link="forearm"/>'), r"'forearm' is the child"),
        (_broken('<mass value="1.2"/>', ""), r"link 'turret'.*no <mass"),
        ("<mujoco/>", r"top element is <mujoco>"),
        ("<robot><link", r"not well-formed XML"),
    ],
)
def test_bad_urdf_names_the_link_or_joint_and_the_fix(text, message):
    with pytest.raises(ModelError, match=message):
        _arm(source=text)


def test_unknown_joint_in_positions_is_refused():
    with pytest.raises(ModelError, match=r"positions\['tool_mount'\] names no revolute"):
        read_urdf(ARM, {"tool_mount": 0.1}, quiet=True)
    assert parse_urdf(ARM).root == "base"


def _arm_errors(hs, discretization):
    """The arm's largest joint-angle error against MuJoCo + DOP853 (rtol = atol = 1e-12)
    over 2 s, read every 10 ms, at each step in ``hs`` under ``discretization``."""
    times = np.linspace(0.0, 2.0, 201)
    ref = mujoco_joint_angles(ARM, POSITIONS, RATES, times)
    model = _arm()
    errors = []
    for h in hs:
        traj = dv.simulate(model.system, model.q0, model.p0, dt=h, steps=round(2.0 / h),
                           discretization=discretization, solver=dv.NewtonSolver())  # fmt: skip
        every = round(0.01 / h)
        errors.append(
            max(np.max(np.abs(model.joint_position(traj.q, j)[::every] - ref[j])) for j in ref)
        )
    return errors


@pytest.mark.slow
def test_arm_joint_angles_against_mujoco():
    """The three joint angles over 2 s against MuJoCo's forward dynamics integrated by
    DOP853 at rtol = atol = 1e-12: order 2 (midpoint), and ≤ 1e-6 at h = 1/8000 s."""
    hs = [0.005, 0.0025, 0.00125]
    errors = _arm_errors([*hs, 0.000125], "midpoint")
    assert loglog_slope(hs, errors[:3]) == pytest.approx(2.0, abs=0.05)
    assert errors[3] < 1e-6


@pytest.mark.slow
def test_arm_joint_angles_against_mujoco_at_order_four():
    """The same under the order-4 rule (``"lobatto"``): order 4 (measured 8.2e-7, 5.1e-8,
    3.2e-9 at h = 0.01, 0.005, 0.0025), within 1e-6 already at h = 0.01 (200 steps)."""
    hs = [0.01, 0.005, 0.0025]
    errors = _arm_errors(hs, "lobatto")
    assert loglog_slope(hs, errors) == pytest.approx(4.0, abs=0.05)
    assert errors[0] < 1e-6


FLOATING = """<robot name="floating">
  <link name="hull">
    <inertial><mass value="3.0"/>
      <inertia ixx="0.3" ixy="0" ixz="0" iyy="0.4" iyz="0" izz="0.5"/></inertial>
  </link>
  <joint name="weld" type="fixed">
    <parent link="hull"/><child link="mast"/>
    <origin xyz="0 0 0.4" rpy="0.1 0 0"/>
  </joint>
  <link name="mast">
    <inertial><origin xyz="0 0 0.2"/><mass value="0.5"/>
      <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001"/></inertial>
  </link>
  <joint name="buoy" type="floating">
    <parent link="hull"/><child link="float"/>
    <origin xyz="1 0 0"/>
  </joint>
  <link name="float">
    <inertial><mass value="0.2"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
</robot>"""


def test_floating_base_fixed_and_floating_joints():
    """``fixed_base=False``: the root is a free body; a fixed joint between two massive
    links welds them (its six rows hold at the pose); a floating joint adds no row."""
    model = read_urdf(FLOATING, fixed_base=False).build()
    assert list(model.bodies) == ["hull", "mast", "float"]
    assert {k: c.kind for k, c in model.joints.items()} == {"weld": "fixed"}
    np.testing.assert_allclose(model.rotation(model.q0, "mast"), rpy_matrix((0.1, 0.0, 0.0)))
    np.testing.assert_allclose(model.body(model.q0, "mast")[:3], [0.0, 0.0, 0.4])
    np.testing.assert_allclose(model.body(model.q0, "float")[:3], [1.0, 0.0, 0.0])
    assert model.system.n == 36
    rows = np.asarray(model.system.position_constraints(model.q0))
    assert rows.shape == (3 * 6 + 6,) and np.max(np.abs(rows)) < 1e-15
    with pytest.raises(ModelError, match=r"link 'hull' \(the root of a floating base\)"):
        read_urdf(FLOATING.replace('<mass value="3.0"/>', '<mass value="0"/>'), fixed_base=False)
