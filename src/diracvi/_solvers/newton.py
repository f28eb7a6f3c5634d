r"""Newton's method on the step residual ``r(x) = 0`` with the JAX Jacobian.

Iterate ``x ← x − J(x)⁻¹ r(x)`` until the update is below ``rtol · max(‖x‖∞, ‖q‖∞)``
(ordinary convergence), or until Newton's quadratic contraction stops while the update is
already tiny (the round-off floor: further iterations cannot improve the answer).
The outcome is a :class:`SolveStatus` code, never an exception, so it can travel through
``lax.scan`` and the driver can stop cleanly at the failing step.
"""

from __future__ import annotations

import enum
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp


class SolveStatus(enum.IntEnum):
    SUCCESS = 0
    MAX_ITERATIONS = 1
    SINGULAR = 2  # the linear solve produced non-finite values from finite inputs
    NONFINITE = 3  # the model itself produced NaN/Inf


class NewtonSolver(eqx.Module):
    """Newton's method with a dense LU solve.

    Args:
        rtol: relative tolerance on the Newton update (default 1e-13).
        max_steps: iteration cap per time step (default 40).
        floor: an update below ``floor · scale`` that fails to contract further is
            accepted as converged at round-off.
    """

    rtol: float = eqx.field(static=True, default=1e-13)
    max_steps: int = eqx.field(static=True, default=40)
    floor: float = eqx.field(static=True, default=1e-9)

    def solve(self, fn: Callable, x0, scale):
        """Solve ``fn(x) = 0`` from ``x0``; returns ``(x, status, iterations, ‖r‖∞)`` with
        the residual of the last iterate evaluated."""

        def body(state):
            x, _, it, last_dx, _ = state
            r, jac = fn(x), jax.jacfwd(fn)(x)
            dx = jnp.linalg.solve(jac, -r)
            dx_norm = jnp.max(jnp.abs(dx), initial=0.0)
            x_new = x + dx
            size = jnp.maximum(jnp.max(jnp.abs(x_new), initial=0.0), scale)
            finite_r = jnp.all(jnp.isfinite(r))
            finite_dx = jnp.all(jnp.isfinite(dx))
            small = dx_norm <= self.rtol * size
            stalled = (dx_norm <= self.floor * size) & (dx_norm >= 0.5 * last_dx)
            status = jnp.where(
                ~finite_r,
                SolveStatus.NONFINITE,
                jnp.where(~finite_dx, SolveStatus.SINGULAR, jnp.where(small | stalled, 0, -1)),
            )
            x_new = jnp.where(finite_dx & finite_r, x_new, x)
            return x_new, status, it + 1, dx_norm, jnp.max(jnp.abs(r), initial=0.0)

        def cond(state):
            _, status, it, _, _ = state
            return (status == -1) & (it < self.max_steps)

        init = (x0, jnp.asarray(-1), jnp.asarray(0), jnp.asarray(jnp.inf), jnp.asarray(jnp.inf))
        # The residual reported is the one at the last Newton iterate evaluated (before its
        # update): re-evaluating at the final x would cost a residual per time step, and it
        # is only read when a step fails.
        x, status, iterations, _, res_norm = jax.lax.while_loop(cond, body, init)
        status = jnp.where(status == -1, SolveStatus.MAX_ITERATIONS, status)
        return x, status, iterations, res_norm
