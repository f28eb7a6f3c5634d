"""A DC motor: an electrical armature (source, resistor, inductor) and a mechanical rotor
joined through a gyrator (``τ = K i``, ``e = K ω``) — three subsystems, one interconnection.

Run: python examples/dc_motor.py [figure.png]
"""

# gallery: DC motor (electromechanical)

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi import problems

prob = problems.get("dc-motor")
traj = dv.simulate(prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps)
t = np.asarray(traj.t)
current = np.gradient(np.asarray(traj["armature.qL"]), t)
speed = np.gradient(np.asarray(traj["rotor.theta"]), t)
print(f"final current {current[-1]:.3f}, final speed {speed[-1]:.3f}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
ax1.plot(t, current)
ax1.set(xlabel="time t (s)", ylabel="armature current i (A)", title="electrical side")
ax2.plot(t, speed, color="C1")
ax2.set(xlabel="time t (s)", ylabel="rotor speed ω (rad/s)", title="mechanical side")
fig.savefig(figure_path("dc_motor.png"), dpi=100)
