"""Discrete-mechanics optimal control: bring a pendulum from rest to rest at 60°.

Run: python examples/optimal_control_pendulum.py [OUT.png]   (about 20 s)

A pendulum (``L = ½ θ̇² + g cos θ``) is driven by a torque ``F(q, v, t) = u(t)`` that is
piecewise constant over ``N = 10`` intervals of ``[0, T]``. The controls minimize

    J(u) = (θ_T − θ*)² + p_T² + ε Σ u_j² Δt

over the discrete Dirac (variational) trajectory itself: ``dv.simulate`` is
differentiated in reverse mode (implicit-function derivatives of each step), and L-BFGS
(``optax.lbfgs``) drives ``J`` down until the final state is the target (θ* = π/3, at
rest) to about 1e-3.
"""

from __future__ import annotations

import sys

import jax
import jax.numpy as jnp
import numpy as np
import optax

import diracvi as dv

G = 9.81
TARGET = np.pi / 3
T, STEPS, N = 2.0, 100, 10
EPS = 1e-5


def pendulum(controls):
    """The driven pendulum; ``controls`` (N,) are the torques on the N intervals."""

    def lagrangian(q, v):
        return 0.5 * v[0] ** 2 + G * jnp.cos(q[0])

    def torque(q, v, t):
        j = jnp.clip(jnp.floor(t / (T / N)).astype(jnp.int32), 0, N - 1)
        return jnp.stack([controls[j]])

    return dv.LagrangeDiracSystem(("theta",), lagrangian, force=torque, name="pendulum")


def run(controls, steps=STEPS, throw=True):
    return dv.simulate(
        pendulum(controls),
        jnp.zeros(1),
        jnp.zeros(1),
        dt=T / steps,
        steps=steps,
        discretization="midpoint",
        throw=throw,
    )


def cost(controls, steps=STEPS):
    # throw=False: a failed step gives J = inf (the line search rejects that trial point)
    # instead of equinox's host-callback check, whose callbacks JAX 0.10 lowers partly as
    # untyped XLA custom calls inside optax's jitted L-BFGS step, so that step does not
    # compile ("No registered implementation for untyped custom call to
    # xla_ffi_python_cpu_callback"; docs/gradients.md)
    traj = run(controls, steps, throw=False)
    j = (traj.q[-1, 0] - TARGET) ** 2 + traj.p[-1, 0] ** 2 + EPS * jnp.sum(controls**2) * (T / N)
    return jnp.where(jnp.all(traj.status == 0), j, jnp.inf)


def optimize(iterations=15, steps=STEPS):
    """L-BFGS from zero torque (one compiled iteration, line search included); returns
    (controls, history of J)."""

    def f(controls):
        return cost(controls, steps)

    opt = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(f)

    @jax.jit
    def step(controls, state):
        value, grad = value_and_grad(controls, state=state)
        updates, state = opt.update(grad, state, controls, value=value, grad=grad, value_fn=f)
        return optax.apply_updates(controls, updates), state, value

    controls = jnp.zeros(N)
    state = opt.init(controls)
    history = []
    for _ in range(iterations):
        controls, state, value = step(controls, state)
        history.append(float(value))
    history.append(float(jax.jit(f)(controls)))
    return controls, np.array(history)


def main(out="optimal_control_pendulum.png"):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    controls, history = optimize()
    traj = run(controls)
    theta_t, p_t = float(traj.q[-1, 0]), float(traj.p[-1, 0])
    print(f"J: {history[0]:.3e} -> {history[-1]:.3e} in {len(history) - 1} L-BFGS iterations")
    print(f"final state θ_T = {theta_t:.5f} (target {TARGET:.5f}), p_T = {p_t:.2e}")
    fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.2))
    a.plot(np.asarray(traj.t), np.asarray(traj.q[:, 0]), label="θ(t)")
    a.axhline(TARGET, ls="--", c="k", lw=0.8, label="target")
    a.step(np.linspace(0, T, N + 1), np.r_[controls, controls[-1]], where="post", label="u(t)")
    a.set_xlabel("t")
    a.legend(fontsize=8)
    b.semilogy(history)
    b.set_xlabel("L-BFGS iteration")
    b.set_ylabel("J")
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
