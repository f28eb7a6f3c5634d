"""The paper's second example: a series RLC circuit, monolithic and torn at the capacitor.

The Lagrangian ``L = ½ L q̇_L² − q_C²/(2C)`` is degenerate (the resistor's charge has no
"mass"); Kirchhoff's current law is a constraint and the resistor a force. Both
discretizations are shown: the resistor removes energy, as it must.

Run: python examples/rlc_circuit.py [figure.png]
"""

# gallery: RLC circuit (paper §5.2)

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi import problems

torn = problems.get("rlc-torn")
mono = torn.reduced
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6), layout="constrained")
for rule in ("retraction", "midpoint"):
    traj = dv.simulate(
        torn.system, torn.q0, torn.p0, dt=torn.dt, steps=torn.steps, discretization=rule
    )
    ref = dv.simulate(
        mono.system, mono.q0, mono.p0, dt=mono.dt, steps=mono.steps, discretization=rule
    )
    diff = max(
        np.abs(np.asarray(traj[a]) - np.asarray(ref[b])).max() for a, b in torn.shared.items()
    )
    print(f"{rule}: torn vs monolithic {diff:.1e}")
    ax1.plot(traj.t, traj["cap.qC"], label=f"q_C, {rule}")
    ax2.plot(traj.t[1:], traj.energy, label=rule)
if mono.exact is not None:
    t = np.asarray(ref.t)
    ax1.plot(t, mono.exact(t)[:, mono.system.coords.index("qC")], "k:", lw=1, label="exact")
ax1.set(xlabel="t", ylabel="capacitor charge", title="torn RLC circuit")
ax1.legend(fontsize=8)
ax2.set(xlabel="t", ylabel="energy", title="the resistor dissipates")
ax2.legend(fontsize=8)
fig.savefig(figure_path("rlc_circuit.png"), dpi=100)
