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

names = list(prob.shared)
order = np.argsort([int(prob.shared[a][1:]) for a in names])
q = np.stack([np.asarray(traj[names[i]]) for i in order], axis=1)
q = q - q[0]
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
im = ax1.imshow(
    q.T, aspect="auto", origin="lower", cmap="RdBu_r", extent=[0, float(traj.t[-1]), 1, len(names)]
)
fig.colorbar(im, ax=ax1, label="q − q(0)")
ax1.set(xlabel="t", ylabel="mass", title="displacement along the chain")
ax2.plot(traj.t[1:], np.asarray(traj.energy) - float(traj.energy[0]))
ax2.set(xlabel="t", ylabel="E(t) − E(0)", title="energy error")
fig.savefig(figure_path("partitioned_chain.png"), dpi=100)
