r"""MuJoCo as the oracle of a URDF arm driven by gear-free DC motors: MuJoCo reads the same
URDF file itself (``mujoco.MjModel.from_xml_path``) and gives, at each state, the
joint-space mass matrix ``M(q)`` (``mj_fullM``) and the bias forces ``c(q, q̇)``
(``qfrc_bias``: Coriolis, centrifugal and gravity); the motors and their armature
circuits are written here, from their textbook equations::

    (M(q) + diag(J_m)) q̈ = K i − c(q, q̇)        (τ = K i: no gear; J_m the rotors)
    L di/dt = V(t) − R i − K q̇                    (one loop per joint: source, R, L, motor)
    dQ/dt = i                                       (the loops' charges)

integrated by SciPy's DOP853 at ``rtol = 1e-12`` (``atol = 1e-13``), piece by piece
between the sources' corners — a reference no part of diracvi computes. Hinge joints only.
"""

from __future__ import annotations

import itertools

import numpy as np


def _full_mass(mujoco):
    """``mj_fullM`` as ``f(model, data, out)``: MuJoCo ≥ 3.4 takes the data (``mj_fullM(m,
    d, dst)``), earlier releases the sparse ``qM`` (``mj_fullM(m, dst, d.qM)``)."""
    if hasattr(mujoco.MjData, "qM"):
        return lambda model, data, out: mujoco.mj_fullM(model, out, data.qM)
    return mujoco.mj_fullM


def mujoco_motor_arm(path, positions, drive, times, breakpoints=(), rotor_inertia=0.0):
    """``(names, y(times))``: the joint names in MuJoCo's order and the rows ``q``, ``q̇``,
    ``i``, ``Q`` (each one per joint) at ``times``. ``drive[joint] = (K, R, L, V)`` with
    ``V(t)`` the loop's source; the arm starts at ``positions`` at rest, no current."""
    import mujoco
    from scipy.integrate import solve_ivp

    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.nq == model.nv == model.njnt, "hinge joints only"
    data = mujoco.MjData(model)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    n = len(names)
    k, r, ell = (np.array([drive[name][c] for name in names]) for c in range(3))
    sources = [drive[name][3] for name in names]
    rotor = np.diag(np.broadcast_to(np.asarray(rotor_inertia, dtype=float), (n,)))
    mass = np.zeros((n, n))
    full_mass = _full_mass(mujoco)

    def rhs(t, y):
        q, w, i = y[:n], y[n : 2 * n], y[2 * n : 3 * n]
        data.qpos[:], data.qvel[:] = q, w
        mujoco.mj_forward(model, data)
        full_mass(model, data, mass)
        acc = np.linalg.solve(mass + rotor, k * i - data.qfrc_bias)
        volts = np.array([v(t) for v in sources])
        return np.concatenate([w, acc, (volts - r * i - k * w) / ell, i])

    times = np.asarray(times, dtype=np.float64)
    y = np.concatenate([[positions.get(name, 0.0) for name in names], np.zeros(3 * n)])
    edges = sorted({0.0, *(b for b in breakpoints if 0.0 < b < times[-1]), float(times[-1])})
    out = np.empty((4 * n, len(times)))
    for a, b in itertools.pairwise(edges):
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-12, atol=1e-13, dense_output=True)
        assert sol.success, sol.message
        inside = (times >= a) & (times <= b)
        out[:, inside] = sol.sol(times[inside])
        y = sol.y[:, -1]
    return names, out
