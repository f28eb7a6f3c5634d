r"""A gyroscope on a gimbal: a spinning rotor on a revolute joint in a frame that hangs from a
pivot by a universal (Cardan) joint, optionally spun by a DC motor from a circuit.

The frame is a rod of length ``ℓ`` along its body axis ``a``; its tip sits on the pivot,
where a universal joint lets it turn about the vertical (precession) and about a horizontal
axis across ``a`` (nutation), not about ``a`` itself; the rotor (a disk, moments ``J_t``
across and ``J_a`` along its axis) turns on a revolute joint about ``a`` at the rod's
end. With the axis horizontal, a rotor spinning at ``ω_s`` relative to the frame and the
pair precessing about the vertical at

    Ω_p = M g ℓ_c / (J_a ω_s),     M ℓ_c = m_f ℓ/2 + m_r ℓ     (the gravity moment)

is an **exact** solution (steady precession): the angular momentum about the pivot is
``J_a ω_s a + I_⊥ Ω_p ẑ`` (both bodies symmetric about ``a``), whose rate
``J_a ω_s Ω_p ẑ × a`` is gravity's torque ``M g ℓ_c ẑ × a`` — the gyroscopic formula,
exact at a horizontal axis (the ``cos θ`` term of the heavy top's steady precession
vanishes there). The axis is then ``a(t) = (cos Ω_p t, sin Ω_p t, 0)``.

With a motor across the rotor's joint driven by ``V = K ω_s`` through a resistor, the
back-emf balances the source, no current flows, and the same motion is exact.
"""

from __future__ import annotations

import numpy as np

from ..components import Multibody, RigidBody

#: frame (rod) mass and length, rotor mass and moments (across, along), gravity
FRAME_MASS, LENGTH, ROTOR_MASS, ROTOR_ACROSS, ROTOR_ALONG, GRAVITY = (
    0.2,
    0.1,
    0.5,
    3.5e-4,
    6.25e-4,
    9.81,
)
#: body z → world x, body y → −world y: the axis horizontal along x at t = 0
LEVEL = np.array([[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]])
#: the pivot's world frame: its first axis vertical (precession), its third along y
PIVOT_AXES = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])


def precession_rate(spin: float, gravity: float = GRAVITY) -> float:
    """``Ω_p = M g ℓ_c / (J_a ω_s)`` of the steady precession at a horizontal axis."""
    moment = (FRAME_MASS * LENGTH / 2 + ROTOR_MASS * LENGTH) * gravity
    return moment / (ROTOR_ALONG * spin)


def precession_axis(t, spin: float) -> np.ndarray:
    """The rotor axis ``(cos Ω_p t, sin Ω_p t, 0)`` of the steady precession (…, 3)."""
    angle = precession_rate(spin) * np.asarray(t)
    return np.stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)], axis=-1)


def gyroscope(spin: float = 150.0, precession: float | None = None, name: str = "gyro"):
    """The gimballed gyroscope as a :class:`~diracvi.components.Multibody` (bodies
    ``frame`` and ``rotor``, joints ``gimbal`` and ``hub``), axis level along x, the rotor
    spinning at ``spin`` (rad/s, relative to the frame) and both precessing about the
    vertical at ``precession`` (default: the steady rate, :func:`precession_rate`)."""
    rate = precession_rate(spin) if precession is None else float(precession)
    rod_across = FRAME_MASS * LENGTH**2 / 12
    frame = RigidBody(
        FRAME_MASS,
        (rod_across, rod_across, 0.1 * rod_across),
        name="frame",
        com=(0.0, 0.0, LENGTH / 2),
        frames={"hub": (0.0, 0.0, LENGTH)},
        gravity=(0.0, 0.0, -GRAVITY),
    )
    rotor = RigidBody(
        ROTOR_MASS,
        (ROTOR_ACROSS, ROTOR_ACROSS, ROTOR_ALONG),
        name="rotor",
        gravity=(0.0, 0.0, -GRAVITY),
    )
    mb = Multibody(name)
    vertical = np.array([0.0, 0.0, rate])
    mb.add(frame, orientation=LEVEL, omega=vertical)
    hub = np.array([LENGTH, 0.0, 0.0])
    mb.add(
        rotor,
        position=hub,
        orientation=LEVEL,
        velocity=np.cross(vertical, hub),
        omega=vertical + spin * LEVEL[:, 2],
    )
    pivot = mb.world_frame("pivot", axes=PIVOT_AXES)
    mb.joint("universal", pivot, "frame.origin", name="gimbal")
    mb.joint("revolute", "frame.hub", "rotor.origin", name="hub")
    return mb


__all__ = ["gyroscope", "precession_axis", "precession_rate"]
