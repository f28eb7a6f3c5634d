"""A quadrotor whose controller is tuned by ``jax.grad`` through the simulation.

The craft (``diracvi.problems.quadrotor``) is a rigid frame in the director form with four
DC motor–propeller rotors (16 coordinates: the frame's 12 and the rotors' angles; the
rotors' spin is part of the frame's angular momentum, a gyrostat); thrust ``k_f ω²`` and
the drag torque ``k_m ω²`` enter through one force port. Lee–Leok–McClamroch's geometric
controller, read from the directors (no Euler angles), turns the position and attitude
errors into the four motor voltages. Its gains ``(k_x, k_v, k_R, k_Ω)`` are tuned by
gradient descent on the mean squared distance to a waypoint over a 2 s flight from hover
— the gradient is ``jax.grad`` of that loss through ``dv.simulate`` (every step
differentiated by the implicit function theorem).

Run: python examples/quadrotor.py [figure.png]   (about 50 s, most of it one compile)
"""

# gallery: Quadrotor with motor–propeller rotors, controller tuned by jax.grad

import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

import diracvi as dv
from diracvi.problems import quadrotor as quad

dt, duration = 0.01, 2.0
# a rotor turns ~5 rad per step and Newton's test is relative to the step's largest
# increment: rtol=1e-16 keeps the frame's orthonormality rows near round-off
theta, history, runs = quad.tune(
    jnp.log(jnp.asarray(quad.GAINS)),
    iterations=10,
    dt=dt,
    duration=duration,
    solver=dv.NewtonSolver(rtol=1e-16),
)
gains = np.exp(np.asarray(theta))
print(f"loss {history[0]:.4f} → {history[-1]:.4f} m² in {len(history) - 1} accepted steps")
print("gains (k_x, k_v, k_R, k_Ω):", np.round(quad.GAINS, 2), "→", np.round(gains, 2))
first, best = runs[0], runs[-1]
rot = np.swapaxes(best[:, 3:12].reshape(-1, 3, 3), 1, 2)
print(f"frame: max |RᵀR − I| = {np.max(np.abs(np.swapaxes(rot, 1, 2) @ rot - np.eye(3))):.1e}")

t = dt * np.arange(len(best))
fig, (ax1, ax2, ax3) = plt.subplots(1, 3, figsize=(13, 3.6), layout="constrained")
for q, style, label in ((first, "--", "initial gains"), (best, "-", "tuned")):
    for i, axis in enumerate("xyz"):
        ax1.plot(t, q[:, i], style, color=f"C{i}", label=f"{axis} ({label})")
for i, w in enumerate(quad.WAYPOINT):
    ax1.axhline(w, color=f"C{i}", lw=0.5, ls=":")
ax1.set(xlabel="t [s]", ylabel="position [m]", title="hover → waypoint")
ax1.legend(fontsize=7, ncol=2)
speeds = np.diff(best[:, 12:16], axis=0) / dt  # the rotors' speeds over each step
ax2.plot(t[:-1] + dt / 2, speeds, lw=0.8)
ax2.set(xlabel="t [s]", ylabel="rad/s", title="rotor speeds (tuned)")
ax3.semilogy(history, "o-")
ax3.set(xlabel="accepted gradient step", ylabel="loss [m²]", title="tuning")
fig.savefig(figure_path("quadrotor.png"), dpi=100)
