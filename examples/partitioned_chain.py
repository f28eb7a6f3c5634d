"""A chain of 200 masses torn into 4 pieces, stepped by the partitioned solver (block
elimination over the pieces, a small interface system), checked against dense Newton.

(``examples/partitioned_scaling.py`` times it up to 10⁶ masses.)

Run: python examples/partitioned_chain.py [figure.png]
"""

# gallery: Partitioned chain (200 masses, 4 pieces)

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi import problems

prob = problems.chain_torn(masses=200, pieces=4, steps=200)
traj = dv.simulate(
    prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps, solver=dv.PartitionedSolver()
)
dense = dv.simulate(prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps)
print(
    f"solvers: {traj.solver} vs {dense.solver}; "
    f"max difference {np.abs(np.asarray(traj.q) - np.asarray(dense.q)).max():.1e}"
)

names = sorted(prob.shared, key=lambda a: int(prob.shared[a][1:]))  # q1 … qN in order
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
for i in (0, len(names) // 4, len(names) // 2, 3 * len(names) // 4, len(names) - 1):
    q = np.asarray(traj[names[i]])
    ax1.plot(traj.t, q - q[0], label=f"mass {i + 1} ({names[i]})")
ax1.set(xlabel="t", ylabel="q(t) − q(0)", title="displacements along the chain")
ax1.legend(fontsize=7)
ax2.plot(traj.t[1:], np.asarray(traj.energy) - float(traj.energy[0]))
ax2.set(xlabel="t", ylabel="E(t) − E(0)", title="energy error")
fig.savefig(figure_path("partitioned_chain.png"), dpi=100)
