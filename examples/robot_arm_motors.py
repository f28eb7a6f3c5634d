"""A three-link robot arm read from URDF, each joint driven by a gear-free DC motor from the
circuit parts: a voltage source, a resistor and an inductor in a loop of its own, the motor
(``Multibody.motor``) across the joint. From rest the arm first sags under gravity, the
shoulder and elbow motors ramp up in 0.1 s and lift it while the turret's turns it about
the vertical. ``tests/test_robot_arm.py`` checks the same machine against MuJoCo's
joint-space dynamics of the same URDF file with the motors' equations (order 2).

Run: python examples/robot_arm_motors.py [figure.png]
"""

# gallery: Robot arm driven by DC motors (URDF + circuit parts)

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi.problems.robot_arm import JOINTS, RESISTANCE, robot_arm, voltage

h, steps = 2e-3, 500  # 1 s; the sources' corners (0.1, 0.2, 0.4 s) fall on the grid
model = robot_arm()  # K = 0.5 N m/A, R = 1 Ω, L = 50 mH on each joint
traj = dv.simulate(model.system, model.q0, model.p0, dt=h, steps=steps, discretization="midpoint")

t = np.asarray(traj.t)
angles = {j: model.joint_position(traj.q, j) for j in JOINTS}
currents = {j: np.diff(traj[model.current_coordinate(f"R_{j}")]) / h for j in JOINTS}
tip = model.point(traj.q, "forearm.tool")  # the tool frame's world position
for j in JOINTS:
    peak = np.max(np.abs(currents[j]))
    print(f"{j:8s} {angles[j][0]:+.3f} → {angles[j][-1]:+.3f} rad, peak |i| {peak:.2f} A")
print(f"tool tip height {tip[0, 2]:.3f} → {tip[-1, 2]:.3f} m")

fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(13, 3.6), layout="constrained")
for k, j in enumerate(JOINTS):
    ax1.plot(t, angles[j], color=f"C{k}", label=j)
    ax2.plot(t[:-1] + h / 2, currents[j], color=f"C{k}", label=f"i({j})")
    ax2.plot(t, voltage(j, t) / RESISTANCE, color=f"C{k}", ls=":", lw=0.8)
ax1.set(xlabel="t [s]", ylabel="rad", title="joint angles")
ax1.legend(fontsize=8)
ax2.set(xlabel="t [s]", ylabel="A (dotted: source V / R)", title="armature currents")
ax2.legend(fontsize=8)
ax3.plot(np.hypot(tip[:, 0], tip[:, 1]), tip[:, 2], color="C3")
ax3.plot(np.hypot(*tip[0, :2]), tip[0, 2], "ko", ms=4, label="start")
ax3.set(xlabel="reach [m]", ylabel="height [m]", title="tool tip", aspect="equal")
ax3.legend(fontsize=8)
fig.savefig(figure_path("robot_arm_motors.png"), dpi=100)
