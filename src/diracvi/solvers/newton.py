r"""Newton's method on the step residual ``r(x) = 0`` with the JAX Jacobian.

Iterate ``x ← x − J⁻¹ r(x)`` until every unknown's update is below ``rtol`` times the
step's increment ``‖x − x_ref‖∞`` (``x_ref`` the known state: ``q_other = q``, multipliers
0) plus that unknown's own round-off (ordinary convergence), or until Newton's quadratic
contraction stops while the update is already tiny (the round-off floor: further
iterations cannot improve the answer). The increment, not ``‖x‖∞``, is the measure
because the step's velocities are differences of the unknowns: an unknown that grows
without bound (a rolling angle, an inductor's charge) must not loosen the test.

With ``reuse_jacobian=True`` (the default) the LU factors of ``J`` are kept from one
iteration and one time step to the next — the simplified (chord) Newton method — and
recomputed only when they stop paying: when an update contracts by less than
``1/contraction`` against the previous one. A step whose extrapolated guess already
satisfies the equations therefore costs one residual and one pair of triangular solves;
a linear problem factorizes once per chunk. The contraction test is also the
convergence safeguard: an update that grows with stale factors is discarded, and
round-off stagnation is only accepted with fresh factors.

Three safeguards make nonlinear steps (exponential junctions) robust.

**A residual at round-off is success**: when every equation's residual is within
``residual_rtol`` of the size of its terms,
``|r_i| ≤ residual_rtol · (|p_i| + Σ_j |J_ij| |x_j − x_ref,j|)`` (``p`` the known
momentum, ``x_ref`` the known state: the terms' size, linearized over the step), with a
Jacobian freshly formed at the iterate, the iterate is accepted whatever the update does
— an ill-conditioned Jacobian (a floating node held by ``G_min``) makes updates noisy
long after the residual has reached round-off.

**Junction limiting**: a system whose parts declare junction coordinates
(:mod:`diracvi.solvers.limiting`) has each Newton iterate's junction voltages limited
as SPICE's ``pnjlim`` does, so an exponential is never evaluated far beyond the last
iterate (without it Newton cycles between two iterates on a diode turning on).

**A fresh Jacobian before giving up**: the last quarter of the iteration budget
recomputes the Jacobian every iteration (full Newton), so stale factors never cause a
failure. ``NewtonSolver(reuse_jacobian=False)`` is full Newton throughout.

The outcome is a :class:`SolveStatus` code, never an exception, so it can travel through
``lax.scan`` and the driver can stop cleanly at the failing step.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl

from ..runtime import small_loops
from ..runtime.compile import fast_compile
from . import small_lu
from .base import SolveStatus, StepResult, StepSolver, check_newton_options
from .limiting import junction_limiter


def _norm(tree):
    """``‖·‖∞`` over every leaf of a PyTree of arrays."""
    return jnp.max(jnp.stack([jnp.max(jnp.abs(a), initial=0.0) for a in jax.tree.leaves(tree)]))


def _finite(tree):
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(a)) for a in jax.tree.leaves(tree)]))


# An update within this many units in the last place of its unknown is round-off.
_ULPS = 4.0


def _converged(rtol, x, dx, reference, factor=1.0):
    r"""The stopping test relative to the step's increment, unknown by unknown:

    ``|dx_i| ≤ rtol · ‖x + dx − x_ref‖∞ + 4 ε |x_i + dx_i|``.

    ``factor`` scales ``|dx_i|``: ``θ``, the observed chord contraction, tests the
    *next* update as predicted (``NewtonSolver.predict_stop``). (Scaling the update by
    ``θ/(1 − θ)`` clipped to ``[1/20, 1]``, as Hairer & Wanner IV.8 do, with ``θ`` also
    measured across a refactorization, saved about one iteration in ten but accepted
    iterates that moved a ``ddt`` source's output by 1e-9 and tore the partitioned and
    dense solves apart by 2.4e-12: not adopted as the default.)

    The unknowns are the far end ``q_{k+1}`` (and stage values) and the multipliers,
    and the step's velocities are their differences from the known ``q_k`` over ``h``.
    Measured against ``‖x‖∞`` instead, an unknown that grows without bound (a rolling
    angle, an inductor's charge) loosens the test for every other one: at an angle of
    10³ rad and ``rtol = 1e-13`` a chord iterate 1e-10 from the solution passes, which
    is a velocity error of 1e-8 at ``h = 0.01`` and an energy drift of 1e-7 over 10⁵
    steps. The second term is each unknown's own round-off, below which no update can
    be asked to fall.
    """
    eps = jnp.finfo(jnp.result_type(*jax.tree.leaves(x))).eps
    new = jax.tree.map(jnp.add, x, dx)
    increment = _norm(jax.tree.map(jnp.subtract, new, reference))
    within = jax.tree.map(
        lambda d, n: jnp.all(factor * jnp.abs(d) <= rtol * increment + _ULPS * eps * jnp.abs(n)),
        dx,
        new,
    )
    return jnp.all(jnp.stack(jax.tree.leaves(within)))


def _within(dx, atol):
    r"""The absolute stopping test: every update within its own bound, ``|dx_i| ≤ atol_i``.

    For a caller that reads the solution only to a known accuracy (the variable-step
    loop's coarse step, read through the step-doubling difference:
    :mod:`diracvi.driver.adaptive`). The caller takes it only on an update that shrank
    by ``θ ≤ contraction`` (0.25) against the one before it in the same solve: the
    iteration then contracts, and the error left after the update is at most
    ``θ/(1 − θ) ≤ 1/3`` of it. The size of an update alone bounds nothing before
    Newton's asymptotic phase (a diode turning on within the step stopped 1.5–7 times
    its bound off the solution on the first update within it).
    """
    within = jax.tree.map(lambda d, a: jnp.all(jnp.abs(d) <= a), dx, atol)
    return jnp.all(jnp.stack(jax.tree.leaves(within)))


def chord_newton(
    options,
    residual,
    factorize,
    correction,
    x0,
    factors,
    valid,
    scale,
    *,
    limit=None,
    row_scale=None,
    reference=None,
    atol=None,
):
    """The (simplified) Newton iteration shared by the step solvers.

    ``residual(x)`` is the step residual, ``factorize(x)`` the factors of its Jacobian
    and ``correction(factors, r)`` the update ``−J⁻¹ r``; ``x`` may be any PyTree of
    arrays. ``options`` carries ``rtol``, ``max_steps``, ``floor``, ``reuse_jacobian`` and
    ``contraction`` (see :class:`NewtonSolver`). Returns ``(x, status, iterations,
    ‖r‖∞, factors)`` with the residual of the last iterate evaluated.

    ``limit(x, x_new)`` (optional) limits an iterate (junction voltages, see
    :mod:`~diracvi.solvers.limiting`); ``row_scale(factors, x)`` (optional) gives each
    equation's size at ``x``, which enables the round-off residual test. ``reference``
    (optional, shaped as ``x``) is the known state as unknowns (``q_other = q``, every
    multiplier 0): with it the update is measured against the step's increment
    ``‖x − reference‖∞`` instead of ``‖x‖∞`` (see :func:`_converged`). ``atol``
    (optional, shaped as ``x``): an absolute bound per unknown; an iterate whose updates
    are all within it has converged as well (:func:`_within`).
    """
    full_from = (3 * options.max_steps) // 4  # from here on, a fresh Jacobian every time

    def body(carry):
        x, _, it, last_dx, _, factors, valid = carry
        r = residual(x)
        refactor = ~valid | (it >= full_from)
        if not options.reuse_jacobian:
            refactor = jnp.asarray(True)
        if row_scale is None:
            factors = jax.lax.cond(refactor, factorize, lambda _: factors, x)
        else:
            # the equations' sizes are read only with fresh factors (the round-off test
            # below), so they are formed with them, not at every iteration
            def fresh(x):
                new = factorize(x)
                return new, row_scale(new, x)

            factors, sizes = jax.lax.cond(
                refactor, fresh, lambda x: (factors, jnp.zeros_like(r)), x
            )
        dx = correction(factors, r)
        dx_norm = _norm(dx)
        size = jnp.maximum(_norm(jax.tree.map(jnp.add, x, dx)), scale)
        finite_r = _finite(r)
        finite_dx = _finite(dx)
        r_norm = _norm(r)
        roundoff = jnp.asarray(False)
        if row_scale is not None:
            within = jnp.abs(r) <= options.residual_rtol * sizes
            roundoff = refactor & finite_r & jnp.all(within)
        # Stale factors that fail to contract are replaced; a growing update is dropped.
        slow = ~refactor & (dx_norm > options.contraction * last_dx)
        diverging = ~refactor & ((dx_norm >= last_dx) | ~finite_dx)
        if reference is None:
            small = dx_norm <= options.rtol * size
        else:
            small = _converged(options.rtol, x, dx, reference)
        if atol is not None:
            # only once this solve has contracted (θ ≤ contraction): an update before
            # Newton's asymptotic phase bounds nothing (measured: a diode turning on
            # within the step stopped 1.5-7x its bound off the solution)
            contracted = jnp.isfinite(last_dx) & (dx_norm <= options.contraction * last_dx)
            small = small | (_within(dx, atol) & contracted)
        if options.predict_stop and reference is not None:
            # the next chord update predicted from this one's contraction (same factors):
            # within the test, the iterate after this update is as converged as the
            # next one would be asked to be
            # (only after an update of this solve: factors kept from an earlier solve
            # have no contraction observed yet, and θ = |dx|/∞ = 0 would pass anything)
            theta = dx_norm / last_dx
            observed = ~refactor & ~slow & jnp.isfinite(last_dx)
            small = small | (observed & _converged(options.rtol, x, dx, reference, theta))
        stalled = refactor & (dx_norm <= options.floor * size) & (dx_norm >= 0.5 * last_dx)
        done = (small & ~diverging) | stalled | roundoff
        status = jnp.where(
            ~finite_r,
            SolveStatus.NONFINITE,
            jnp.where(
                ~finite_dx & refactor,
                SolveStatus.SINGULAR,
                jnp.where(done & (finite_dx | roundoff), SolveStatus.SUCCESS, -1),
            ),
        )
        keep = finite_dx & finite_r & ~diverging
        x_new = jax.tree.map(lambda a, b: jnp.where(keep, a + b, a), x, dx)
        if limit is not None:
            x_new = limit(x, x_new)
        last = jnp.where(keep, dx_norm, last_dx)
        valid = ~(slow | diverging)
        return x_new, status, it + 1, last, r_norm, factors, valid

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
        rtol: tolerance on the Newton update relative to the step's increment
            (default 1e-13).
        max_steps: iteration cap per time step (default 40).
        floor: an update below ``floor · scale`` that fails to contract further (with a
            freshly factorized Jacobian) is accepted as converged at round-off.
        reuse_jacobian: keep the factorized Jacobian across iterations and time steps
            while it still contracts (default True); False recomputes it every iteration.
        contraction: with reused factors, an update must shrink at least this much
            (``‖dx_j‖ ≤ contraction · ‖dx_{j−1}‖``) or the Jacobian is recomputed.
        residual_rtol: a residual within this fraction of each equation's terms (see
            above) is at round-off: the step has converged (default 1e-13).
        limit_junctions: limit junction voltages between iterates as SPICE's
            ``pnjlim`` (default True; see :mod:`diracvi.solvers.limiting`).
        predict_stop: also stop when the *next* update, predicted as ``θ |dx|`` from
            the contraction ``θ = ‖dx‖/‖dx_prev‖`` of a chord update that reused the last
            factors and contracted (``θ ≤ contraction``), would pass the test: that next
            update is the error left after this one (a chord iteration contracts at a
            steady rate while its factors are kept). Saves the confirming iteration of
            a nonlinear solve; the iterate kept is within ``rtol`` of the increment
            instead of well below it (default False; the variable-step loop sets it).
        plain_lu: factor a model of at most ``small_lu.SMALL`` unknowns in plain XLA
            operations (:mod:`diracvi.solvers.small_lu`) instead of LAPACK's custom
            calls, where the process compiles small loops as one kernel
            (:mod:`diracvi.runtime.small_loops`) and not under ``DIRACVI_FAST_COMPILE=1``
            (default False; the circuits' variable-step loop sets it: there the loop
            becomes one kernel, 0.23 → 0.07 CPU s a warm call of the bridge rectifier; a
            fixed-step march is not one kernel either way, and the unrolled factors only
            lengthened its first compilation: Andrews' mechanism 7.2 → 12.7 CPU s).
    """

    rtol: float = eqx.field(static=True, default=1e-13)
    max_steps: int = eqx.field(static=True, default=40)
    floor: float = eqx.field(static=True, default=1e-9)
    reuse_jacobian: bool = eqx.field(static=True, default=True)
    contraction: float = eqx.field(static=True, default=0.25)
    residual_rtol: float = eqx.field(static=True, default=1e-13)
    limit_junctions: bool = eqx.field(static=True, default=True)
    predict_stop: bool = eqx.field(static=True, default=False)
    plain_lu: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        check_newton_options(self)

    def init(self, eqs):
        size = eqs.size
        return (
            jnp.zeros((size, size), dtype=eqs.q.dtype),
            jnp.zeros(size, dtype=jnp.int32),
            jnp.zeros((size, size), dtype=eqs.q.dtype),  # |J| of the factorized Jacobian
            jnp.asarray(False),
        )

    def solve(self, eqs, guess, state, atol=None) -> StepResult:
        """Solve ``eqs.residual(x) = 0`` from ``guess``; ``atol`` (optional, shaped as
        ``x``): an absolute bound per unknown its updates may stop within
        (:func:`_within`)."""
        fn = eqs.residual
        # a small model's factors in plain operations when asked (plain_lu), so that a
        # loop around this solve holds no LAPACK custom call and XLA can compile it as one
        # kernel where the process raised the small-loop threshold (runtime/small_loops.py;
        # the bridge rectifier's variable-step loop 0.23 -> 0.07 CPU s); else LAPACK.
        # Not under DIRACVI_FAST_COMPILE=1: one kernel unoptimized compiles slower (6.1
        # against 4.2 CPU s) and runs slower (0.61 against 0.43 s) than the thunks
        small = (
            self.plain_lu
            and eqs.size <= small_lu.SMALL
            and small_loops.in_force()
            and not fast_compile()
        )
        lu_factor = small_lu.lu_factor if small else jsl.lu_factor
        lu_solve = small_lu.lu_solve if small else jsl.lu_solve

        def factorize(x):
            jac = jax.jacfwd(fn)(x)
            return (*lu_factor(jac), jnp.abs(jac))

        # each equation's size: the known momentum and the linearized change over the step
        x_ref = eqs.reference()
        known = jnp.zeros(eqs.size, dtype=eqs.q.dtype).at[: eqs.p.shape[0]].set(jnp.abs(eqs.p))

        # with the force terms a law computes, whose Jacobian may cancel to 0
        # (StepEquations.force_sizes; None: no part bounds its force's round-off)
        with_forces = eqs.bounds_forces

        def row_scale(factors, x):
            linear = known + factors[2] @ jnp.abs(x - x_ref)
            return linear + eqs.force_sizes(x) if with_forces else linear

        lu, piv, jnorm, valid = state
        x, status, iterations, res_norm, (lu, piv, jnorm) = chord_newton(
            self,
            fn,
            factorize,
            lambda factors, r: lu_solve(factors[:2], -r),
            guess,
            (lu, piv, jnorm),
            valid,
            eqs.scale(),
            limit=junction_limiter(eqs) if self.limit_junctions else None,
            row_scale=row_scale,
            reference=x_ref,
            atol=atol,
        )
        return StepResult(x, status, iterations, res_norm, (lu, piv, jnorm, status == 0))
