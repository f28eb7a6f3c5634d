"""A DC motor swinging a pendulum, built from parts: a ramped voltage source, the armature
resistance and inductance, an EMF (the gyrator ``τ = K i``, ``e = K θ̇``) and a pendulum
on the motor's shaft. The voltage ramps to 2 V, which stalls the motor where its torque
``K V/R`` balances gravity ``m g ℓ sin θ``.

Run: python examples/motor_pendulum.py [figure.png]
"""

# gallery: DC motor driving a pendulum, built from parts

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi import components as cp
from diracvi.spice import waveforms

R, L, K, m, ell, g = 1.0, 0.05, 0.5, 0.5, 0.4, 9.81
c = cp.Circuit("motor_pendulum")
c.add(cp.VoltageSource(cp.PWL([0.0, 0.2], [0.0, 2.0]), name="V1"), p="vp", n="0")
c.add(cp.Resistor(R, name="R1"), p="vp", n="b")
c.add(cp.Inductor(L, name="L1"), p="b", n="c")
c.add(cp.EMF(K, name="emf"), p="c", n="0", flange="shaft")
c.add(cp.Pendulum(m, ell, g, name="arm"), flange="shaft")
built = c.build()
traj = dv.simulate(built.system, built.q0, built.p0, dt=2e-3, steps=2000, discretization="midpoint")
w = waveforms(built, traj)
theta = traj["arm.x"]
print("coordinates:", built.system.coords)
balance = np.arcsin(K * 2.0 / R / (m * g * ell))  # K V/R = m g ℓ sin θ
print(f"final angle {theta[-1]:.4f} rad; torque balance predicts {balance:.4f}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
ax1.plot(traj.t, w["v(vp)"], label="v(vp) source")
ax1.plot(traj.t, w["v(c)"], label=r"v(c) back-emf $K\dot\theta$")  # mathtext: θ̇'s dot shows
ax1.plot(traj.t, w["i(R1)"], label="i(R1) armature current")
ax1.set(xlabel="t [s]", ylabel="v [V], i [A]", title="electrical side")
ax1.legend(fontsize=8)
ax2.plot(traj.t, theta, color="C3")
ax2.axhline(balance, color="0.6", ls="--", label="torque balance")
ax2.set(xlabel="t [s]", ylabel="θ [rad]", title="pendulum on the shaft")
ax2.legend(fontsize=8)
fig.savefig(figure_path("motor_pendulum.png"), dpi=100)
