"""A floor for one step of the torn chain: the work a minimal hand-written JAX step does.

``python benchmarks/chain_floor.py N STEPS``: N masses in pieces of 100. Per step, per
piece (vmapped as one array): the spring forces along the piece, a diagonal local solve
(the left-point rule's mass matrix), then a tridiagonal interface solve over the
2(M − 1) port slots, the momentum update, the energy and a finiteness check with a
frozen-state select. Not diracvi's equations to the bit (no Newton iteration, no
residual check): the kinds and number of passes over the state a minimal
implementation of the same step needs, to compare diracvi's time per step against.
"""

import sys
import time

import jax
import jax.numpy as jnp

jax.config.update("jax_enable_x64", True)
N, steps = int(sys.argv[1]), int(sys.argv[2])
M, P = N // 100, 100
h = 0.01
m = 1.0 + 0.5 * jnp.sin(jnp.arange(N).reshape(M, P)) ** 2
k = 1.0 + 0.3 * jnp.cos(jnp.arange(N).reshape(M, P)) ** 2
q0 = jnp.arange(N, dtype=jnp.float64).reshape(M, P) * 1e-3
p0 = jnp.zeros((M, P))
qbar0 = q0[:-1, -1]


def step(c, _):
    q, p, qbar = c
    # local: forces of each piece (the first spring hangs from the port / the wall)
    left = jnp.concatenate([jnp.zeros((1,)), qbar])[:, None]
    prev = jnp.concatenate([left, q[:, :-1]], axis=1)
    stretch = q - prev
    f = -k * stretch + jnp.concatenate([k[:, 1:] * stretch[:, 1:], jnp.zeros((M, 1))], axis=1)
    # local diagonal solve for the free (unconstrained) update, and the port responses
    q_free = q + h * (p + h * f) / m
    # interface: tridiagonal system over the 2(M-1) slots (Robin form), O(M)
    n_if = 2 * (M - 1)
    d = 2.0 + h * h / m[1:, 0].repeat(2)[:n_if]
    dl = jnp.concatenate([jnp.zeros(1), -jnp.ones(n_if - 1)])
    du = jnp.concatenate([-jnp.ones(n_if - 1), jnp.zeros(1)])
    rhs = jnp.stack([q_free[:-1, -1], q_free[1:, 0]], axis=1).reshape(-1)
    g = jax.lax.linalg.tridiagonal_solve(dl, d, du, rhs[:, None])[:, 0].reshape(M - 1, 2)
    lam = g[:, 0] - g[:, 1]
    q1 = q_free.at[:-1, -1].add(-h * h * lam / m[:-1, -1]).at[1:, 0].add(h * h * lam / m[1:, 0])
    p1 = m * (q1 - q) / h
    qbar1 = q1[:-1, -1]
    energy = 0.5 * jnp.sum(p1 * p1 / m) + 0.5 * jnp.sum(k * stretch**2)
    ok = jnp.all(jnp.isfinite(q1)) & jnp.all(jnp.isfinite(p1))
    q1, p1 = jnp.where(ok, q1, q), jnp.where(ok, p1, p)
    return (q1, p1, qbar1), (energy, ok)


run = jax.jit(lambda c: jax.lax.scan(step, c, None, length=steps))
jax.block_until_ready(run((q0, p0, qbar0)))  # compile
ts = []
for _ in range(3):
    t0 = time.perf_counter()
    jax.block_until_ready(run((q0, p0, qbar0)))
    ts.append(time.perf_counter() - t0)
print(f"hand step N={N}: min {min(ts) / steps * 1e3:.2f} ms/step, all {[t / steps for t in ts]}")
