r"""A three-link robot arm read from URDF, each joint driven by a gear-free DC motor fed by
its own armature circuit (a voltage source, a resistor and an inductor in a loop).

The arm (``robot_arm.urdf`` beside this module, :data:`ROBOT_ARM`) is a turret on a
vertical hinge (``yaw``) carrying an upper arm and a forearm on two parallel horizontal
hinges (``shoulder``, ``elbow``). Across each hinge sits :meth:`Multibody.motor
<diracvi.components.Multibody.motor>`, the ``EMF`` gyrator on the joint's relative turn,
in a loop of its own::

    L di/dt = V(t) − R i − K θ̇          (the armature: back-emf K θ̇)
    τ = K i                              (the torque on the joint: no gear)

and the bodies are the director rigid bodies of :mod:`~diracvi.components.rigid_body`
under gravity. Together, in joint space, the motion is that of

    (M(θ) + J_m) θ̈ + c(θ, θ̇) = K i,

``M`` the arm's joint-space mass matrix, ``c`` its Coriolis, centrifugal and gravity
forces, ``J_m`` the rotors' moments about their shafts (``rotor_inertia``, default 0) —
the equations ``tests/test_robot_arm.py`` builds from MuJoCo's ``M`` and ``c`` of the same
file to check this model against.

The three loops are one :class:`~diracvi.components.Circuit` that shares only the ground
node: no current passes from one loop to another (each loop's KCL closes on its own), so
each motor has its own armature circuit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..components import PWL, Circuit, Inductor, Resistor, VoltageSource
from ..components.urdf import read_urdf

#: the arm's URDF file, shipped with the package
ROBOT_ARM = Path(__file__).with_name("robot_arm.urdf")
#: the driven joints, base to tip
JOINTS = ("yaw", "shoulder", "elbow")
#: the motors' torque (= back-emf) constant K [N m/A = V s/rad], armature R [Ω] and L [H]
CONSTANT, RESISTANCE, INDUCTANCE = 0.5, 1.0, 0.05
#: the initial pose [rad] (at rest): the arm leaning forward, its elbow bent
POSITIONS = {"yaw": 0.0, "shoulder": 0.8, "elbow": 0.7}
#: each loop's source as PWL corners (times [s], volts [V]): from 0 V the shoulder and
#: elbow motors ramp in 0.1 s to lift the arm against gravity, the turret's to turn it
VOLTAGES = {
    "yaw": ((0.0, 0.2), (0.0, 1.5)),
    "shoulder": ((0.0, 0.1, 0.4), (0.0, -9.0, -8.0)),
    "elbow": ((0.0, 0.1), (0.0, -2.5)),
}


def breakpoints(voltages=VOLTAGES) -> tuple[float, ...]:
    """The sources' corners after ``t = 0`` (the times a step grid should hit, and where a
    reference integrator should restart)."""
    return tuple(sorted({float(t) for times, _ in voltages.values() for t in times[1:]}))


def voltage(joint: str, t, voltages=VOLTAGES):
    """The source of ``joint``'s loop at times ``t`` [V] (the PWL's linear interpolation)."""
    times, volts = voltages[joint]
    return np.interp(t, times, volts)


def robot_arm(
    voltages=VOLTAGES,
    positions=POSITIONS,
    constant=CONSTANT,
    resistance=RESISTANCE,
    inductance=INDUCTANCE,
    rotor_inertia=0.0,
    torn: bool = False,
    path=ROBOT_ARM,
):
    """The arm of :data:`ROBOT_ARM` with a motor across each joint, built with its circuit.

    Args:
        voltages: ``{joint: (times, volts)}`` the PWL corners of each loop's source (a
            joint left out gets no motor: it swings freely).
        positions: ``{joint: angle}`` of the initial pose (at rest, no current).
        constant, resistance, inductance: every motor's ``K``, ``R`` and ``L``.
        rotor_inertia: every rotor's moment ``J_m`` about its shaft [kg m²].
        torn: the bodies torn into subsystems (one per body, joint and motor), or one.
        path: the URDF file (its revolute joints named as in ``voltages``).

    Returns:
        The :class:`~diracvi.components.MultibodyModel`: ``model.joint_position(q,
        "shoulder")`` the joint angles, ``model.current_coordinate("R_shoulder")`` the
        coordinate whose rate is that loop's current; the motors are ``M_<joint>``, the
        sources ``V_<joint>``, the resistors ``R_<joint>``, the inductors ``L_<joint>``.
    """
    mb = read_urdf(path, positions, quiet=True)
    drive = Circuit("drive")
    for joint, (times, volts) in voltages.items():
        motor = mb.motor(constant, joint, name=f"M_{joint}", inertia=rotor_inertia)
        supply, armature, coil = f"{joint}_supply", f"{joint}_armature", f"{joint}_coil"
        drive.add(VoltageSource(PWL(times, volts), name=f"V_{joint}"), p=supply, n="0")
        drive.add(Resistor(resistance, name=f"R_{joint}"), p=supply, n=armature)
        drive.add(Inductor(inductance, name=f"L_{joint}"), p=armature, n=coil)
        drive.add(motor, p=coil, n="0")
    return mb.build(torn=torn, circuit=drive)


__all__ = [
    "CONSTANT",
    "INDUCTANCE",
    "JOINTS",
    "POSITIONS",
    "RESISTANCE",
    "ROBOT_ARM",
    "VOLTAGES",
    "breakpoints",
    "robot_arm",
    "voltage",
]
