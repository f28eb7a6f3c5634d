r"""A quadrotor: a rigid frame with four propellers, its geometric controller, and its
Newton–Euler reference.

The craft (:func:`quadrotor`) is :func:`~diracvi.components.rotorcraft` on a frame of mass
``m`` and inertia ``J`` with propellers at ``(±ℓ, 0, 0)``, ``(0, ±ℓ, 0)`` turning in
the senses ``s = (+1, −1, +1, −1)``; either the squared propeller speeds are the inputs
(``motors=False``, 12 coordinates) or each propeller is a rotor driven by a DC motor from
a commanded voltage (``motors=True``, 16 coordinates: the gyrostat).

The controller (:func:`geometric_controller`) is Lee, Leok & McClamroch's tracking law on
SE(3) (CDC 2010), read from the directors, so no angle of the attitude is ever formed::

    F_d = m (−k_x e_x − k_v ẋ + g e₃),            f = F_d·d₃,
    R_d = [b₂ × b₃, b₂, b₃],  b₃ = F_d/|F_d|,  b₂ = b₃ × b₁ᶜ/|b₃ × b₁ᶜ|,
    M = −J (k_R e_R + k_Ω Ω),   e_R = ½ (R_dᵀ R − Rᵀ R_d)^∨,

then the wrench ``(f, M)`` is split among the four thrusts by the mixing matrix and, with
motors, each thrust ``k_f ω²`` turned into the voltage that holds ``ω`` against the drag.

:func:`newton_euler` is the reference: the same craft's Newton–Euler (gyrostat) equations
in ``(x, ẋ, R, Ω, φ̇)`` under prescribed inputs, integrated by SciPy's DOP853, in NumPy
without diracvi.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..components.rigid_body import RigidBody
from ..components.rotorcraft import MotorPropeller, momenta, rotorcraft
from ..driver.simulate import simulate
from .linkages import _dop853

MASS, INERTIA, ARM, GRAVITY = 1.0, (0.01, 0.01, 0.018), 0.2, 9.81
#: k_f (N/(rad/s)²) and k_m (N m/(rad/s)²): thrust and drag torque of a propeller
THRUST, DRAG = 1e-5, 2e-7
#: rotor axial moment (kg m²), motor constant (V s/rad), armature resistance (Ω)
MOTOR = MotorPropeller(3e-5, 0.01, 0.2)
ARMS = np.array([[ARM, 0.0, 0.0], [0.0, ARM, 0.0], [-ARM, 0.0, 0.0], [0.0, -ARM, 0.0]])
SENSES = np.array([1.0, -1.0, 1.0, -1.0])
#: (f, M₁, M₂, M₃) = MIXING @ (T₁ … T₄): the wrench of the four thrusts Tᵢ = k_f uᵢ
MIXING = np.vstack([np.ones(4), ARMS[:, 1], -ARMS[:, 0], -(DRAG / THRUST) * SENSES])
#: default gains (k_x, k_v, k_R, k_Ω) in 1/s², 1/s, 1/s², 1/s
GAINS = (2.0, 2.0, 40.0, 8.0)
#: the manoeuvre's target: from hover at the origin to this point
WAYPOINT = (1.0, 0.5, 0.3)


def hover_speed() -> float:
    """``ω_h = √(m g / (4 k_f))``: each propeller carries a quarter of the weight."""
    return float(np.sqrt(MASS * GRAVITY / (4 * THRUST)))


def frame(name: str = "frame") -> RigidBody:
    """The frame: the craft's mass and inertia (rotors' spin excepted), under gravity."""
    return RigidBody(MASS, INERTIA, name=name, gravity=(0.0, 0.0, -GRAVITY))


def _vee(a):
    return jnp.stack([a[2, 1], a[0, 2], a[1, 0]])


def geometric_controller(gains, waypoint, motors: bool = True, heading=(1.0, 0.0, 0.0)):
    r"""``command(q_f, v_f, t)``: the tracking law of the module docstring toward the
    fixed ``waypoint`` with gains ``(k_x, k_v, k_R, k_Ω)`` (may be traced), giving the
    squared propeller speeds (``motors=False``) or the motors' voltages."""
    kx, kv, kr, kw = (gains[i] for i in range(4))
    target = jnp.asarray(waypoint, dtype=jnp.float64)
    b1c = jnp.asarray(heading, dtype=jnp.float64)
    j = jnp.diag(jnp.asarray(INERTIA))
    unmix = jnp.asarray(np.linalg.inv(MIXING))
    soft = 0.02 * MASS * GRAVITY / 4  # the thrusts' smooth floor at 0 (differentiable)

    def command(qf, vf, t):
        r = qf[3:12].reshape(3, 3).T
        omega = r.T @ (0.5 * jnp.sum(jnp.cross(r.T, vf[3:12].reshape(3, 3)), axis=0))
        fd = MASS * (-kx * (qf[0:3] - target) - kv * vf[0:3] + jnp.array([0.0, 0.0, GRAVITY]))
        b3 = fd / jnp.linalg.norm(fd)
        b2 = jnp.cross(b3, b1c)
        b2 = b2 / jnp.linalg.norm(b2)
        rd = jnp.stack([jnp.cross(b2, b3), b2, b3], axis=1)
        e_r = 0.5 * _vee(rd.T @ r - r.T @ rd)
        wrench = jnp.concatenate([jnp.stack([fd @ r[:, 2]]), -j @ (kr * e_r + kw * omega)])
        thrusts = soft * jnp.logaddexp(0.0, (unmix @ wrench) / soft)
        u = thrusts / THRUST
        return MOTOR.voltage(jnp.sqrt(u), DRAG) if motors else u

    return command


def quadrotor(command, motors: bool = True, position=(0.0, 0.0, 0.0), name: str = "quadrotor"):
    r"""``(system, q0, p0)``: the craft hovering at ``position`` (at rest, level, the
    propellers at the hover speed ``ω_h``) under ``command(q_f, v_f, t)``."""
    body = frame()
    system = rotorcraft(
        body, ARMS, SENSES, THRUST, DRAG, command, motors=MOTOR if motors else None, name=name
    )
    qf, vf = body.state(position)
    if not motors:
        return system, qf, body.momenta(vf)
    q0 = np.concatenate([qf, np.zeros(4)])
    v0 = np.concatenate([vf, np.full(4, hover_speed())])
    return system, q0, momenta(body, SENSES, MOTOR, q0, v0)


def _hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def newton_euler(inputs, t, motors: bool = True, position=(0.0, 0.0, 0.0)):
    r"""The hovering craft under prescribed ``inputs(t) -> (4,)`` (squared speeds, or
    voltages with motors) by DOP853 (``rtol = 1e-12``): ``(x (T, 3), R (T, 3, 3), φ̇ (T,
    4))``. The gyrostat in body axes, ``H = J Ω + J_r Σ (sᵢ φ̇ᵢ + Ω₃) e₃``::

        m ẍ = m g + R e₃ k_f Σ uᵢ,        Ṙ = R Ω̂,
        J Ω̇ = M − Ω × H − Σ sᵢ (τᵢ − k_m uᵢ) e₃,   M = Σ Xᵢ × k_f uᵢ e₃ − Σ sᵢ k_m uᵢ e₃,
        J_r φ̈ᵢ = τᵢ − k_m uᵢ − J_r sᵢ Ω̇₃,     τᵢ = K (Vᵢ − K φ̇ᵢ)/R,   uᵢ = φ̇ᵢ |φ̇ᵢ|.
    """
    j = np.diag(INERTIA)
    j_inv = np.linalg.inv(j)
    e3 = np.array([0.0, 0.0, 1.0])
    jr, k, res = MOTOR.inertia, MOTOR.constant, MOTOR.resistance

    def rhs(time, y):
        xd, r, w = y[3:6], y[6:15].reshape(3, 3), y[15:18]
        cmd = np.asarray(inputs(time), dtype=np.float64)
        rate = y[18:22] if motors else None
        u = rate * np.abs(rate) if motors else cmd
        moment = np.cross(ARMS, THRUST * u[:, None] * e3).sum(axis=0)
        moment = moment - DRAG * (SENSES @ u) * e3
        h = j @ w
        if motors:
            tau = k * (cmd - k * rate) / res
            h = h + jr * np.sum(SENSES * rate + w[2]) * e3
            moment = moment - np.sum(SENSES * (tau - DRAG * u)) * e3
        dw = j_inv @ (moment - np.cross(w, h))
        acc = np.array([0.0, 0.0, -GRAVITY]) + r @ e3 * THRUST * np.sum(u) / MASS
        out = [xd, acc, (r @ _hat(w)).reshape(9), dw]
        if motors:
            out.append((tau - DRAG * u) / jr - SENSES * dw[2])
        return np.concatenate(out)

    y0 = [np.asarray(position, dtype=np.float64), np.zeros(3), np.eye(3).reshape(9), np.zeros(3)]
    if motors:
        y0.append(np.full(4, hover_speed()))
    y = _dop853(rhs, np.concatenate(y0), 0.0, t)
    rates = y[:, 18:22] if motors else np.zeros((len(y), 0))
    return y[:, 0:3], y[:, 6:15].reshape(-1, 3, 3), rates


def power_terms(q, dt, voltages) -> dict:
    r"""The motor–propeller craft's force port, step by step, split by what does the work
    (J per step, from ``q̄ = (qₖ + qₖ₊₁)/2`` and ``v = (qₖ₊₁ − qₖ)/h`` as the midpoint
    rule evaluates it): ``"input"`` ``h Σ Vᵢ iᵢ``, ``"winding"`` ``−h Σ R iᵢ²``,
    ``"rotors"`` the air's ``−h Σ k_m uᵢ (φ̇ᵢ + sᵢ Ω₃)``, ``"frame"`` the thrusts'
    ``h Σ k_f uᵢ d₃·(ẋ + Σⱼ Xᵢⱼ ḋⱼ)``; ``voltages`` is ``V(t) -> (4,)`` (NumPy), ``q``
    the run's coordinates (N+1, 16) from t = 0."""
    q = np.asarray(q, dtype=np.float64)
    mid, vel = 0.5 * (q[1:] + q[:-1]), np.diff(q, axis=0) / dt
    t = dt * (np.arange(len(vel)) + 0.5)
    volts = np.array([np.asarray(voltages(s), dtype=np.float64) for s in t])
    rate = vel[:, 12:16]
    u, current = rate * np.abs(rate), (volts - MOTOR.constant * rate) / MOTOR.resistance
    spin = 0.5 * (np.sum(mid[:, 6:9] * vel[:, 3:6], 1) - np.sum(mid[:, 3:6] * vel[:, 6:9], 1))
    arm_velocity = vel[:, None, 0:3] + np.einsum(
        "ij,kjl->kil", ARMS, vel[:, 3:12].reshape(-1, 3, 3)
    )
    lift = np.einsum("kil,kl->ki", arm_velocity, mid[:, 9:12])  # d₃·(velocity of arm i)
    return {
        "input": dt * np.sum(volts * current, axis=1),
        "winding": -dt * np.sum(MOTOR.resistance * current**2, axis=1),
        "rotors": -dt * np.sum(DRAG * u * (rate + SENSES * spin[:, None]), axis=1),
        "frame": dt * np.sum(THRUST * u * lift, axis=1),
    }


def tracking_loss(log_gains, dt=0.01, duration=2.0, waypoint=WAYPOINT, motors=True, solver=None):
    r"""``(J, q)``: the mean squared distance ``J = (1/(N+1)) Σₖ |xₖ − w|²`` to the
    waypoint over a run of ``duration`` from hover at the origin, the craft flown by
    :func:`geometric_controller` with gains ``exp(log_gains)``, and the run's coordinates.
    Traceable: ``jax.grad`` of it differentiates through :func:`~diracvi.simulate` (each
    step by the implicit function theorem). A failed step gives ``J = ∞``. ``solver``
    goes to ``simulate``."""
    command = geometric_controller(jnp.exp(log_gains), waypoint, motors=motors)
    system, q0, p0 = quadrotor(command, motors=motors)
    steps = round(duration / dt)
    traj = simulate(
        system, q0, p0, dt=dt, steps=steps, discretization="midpoint", solver=solver, throw=False
    )
    miss = jnp.mean(jnp.sum((traj.q[:, 0:3] - jnp.asarray(waypoint)) ** 2, axis=1))
    return jnp.where(jnp.all(traj.status == 0), miss, jnp.inf), traj.q


def tune(log_gains, iterations=10, rate=1.0, **run):
    r"""Gradient descent on :func:`tracking_loss` (keyword arguments ``run``) with a
    step that grows by 1.5 after a descent and halves after a rise (the trial is then
    dropped): ``(log_gains, history of J, runs)``, ``runs`` the coordinates of the
    first run and of each accepted one. One compiled value-and-gradient serves every
    iteration."""
    value_and_grad = jax.jit(jax.value_and_grad(lambda g: tracking_loss(g, **run), has_aux=True))
    theta = jnp.asarray(log_gains, dtype=jnp.float64)
    (value, q), grad = value_and_grad(theta)
    history, runs = [float(value)], [np.asarray(q)]
    for _ in range(iterations):
        trial = theta - rate * grad
        (v_trial, q_trial), g_trial = value_and_grad(trial)
        if float(v_trial) < history[-1]:
            theta, grad, rate = trial, g_trial, 1.5 * rate
            history.append(float(v_trial))
            runs.append(np.asarray(q_trial))
        else:
            rate *= 0.5
    return theta, np.array(history), runs


__all__ = [
    "ARMS",
    "GAINS",
    "MIXING",
    "MOTOR",
    "SENSES",
    "WAYPOINT",
    "frame",
    "geometric_controller",
    "hover_speed",
    "newton_euler",
    "power_terms",
    "quadrotor",
    "tracking_loss",
    "tune",
]
