"""MuJoCo's spatial double pendulum: the same two links as
:func:`diracvi.problems.rigid_bodies.spatial_double_pendulum`, written as MJCF (a ball
joint at the world origin, a hinge about the first link's body x-axis). MuJoCo is the
independent oracle: its trajectories (RK4 at 1e-4 s) and its forward dynamics."""

from __future__ import annotations

import numpy as np


def _model(rotation0, omega0_body, hinge_rate, options):
    """The MJCF model and its data at the initial state (forward dynamics evaluated)."""
    import mujoco

    from diracvi.problems.rigid_bodies import LINKS

    (m1, j1, a1, l1), (m2, j2, a2, _) = LINKS
    xml = f"""
<mujoco><option {options}><flag contact="disable"/></option><worldbody>
 <body name="l1"><joint type="ball"/>
  <inertial pos="0 0 {-a1}" mass="{m1}" diaginertia="{j1[0]} {j1[1]} {j1[2]}"/>
  <body name="l2" pos="0 0 {-l1}"><joint type="hinge" axis="1 0 0"/>
   <inertial pos="0 0 {-a2}" mass="{m2}" diaginertia="{j2[0]} {j2[1]} {j2[2]}"/>
  </body></body></worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.asarray(rotation0, dtype=np.float64).reshape(9))
    data.qpos[:4], data.qpos[4] = quat, 0.0
    data.qvel[:3], data.qvel[3] = omega0_body, hinge_rate  # a ball's qvel is in body axes
    mujoco.mj_forward(model, data)
    return model, data


def mujoco_centres(rotation0, omega0_body, hinge_rate, times, gravity=9.81, dt=1e-4):
    """The world centres of mass of both links at ``times``, stepped by MuJoCo's RK4."""
    import mujoco

    options = f'gravity="0 0 {-gravity}" integrator="RK4" timestep="{dt}"'
    model, data = _model(rotation0, omega0_body, hinge_rate, options)
    out, k = [], 0
    for t in np.asarray(times, dtype=np.float64):
        target = round(t / dt)
        while k < target:
            mujoco.mj_step(model, data)
            k += 1
        out.append(np.array(data.xipos[1:3]))
    return np.array(out)  # (T, 2, 3)


def mujoco_accelerations(rotation0, omega0_body, hinge_rate, gravity=9.81):
    """MuJoCo's forward dynamics ``qacc`` at the initial state: the ball joint's body-axis
    angular acceleration (3) and the hinge's (1)."""
    _, data = _model(rotation0, omega0_body, hinge_rate, f'gravity="0 0 {-gravity}"')
    return np.array(data.qacc)


def centre_errors(hs, discretization):
    """diracvi's spatial double pendulum after 1 s at each step in ``hs`` under
    ``discretization``: the largest distance of the two links' centres of mass from
    MuJoCo's (RK4 at 1e-4 s), one error per step size."""
    import diracvi as dv
    from diracvi.problems.rigid_bodies import _turned, spatial_double_pendulum

    ref = mujoco_centres(_turned((0.6, 0.2, 0.0)), (0.3, -0.4, 1.0), 2.0, [1.0])[-1]
    errors = []
    for h in hs:
        prob = spatial_double_pendulum(dt=h, steps=round(1.0 / h))
        tr = dv.simulate(prob.system, prob.q0, prob.p0, dt=h, steps=prob.steps,
                         discretization=discretization, solver=dv.NewtonSolver())  # fmt: skip
        errors.append(np.max(np.abs(np.stack([tr.q[-1, 0:3], tr.q[-1, 12:15]]) - ref)))
    return errors
