"""How each discretization treats the vertical rolling disk over a long run (T = 1000).

Run: python examples/rolling_disk_long_run.py   (about 10 s)
Prints, for each rule and step: energy drift, rolling rate at the end (exact: constant),
position error against the closed form, and the largest discrete-constraint residual.
"""

import numpy as np

import diracvi as dv
from diracvi import problems

problem = problems.get("rolling-disk")
print(
    f"exact rolling rate {problem.parameters['Omega']}, turning rate {problem.parameters['omega']}"
)
for discretization in ("retraction", "midpoint"):
    for h in (0.01, 0.05):
        traj = dv.simulate(
            problem.system,
            problem.q0,
            problem.p0,
            dt=h,
            steps=round(1000 / h),
            discretization=discretization,
        )
        energy = traj.energy
        roll = np.diff(traj["theta"]) / h
        error = np.max(np.abs(traj.q[-1, :2] - problem.exact(traj.t[-1:])[0, :2]))
        drift = (energy[-1] - energy[0]) / energy[0]
        print(
            f"{discretization:10s} h={h:<5} energy change {drift:+.2e}"
            f"  rolling rate {roll[0]:.6f} -> {roll[-1]:.6f}  position error {error:.2e}"
            f"  max |ω_d| {np.max(np.abs(traj.constraint_residual)):.1e}"
        )
