r"""Newton's method on the step residual ``r(x) = 0`` with the JAX Jacobian.

Iterate ``x ← x − J⁻¹ r(x)`` until the update is below ``rtol · max(‖x‖∞, ‖q‖∞)``
(ordinary convergence), or until Newton's quadratic contraction stops while the update is
already tiny (the round-off floor: further iterations cannot improve the answer).

With ``reuse_jacobian=True`` (the default) the LU factors of ``J`` are kept from one
iteration and one time step to the next — the simplified (chord) Newton method — and
recomputed only when they stop paying: when an update contracts by less than
``1/contraction`` against the previous one. A step whose extrapolated guess already
satisfies the equations therefore costs one residual and one pair of triangular solves;
a linear problem factorizes once per chunk. The contraction test is also the
convergence safeguard: an update that grows with stale factors is discarded, and
round-off stagnation is only accepted with fresh factors.

The outcome is a :class:`SolveStatus` code, never an exception, so it can travel through
``lax.scan`` and the driver can stop cleanly at the failing step.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl

from .base import SolveStatus, StepResult, StepSolver, check_newton_options


def _norm(tree):
    """``‖·‖∞`` over every leaf of a PyTree of arrays."""
    return jnp.max(jnp.stack([jnp.max(jnp.abs(a), initial=0.0) for a in jax.tree.leaves(tree)]))


def _finite(tree):
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(a)) for a in jax.tree.leaves(tree)]))


def chord_newton(options, residual, factorize, correction, x0, factors, valid, scale):
    """The (simplified) Newton iteration shared by the step solvers.

    ``residual(x)`` is the step residual, ``factorize(x)`` the factors of its Jacobian
    and ``correction(factors, r)`` the update ``−J⁻¹ r``; ``x`` may be any PyTree of
    arrays. ``options`` carries ``rtol``, ``max_steps``, ``floor``, ``reuse_jacobian`` and
    ``contraction`` (see :class:`NewtonSolver`). Returns ``(x, status, iterations,
    ‖r‖∞, factors)`` with the residual of the last iterate evaluated.
    """

    def body(carry):
        x, _, it, last_dx, _, factors, valid = carry
        r = residual(x)
        refactor = ~valid
        if not options.reuse_jacobian:
            refactor = jnp.asarray(True)
        factors = jax.lax.cond(refactor, factorize, lambda _: factors, x)
        dx = correction(factors, r)
        dx_norm = _norm(dx)
        size = jnp.maximum(_norm(jax.tree.map(jnp.add, x, dx)), scale)
        finite_r = _finite(r)
        finite_dx = _finite(dx)
        # Stale factors that fail to contract are replaced; a growing update is dropped.
        slow = ~refactor & (dx_norm > options.contraction * last_dx)
        diverging = ~refactor & ((dx_norm >= last_dx) | ~finite_dx)
        small = dx_norm <= options.rtol * size
        stalled = refactor & (dx_norm <= options.floor * size) & (dx_norm >= 0.5 * last_dx)
        done = (small & ~diverging) | stalled
        status = jnp.where(
            ~finite_r,
            SolveStatus.NONFINITE,
            jnp.where(
                ~finite_dx & refactor,
                SolveStatus.SINGULAR,
                jnp.where(done & finite_dx, SolveStatus.SUCCESS, -1),
            ),
        )
        keep = finite_dx & finite_r & ~diverging
        x_new = jax.tree.map(lambda a, b: jnp.where(keep, a + b, a), x, dx)
        last = jnp.where(keep, dx_norm, last_dx)
        valid = ~(slow | diverging)
        return x_new, status, it + 1, last, _norm(r), factors, valid

    def cond(carry):
        _, status, it = carry[:3]
        return (status == -1) & (it < options.max_steps)

    inf = jnp.asarray(jnp.inf, dtype=scale.dtype)
    init = (x0, jnp.asarray(-1), jnp.asarray(0), inf, inf, factors, valid)
    # The residual reported is the one at the last Newton iterate evaluated (before its
    # update): re-evaluating at the final x would cost a residual per time step, and it
    # is only read when a step fails.
    x, status, iterations, _, res_norm, factors, _ = jax.lax.while_loop(cond, body, init)
    status = jnp.where(status == -1, SolveStatus.MAX_ITERATIONS, status)
    return x, status, iterations, res_norm, factors


class NewtonSolver(StepSolver):
    """Newton's method with a dense LU solve.

    Args:
        rtol: relative tolerance on the Newton update (default 1e-13).
        max_steps: iteration cap per time step (default 40).
        floor: an update below ``floor · scale`` that fails to contract further (with a
            freshly factorized Jacobian) is accepted as converged at round-off.
        reuse_jacobian: keep the factorized Jacobian across iterations and time steps
            while it still contracts (default True); False recomputes it every iteration.
        contraction: with reused factors, an update must shrink at least this much
            (``‖dx_j‖ ≤ contraction · ‖dx_{j−1}‖``) or the Jacobian is recomputed.
    """

    rtol: float = eqx.field(static=True, default=1e-13)
    max_steps: int = eqx.field(static=True, default=40)
    floor: float = eqx.field(static=True, default=1e-9)
    reuse_jacobian: bool = eqx.field(static=True, default=True)
    contraction: float = eqx.field(static=True, default=0.25)

    def __check_init__(self):
        check_newton_options(self)

    def init(self, eqs):
        size = eqs.size
        return (
            jnp.zeros((size, size), dtype=eqs.q.dtype),
            jnp.zeros(size, dtype=jnp.int32),
            jnp.asarray(False),
        )

    def solve(self, eqs, guess, state) -> StepResult:
        """Solve ``eqs.residual(x) = 0`` from ``guess``."""
        fn = eqs.residual

        def factorize(x):
            return jsl.lu_factor(jax.jacfwd(fn)(x))

        lu, piv, valid = state
        x, status, iterations, res_norm, (lu, piv) = chord_newton(
            self,
            fn,
            factorize,
            lambda factors, r: jsl.lu_solve(factors, -r),
            guess,
            (lu, piv),
            valid,
            eqs.scale(),
        )
        return StepResult(x, status, iterations, res_norm, (lu, piv, status == 0))
