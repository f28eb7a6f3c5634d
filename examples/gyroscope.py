"""A gyroscope spun up by a DC motor: a rotor on a revolute joint in a gimballed frame
(universal joint at the pivot), precessing under gravity. The motor across the rotor's
joint (``Multibody.motor``) is fed from a voltage source through R and L. The source
first matches the back-emf (no current: steady precession, an exact solution), then
ramps up: the motor spins the rotor faster and the precession slows, following the
gyroscopic rate ``Ω_p = M g ℓ_c / (J_a ω_s)`` through the nutation it sets off.

Run: python examples/gyroscope.py [figure.png]
"""

# gallery: Gyroscope spun up by a DC motor (rigid bodies + circuit)

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi import components as cp
from diracvi.problems.gyroscope import gyroscope, precession_rate

spin, K, R, h, steps = 150.0, 0.03, 2.0, 1e-3, 3000
mb = gyroscope(spin)  # bodies "frame" and "rotor", joints "gimbal" and "hub"
motor = mb.motor(K, "hub", name="motor")
c = cp.Circuit("drive")
c.add(
    cp.VoltageSource(cp.PWL([0.0, 0.5, 1.0], [K * spin, K * spin, 2 * K * spin]), name="V1"),
    p="vp",
    n="0",
)
c.add(cp.Resistor(R, name="R1"), p="vp", n="a")
c.add(cp.Inductor(1e-3, name="L1"), p="a", n="b")
c.add(motor, p="b", n="0")
model = mb.build(circuit=c)
traj = dv.simulate(model.system, model.q0, model.p0, dt=h, steps=steps, discretization="midpoint")

t = np.asarray(traj.t)
rotor_spin = np.gradient(model.joint_position(traj.q, "hub"), t)  # ω_s about the axis
axis = model.rotation(traj.q, "rotor")[:, :, 2]
azimuth = np.unwrap(np.arctan2(axis[:, 1], axis[:, 0]))
current = np.diff(traj[model.current_coordinate("R1")]) / h
rot = model.rotation(traj.q, "rotor")
print(f"spin {rotor_spin[0]:.1f} → {rotor_spin[-1]:.1f} rad/s; precessed {azimuth[-1]:.2f} rad")
print(f"rotor: max |RᵀR − I| = {np.max(np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3))):.1e}")

fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(13, 3.6), layout="constrained")
ax1.plot(t, rotor_spin, label=r"rotor spin $\omega_s$")
ax1.set(xlabel="t [s]", ylabel="rad/s", title="motor")
ax1b = ax1.twinx()
ax1b.plot(t[:-1] + h / 2, current, color="C1", lw=0.8, label="i(R1)")
ax1b.set_ylabel("A")
ax1.legend(loc="upper left", fontsize=8)
ax1b.legend(loc="lower right", fontsize=8)
ax2.plot(t, np.gradient(azimuth, t), lw=0.8, label="precession rate (axis azimuth)")
ax2.plot(t, precession_rate(rotor_spin), "k--", label=r"$Mg\ell_c/(J_a\omega_s)$")
ax2.set(xlabel="t [s]", ylabel="rad/s", title="precession")
ax2.legend(fontsize=8)
ax3.plot(t, np.degrees(np.arcsin(axis[:, 2])), color="C3")
ax3.set(xlabel="t [s]", ylabel="axis elevation [deg]", title="nutation")
fig.savefig(figure_path("gyroscope.png"), dpi=100)
