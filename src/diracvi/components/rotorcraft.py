r"""A rigid frame carrying propellers: a multirotor, with or without motor dynamics.

The frame is a :class:`~diracvi.components.RigidBody` ``q_f = (x, d₁, d₂, d₃)``; each
propeller ``i`` sits at the body point ``Xᵢ`` (its arm), turns about the frame's third
director ``d₃`` in the sense ``sᵢ = ±1``, and the air gives it

    thrust  k_f uᵢ d₃  at Xᵢ,        drag torque  −sᵢ k_m uᵢ d₃,

with ``uᵢ = ωᵢ |ωᵢ|`` the squared propeller speed. Two models:

- **thrust input** (``motors=None``): ``uᵢ`` is the command itself and the drag torque
  acts on the frame (a propeller at constant speed passes its drag on through the
  motor's stator). The system is the frame's own (12 coordinates, 6 rows) with the
  force ``F(q, v, t)``.
- **motor–propeller** (``motors=MotorPropeller(…)``): each propeller is a rotor with
  axial moment ``J_r`` on a coordinate ``φᵢ`` of its own (its angle relative to the
  frame, counted in the sense ``sᵢ``), driven by a DC motor ``τᵢ = K iᵢ``,
  ``iᵢ = (Vᵢ − K φ̇ᵢ)/R`` (the armature's inductance neglected) from the commanded
  voltage ``Vᵢ``; ``uᵢ = φ̇ᵢ |φ̇ᵢ|``. The rotor's absolute spin is ``φ̇ᵢ + sᵢ Ω₃`` with
  ``Ω₃ = d₃·ω = ½ (d₂·ḋ₁ − d₁·ḋ₂)`` (``ω = ½ Σ dⱼ × ḋⱼ``), so

      L = L_frame(q_f, v_f) + Σᵢ ½ J_r (φ̇ᵢ + sᵢ Ω₃(q_f, v_f))²

  — the gyrostat: the rotors' angular momentum is the frame's too, and the motor torque
  on ``φᵢ`` (a relative coordinate) is an internal torque whose reaction on the frame
  the Lagrangian carries. The rotors' mass and transverse inertia belong to the frame.

Both enter the Lagrange–Dirac structure as one **force port** ``F(q, v, t)``, a
covector whose pairing with the velocities is the power delivered:

    thrust on the frame      (f, X₁ f, X₂ f, X₃ f),  f = k_f uᵢ d₃
    drag torque on a rotor   (0, ½ τ × d₁, ½ τ × d₂, ½ τ × d₃) on the frame and
                             −k_m uᵢ on φᵢ,          τ = −sᵢ k_m uᵢ d₃
    motor torque             K (Vᵢ − K φ̇ᵢ)/R on φᵢ

(a torque on a rotor carried by the frame does the virtual work ``τ·(δθ_frame + sᵢ δφᵢ
d₃)``). So ``dE/dt = F·v``: the air's work on the frame and the rotors plus the motors'
shaft power ``Vᵢ iᵢ − R iᵢ²`` (``problems/quadrotor.py: power_terms`` splits a run's).
"""

from __future__ import annotations

from dataclasses import dataclass

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.system import LagrangeDiracSystem
from ._part import positive
from .rigid_body import COORDS, ORTHONORMALITY, RigidBody, orthonormality


@dataclass(frozen=True)
class MotorPropeller:
    """A DC motor with a propeller on its shaft: rotor axial moment ``inertia`` (kg m²),
    motor constant ``constant`` (V s/rad = N m/A) and armature ``resistance`` (Ω)."""

    inertia: float
    constant: float
    resistance: float

    def __post_init__(self):
        for arg in ("inertia", "constant", "resistance"):
            object.__setattr__(self, arg, positive("MotorPropeller", arg, getattr(self, arg)))

    def voltage(self, speed, drag: float):
        r"""The voltage that holds a propeller at ``speed``: ``K ω + R k_m ω²/K``
        (motor torque = drag torque, ``iᵢ = k_m ω²/K``)."""
        k, r = self.constant, self.resistance
        return k * speed + r * drag * speed * jnp.abs(speed) / k


class Propellers(eqx.Module):
    """The propellers' geometry and air coefficients (static: hashed with the system)."""

    arms: tuple = eqx.field(static=True)  # (n, 3) body points Xᵢ
    senses: tuple = eqx.field(static=True)  # (n,) ±1
    thrust: float = eqx.field(static=True)  # k_f
    drag: float = eqx.field(static=True)  # k_m

    @property
    def count(self) -> int:
        return len(self.senses)

    def frame_force(self, qf, u):
        r"""The frame's covector of thrusts ``k_f uᵢ d₃`` at ``Xᵢ`` and torques
        ``−sᵢ k_m uᵢ d₃``: ``(Σ f, Σ Xᵢ₁ f + ½ τ × d₁, …)``."""
        d = qf[3:12].reshape(3, 3)
        arms, senses = jnp.asarray(self.arms), jnp.asarray(self.senses)
        lift = self.thrust * jnp.sum(u)
        moment = self.thrust * (arms.T @ u)  # Σ Xᵢ uᵢ k_f (body coordinates)
        yaw = -self.drag * (senses @ u)
        f, tau = lift * d[2], yaw * d[2]
        rows = moment[:, None] * d[2][None, :] + 0.5 * jnp.cross(tau[None, :], d)
        return jnp.concatenate([f, rows.reshape(9)])


def spin_rate(qf, vf):
    r"""``Ω₃ = d₃·ω = ½ (d₂·ḋ₁ − d₁·ḋ₂)`` of the frame (``ω = ½ Σ dⱼ × ḋⱼ`` on the
    orthonormal directors; bilinear in ``(q, v)``)."""
    return 0.5 * (qf[6:9] @ vf[3:6] - qf[3:6] @ vf[6:9])


class _Lagrangian(eqx.Module):
    frame: object
    senses: tuple = eqx.field(static=True)
    inertia: float = eqx.field(static=True)

    def __call__(self, q, v):
        spin = v[12:] + jnp.asarray(self.senses) * spin_rate(q[:12], v[:12])
        return self.frame(q[:12], v[:12]) + 0.5 * self.inertia * jnp.sum(spin**2)


def _force(props: Propellers, command, motor: MotorPropeller | None):
    """The force port ``F(q, v, t)`` (module docstring) with the command
    ``command(q_f, v_f, t)`` — a plain closure, so that gains a traced ``command``
    captures are lifted out as the system's parameters (docs/gradients.md)."""

    def force(q, v, t):
        cmd = command(q[:12], v[:12], t)
        if motor is None:
            return props.frame_force(q, cmd)
        rate = v[12:]
        u = rate * jnp.abs(rate)
        k, r = motor.constant, motor.resistance
        shaft = k * (cmd - k * rate) / r - props.drag * u
        return jnp.concatenate([props.frame_force(q[:12], u), shaft])

    return force


def _arms(where: str, arms, senses):
    pts = np.atleast_2d(np.asarray(arms, dtype=np.float64))
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise ModelError(f"{where}: arms={arms!r} must be finite body points, shape (n, 3).")
    s = np.asarray(senses, dtype=np.float64)
    if s.shape != (len(pts),) or not np.all(np.abs(s) == 1.0):
        raise ModelError(
            f"{where}: senses={senses!r} must be one ±1 per arm ({len(pts)} arms): the sense "
            "in which each propeller turns about the frame's third axis."
        )
    return pts, s


def rotorcraft(
    frame: RigidBody,
    arms,
    senses,
    thrust,
    drag,
    command,
    motors: MotorPropeller | None = None,
    name: str = "rotorcraft",
) -> LagrangeDiracSystem:
    r"""The frame with its propellers as one :class:`~diracvi.LagrangeDiracSystem`.

    Args:
        frame: the body (mass and inertia of the whole craft but the rotors' spin).
        arms: ``(n, 3)`` propeller positions ``Xᵢ`` in body coordinates.
        senses: ``(n,)`` ±1, each propeller's sense of turning about ``d₃``.
        thrust, drag: ``k_f`` (N per (rad/s)²) and ``k_m`` (N m per (rad/s)²).
        command: ``command(q_f, v_f, t) -> (n,)`` of the frame's 12 coordinates and
            velocities: the squared speeds ``uᵢ`` (thrust input), or the motors'
            voltages with ``motors``. It may close over traced controller gains.
        motors: a :class:`MotorPropeller` for rotors with motor dynamics (coordinates
            ``rotor1 … rotorn`` after the frame's), or ``None`` for thrust input.
    """
    where = f"rotorcraft({name!r})"
    if not isinstance(frame, RigidBody):
        raise ModelError(f"{where}: frame={frame!r} is not a RigidBody.")
    if frame.loads is not None:
        raise ModelError(
            f"{where}: frame {frame.name!r} has its own applied loads; the propellers are "
            "the craft's loads — build the frame without force= or torque=."
        )
    pts, s = _arms(where, arms, senses)
    props = Propellers(
        tuple(map(tuple, pts.tolist())),
        tuple(s.tolist()),
        positive(where, "thrust", thrust),
        positive(where, "drag", drag),
    )
    if not callable(command):
        raise ModelError(f"{where}: command={command!r} must be a function (q_f, v_f, t) -> (n,).")
    probe = np.shape(command(jnp.asarray(_rest()), jnp.zeros(12), 0.0))
    if probe != (props.count,):
        raise ModelError(
            f"{where}: command(q_f, v_f, t) returned shape {probe}; it must give one value "
            f"per propeller, shape ({props.count},)."
        )
    coords = tuple(f"{frame.name}.{c}" for c in COORDS)
    if motors is None:
        lagrangian = frame.inertial
    else:
        coords += tuple(f"rotor{i + 1}" for i in range(props.count))
        lagrangian = _Lagrangian(frame.inertial, props.senses, motors.inertia)
    return LagrangeDiracSystem(
        coords,
        lagrangian,
        force=_force(props, command, motors),
        holonomic=lambda q: orthonormality(q[:12]),
        holonomic_names=tuple(f"{frame.name}.{r}" for r in ORTHONORMALITY),
        name=name,
    )


def _rest():
    return np.concatenate([np.zeros(3), np.eye(3).reshape(9)])


def momenta(frame: RigidBody, senses, motors: MotorPropeller | None, q, v) -> np.ndarray:
    r"""``p = ∂L/∂v`` at ``(q, v)``: the frame's ``M̄ v_f`` plus, with rotors, their spin
    momenta ``pᵢ = J_r (φ̇ᵢ + sᵢ Ω₃)`` on ``φᵢ`` and ``Σ sᵢ pᵢ ∂Ω₃/∂v_f =
    Σ sᵢ pᵢ ½ (0, d₂, −d₁, 0)`` on the frame (the rotors' spin is the frame's momentum
    too). NumPy; it depends on no command, so it is computed outside a traced run."""
    q, v = np.asarray(q, dtype=np.float64), np.asarray(v, dtype=np.float64)
    pf = frame.momenta(v[:12])
    if motors is None:
        return pf
    s = np.asarray(senses, dtype=np.float64)
    spin = motors.inertia * (v[12:] + s * float(spin_rate(q[:12], v[:12])))
    coupling = 0.5 * np.concatenate([np.zeros(3), q[6:9], -q[3:6], np.zeros(3)])
    return np.concatenate([pf + (s @ spin) * coupling, spin])


__all__ = ["MotorPropeller", "Propellers", "momenta", "rotorcraft", "spin_rate"]
