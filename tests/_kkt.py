"""The continuous constrained accelerations of a model with a constant mass matrix, by a
KKT solve (no step, no rule): the model side of comparisons with MuJoCo's forward
dynamics."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def constrained_accelerations(system, q, v, mass):
    r"""The continuous model's ``a = q̈``: ``[M Gᵀ; G 0] [a; λ] = [∂L/∂q − (∂²L/∂v∂q) v;
    −d²g(q + s v)/ds²]`` with the constant mass matrix ``M`` and ``G = ∂g/∂q`` (no step,
    no rule). Directional derivatives only: one compile of a few passes."""

    def g(x):
        return system.position_constraints(x, 0.0)

    @jax.jit
    def solve(q, v):
        grad_v = jax.grad(system.lagrangian, argnums=1)
        mixed_v = jax.jvp(lambda x: grad_v(x, v, 0.0), (q,), (v,))[1]
        rhs = jax.grad(system.lagrangian, argnums=0)(q, v, 0.0) - mixed_v
        jac = jax.jacfwd(g)(q)
        curvature = jax.jvp(lambda x: jax.jvp(g, (x,), (v,))[1], (q,), (v,))[1]
        k = jac.shape[0]
        kkt = jnp.block([[jnp.asarray(mass), jac.T], [jac, jnp.zeros((k, k))]])
        return jnp.linalg.solve(kkt, jnp.concatenate([rhs, -curvature]))[: q.shape[0]]

    return np.asarray(solve(jnp.asarray(q), jnp.asarray(v)))
