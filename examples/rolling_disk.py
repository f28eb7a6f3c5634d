"""A vertical disk rolling without slipping: two nonholonomic constraints
``ẋ = R cos φ θ̇``, ``ẏ = R sin φ θ̇``, kept to round-off by the discrete Dirac integrator.

(``examples/rolling_disk_long_run.py`` runs it for 10⁶ steps.)

Run: python examples/rolling_disk.py [figure.png]
"""

# gallery: Rolling disk (nonholonomic)

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi import problems

prob = problems.get("rolling-disk")
traj = dv.simulate(prob.system, prob.q0, prob.p0, dt=prob.dt, steps=5 * prob.steps)
violation = np.abs(np.asarray(traj.constraint_violation)).max()
print(f"max constraint violation {violation:.1e}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
ax1.plot(traj["x"], traj["y"])
ax1.set(xlabel="x", ylabel="y", title="path of the contact point", aspect="equal")
energy_error = np.abs(np.asarray(traj.energy) - float(traj.energy[0]))
ax2.semilogy(traj.t[1:], np.abs(np.asarray(traj.constraint_violation)) + 1e-17, label="constraint")
ax2.semilogy(traj.t[1:], energy_error + 1e-17, label="|E(t) − E(0)|")
ax2.set(xlabel="t", ylabel="size", title="constraint violation and energy error")
ax2.legend(fontsize=8)
fig.savefig(figure_path("rolling_disk.png"), dpi=100)
