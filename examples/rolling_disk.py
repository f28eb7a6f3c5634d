"""A vertical disk rolling without slipping: two nonholonomic constraints
``ẋ = R cos φ θ̇``, ``ẏ = R sin φ θ̇``, kept to round-off by the discrete Dirac integrator
under either rule. The energy is another matter: the left-point ``"retraction"`` rule
takes a little of it at every step (the disk slows down), the time-symmetric
``"midpoint"`` rule keeps it (here to 1e-9 of E; ``docs/discretizations.md``, "Long
runs").

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
runs = {
    rule: dv.simulate(
        prob.system, prob.q0, prob.p0, dt=prob.dt, steps=5 * prob.steps, discretization=rule
    )
    for rule in ("retraction", "midpoint")
}
for rule, traj in runs.items():
    violation = np.abs(np.asarray(traj.constraint_violation)).max()
    drift = abs(float(traj.energy[-1]) / float(traj.energy[0]) - 1.0)
    print(f"{rule}: max constraint violation {violation:.1e}, energy change {drift:.1e}")

fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), layout="constrained")
traj = runs["midpoint"]
ax1.plot(traj["x"], traj["y"])
ax1.set(xlabel="x", ylabel="y", title="path of the contact point (midpoint)", aspect="equal")
for (rule, traj), color in zip(runs.items(), ("C1", "C0"), strict=True):
    energy_error = np.abs(np.asarray(traj.energy) - float(traj.energy[0]))
    violation = np.abs(np.asarray(traj.constraint_violation))
    # + 1e-17: an exact zero has no place on a log axis
    ax2.semilogy(traj.t[1:], energy_error + 1e-17, color=color, label=f"|E(t) − E(0)|, {rule}")
    ax2.semilogy(
        traj.t[1:], violation + 1e-17, color=color, lw=0.6, alpha=0.6, label=f"constraint, {rule}"
    )
ax2.set(xlabel="time t", ylabel="size", title="energy error and constraint violation")
# in the band between 1e-8 and 1e-4, which no curve crosses after the first second
ax2.legend(fontsize=8, loc="center right", bbox_to_anchor=(1.0, 0.66))
fig.savefig(figure_path("rolling_disk.png"), dpi=100)
