"""MuJoCo as the oracle of a URDF arm: it reads the same URDF file itself
(``mujoco.MjModel.from_xml_path``), evaluates its forward dynamics ``qacc = M⁻¹(τ − c)``
with ``mj_forward``, and SciPy's DOP853 integrates ``(qpos, qvel)`` at ``rtol = atol =
1e-12`` — a reference no part of diracvi computes. Hinge joints only (``qpos`` = the URDF
joint angles, ``qvel`` their rates)."""

from __future__ import annotations

import numpy as np


def _load(path, positions, rates):
    import mujoco

    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nq == model.nv, "hinge and slide joints only"
    data = mujoco.MjData(model)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(model.njnt)]
    q0 = np.array([positions.get(n, 0.0) for n in names])
    v0 = np.array([rates.get(n, 0.0) for n in names])
    return model, data, names, q0, v0


def mujoco_accelerations(path, positions, rates):
    """``{joint: qacc}`` at the given joint positions and rates."""
    import mujoco

    model, data, names, q0, v0 = _load(path, positions, rates)
    data.qpos[:], data.qvel[:] = q0, v0
    mujoco.mj_forward(model, data)
    return dict(zip(names, np.array(data.qacc), strict=True))


def mujoco_joint_angles(path, positions, rates, times):
    """``{joint: angle(times)}`` integrated from MuJoCo's forward dynamics by DOP853."""
    import mujoco
    from scipy.integrate import solve_ivp

    model, data, names, q0, v0 = _load(path, positions, rates)
    n = len(names)

    def rhs(_, y):
        data.qpos[:], data.qvel[:] = y[:n], y[n:]
        mujoco.mj_forward(model, data)
        return np.concatenate([y[n:], data.qacc])

    times = np.asarray(times, dtype=np.float64)
    sol = solve_ivp(
        rhs,
        (0.0, times[-1]),
        np.concatenate([q0, v0]),
        method="DOP853",
        t_eval=times,
        rtol=1e-12,
        atol=1e-12,
    )
    assert sol.success, sol.message
    return {name: sol.y[i] for i, name in enumerate(names)}
