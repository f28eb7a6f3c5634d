r"""The affine fast path: for linear step equations, one matrix product per step.

When ``L`` is quadratic with a constant mass matrix, the one-forms are constant and the
forces are linear (spring networks, RLC networks, the paper's examples), the step
residual ``r(q, p; x)`` is affine in all its arguments and the explicit momentum line is
affine too. Then the whole step ``(q, p) ↦ (q_other, p_other, μ)`` is one affine map::

    x      = −J_x⁻¹ (r₀ + J_z z),             z = (q, p)
    p_other = P₀ + P_q q + P_x x

i.e. ``(q_other, p_other, μ) = Φ z + b``, computed once and scanned over. It is stored
and applied in increments, ``(q_other − q, p_other − p, μ) = Δ z + b``, for accuracy.

A *driven* linear model (sources ``V(t)``, prescribed currents or motions) has the same
constant ``Δ`` but an offset ``b(t_k)`` that changes every step: ``r₀(t_k)`` and ``P₀(t_k)``
are the residual and momentum line at zero, evaluated for all steps of a block at once,
and ``b(t_k) = (−J_x⁻¹ r₀, P₀ − P_x J_x⁻¹ r₀)``. Detection then also probes at different
times: the Jacobians must not depend on t (a time-varying inductance is not affine).

*Detection* is numerical (user callables are opaque): the Jacobians of ``r`` and of the
momentum line must agree at three points (zero, the initial state, and a pseudo-random
point) and the functions must equal their linearization there. *Verification* is done
on every step of the run: one Newton correction ``J_x⁻¹ r`` of each computed step must be
below ``verify_rtol`` relative to the step's size — the same test that stops Newton — so a
nonlinearity that the three points missed is caught where it acts, and the driver falls
back to the general solver from the start of that chunk.
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg as sla

from .._compile import run_once_jit
from .._equations import StepEquations, new_momentum, residual, unknown_count
from .._errors import ModelError
from .base import StepSolver
from .newton import NewtonSolver

#: Beyond this many unknowns a dense step map costs O(n²) per step and memory; large
#: interconnections use the partitioned solver, which also factorizes only once when the
#: equations are linear.
AFFINE_DENSE_LIMIT = 1500


class AffineSolver(eqx.Module):
    """Step with a precomputed affine map when the step equations are linear.

    Args:
        fallback: the solver used when the equations are not affine, or when the
            per-step verification fails (default ``NewtonSolver()``).
        detect_rtol: relative tolerance of the affinity detection (default 1e-12).
        verify_rtol: a computed step is accepted if one Newton correction of it is below
            ``verify_rtol · max(‖x‖∞, ‖q‖∞)`` (default 1e-11, about 50 round-offs of a
            well-conditioned step; a nonlinearity shows up orders of magnitude above).
    """

    fallback: StepSolver = eqx.field(default_factory=NewtonSolver)
    detect_rtol: float = eqx.field(static=True, default=1e-12)
    verify_rtol: float = eqx.field(static=True, default=1e-11)

    def __check_init__(self):
        if not isinstance(self.fallback, StepSolver):
            raise ModelError(
                f"AffineSolver(fallback={self.fallback!r}): the fallback must be a step "
                "solver, e.g. dv.NewtonSolver() or dv.PartitionedSolver()."
            )
        for arg in ("detect_rtol", "verify_rtol"):
            value = getattr(self, arg)
            if not (isinstance(value, int | float) and 0.0 < float(value) < 1e-3):
                raise ModelError(
                    f"AffineSolver({arg}={value!r}): must be a small positive tolerance "
                    "(below 1e-3), e.g. 1e-12 (detect) or 1e-11 (verify)."
                )


class ReducedMap(eqx.Module):
    r"""The step map on the subspace a run's increments lie in: ``z_k = z_1 + T y_k``.

    Every increment after the first step, ``d_k = z_{k+1} − z_k = Δ z_k + b``, lies in
    ``V = range(Δ Φ) + span(Δ b + b)`` (``Φ = I + Δ``: ``d_k = ΔΦ z_{k−1} + Δb + b``), and
    ``V`` is invariant under ``Δ`` (``Φ`` commutes with ``Δ``). With ``T`` an orthonormal
    basis of ``V`` (``r = dim V``) the states from the first step on are
    ``z_k = z_1 + T y_k``, ``y_1 = 0``, exactly: the directions a torn model carries
    beyond its hand-built reduced model never move along a run (the velocity constraints
    ``A v = 0`` keep ``A q`` fixed, a massless port's momentum stays 0), so they are left
    out of the recursion. ``r = 6`` for the torn chain (``2n = 8``), as for the 3-mass
    hand-built chain.

    With the ``B``-step maps ``z_{s+j} = z_s + P_j z_s + c_j`` of :class:`AffineStepMap`
    and ``z_s = z_1 + T y_s`` at every block start ``s = 1 + iB``::

        z_{s+j} = (z_1 + P_j z_1 + c_j) + (T + P_j T) y_s,      j = 1..B
        y_{s+B} = (I + Tᵀ P_B T) y_s + Tᵀ (P_B z_1 + c_B)

    The first bracket is the first block of the run (the full map applied to ``z_1``
    once); the block starts follow from ``k/B`` sequential ``r × r`` products; then every
    state of the run is one batched product of the starts with the lifts ``T + P_j T``
    (formed in extended precision). Each block start is a rounding of its exact value, so
    the error grows with the number of blocks, not of steps. Where ``V`` is all of the
    state space (a model without port variables, e.g. the hand-built chain) ``T = I``:
    the same two levels without a reduction, which spares the loop of ``k/B`` block
    iterations the one-level scan pays (several microseconds each on a CPU).
    """

    basis: jax.Array  # T (2n, r)
    lifts: jax.Array  # (B, 2n, r): T + P_j T
    maps: jax.Array  # (B, 2n, 2n): P_j
    offsets: jax.Array  # (B, 2n): c_j

    def states(self, step_map, z0, k: int):
        """``z_1 … z_k`` from ``z0`` (shape (k, 2n)); ``k ≥ 2``."""
        z1 = z0 + (step_map.delta @ z0 + step_map.offset)
        width = min(self.lifts.shape[0], k - 1)  # static: no block longer than the run
        lifts = self.lifts[:width]
        first = z1 + (self.maps[:width] @ z1 + self.offsets[:width])
        final = self.basis.T @ lifts[-1]  # I + Tᵀ P_B T
        step = self.basis.T @ (first[-1] - z1)
        blocks = -(-(k - 1) // width)

        def advance(y, _):
            return final @ y + step, y

        # a few block starts are unrolled: a loop iteration costs microseconds on a CPU
        unroll = True if blocks <= _UNROLL_BLOCKS else 8
        _, starts = jax.lax.scan(advance, jnp.zeros_like(step), None, length=blocks, unroll=unroll)
        # (blocks, B, 2n): every state of every block in one product
        zs = jnp.einsum("sr,jnr->sjn", starts, lifts) + first
        return jnp.concatenate([z1[None], zs.reshape(-1, z0.shape[0])[: k - 1]])


#: runs of at most this many blocks compute their block starts without a loop
_UNROLL_BLOCKS = 16


class AffineStepMap(eqx.Module):
    """``(q_other, p_other) = (q, p) + Δ (q, p) + b`` and ``μ = C (q, p) + c``.

    ``μ`` is not needed to advance, so the scan carries only ``z = (q, p)`` and the
    multipliers of all steps are formed afterwards in one matrix product.
    """

    delta: jax.Array  # (2n, 2n)
    offset: jax.Array  # (2n,)
    mu_map: jax.Array  # (m, 2n)
    mu_offset: jax.Array  # (m,)
    inverse: jax.Array  # J_x⁻¹, to measure one Newton correction per step
    jacobian: jax.Array  # J_x, for the solvability check
    powers: jax.Array  # (B, 2n, 2n): z_{k+j} = z_k + powers[j-1] z_k + power_offsets[j-1]
    power_offsets: jax.Array  # (B, 2n)
    momentum_x: jax.Array  # P_x, for the offsets of a driven model
    verify_rtol: float = eqx.field(static=True)
    driven: bool = eqx.field(static=True, default=False)
    #: the two-level map on the run's invariant subspace (:class:`ReducedMap`; ``T = I``
    #: if there is none smaller); ``None`` for a driven model or a staged rule
    reduced: ReducedMap | None = None

    def advance(self, z):
        """One step of ``z = (q, p)``, in increments."""
        return z + (self.delta @ z + self.offset)

    def advance_block(self, z):
        """The next ``B`` states from ``z``, each straight from ``z`` (shape (B, 2n)).

        A scan of single steps pays the loop's overhead per step; these ``B``-step maps
        (formed once in extended precision) cut the iterations ``B``-fold. Each is an
        increment map rounded once, so the error per unit time is that of single steps.
        """
        return z + (self.powers @ z + self.power_offsets)

    def multipliers(self, z_from):
        """``μ`` of the steps taken from each row of ``z_from``."""
        return z_from @ self.mu_map.T + self.mu_offset

    def offsets_at(self, system, rule, scheme, h, times):
        """``(b(t_k), μ offset(t_k))`` for each ``t_k`` of ``times``: the driven offsets."""
        n = system.n
        zero_q, zero_x = jnp.zeros(n), jnp.zeros(unknown_count(system, rule))

        def one(tk):
            r0 = residual(system, rule, scheme, h, zero_q, zero_q, zero_x, tk)
            p0 = new_momentum(system, rule, scheme, h, zero_q, zero_x, tk)
            b_x = -self.inverse @ r0
            return jnp.concatenate([b_x[:n], p0 + self.momentum_x @ b_x]), b_x[n:]

        return jax.vmap(one)(times)

    def correction(self, eqs: StepEquations, x):
        """One Newton correction ``−J_x⁻¹ r(x)`` of a computed step."""
        return -self.inverse @ eqs.residual(x)


@run_once_jit
def _linearizations(system, rule, scheme, h, points, times):
    """Values and Jacobians of the residual and the momentum increment at each
    ``(q, p, d, μ)`` and time ``t_k``, where ``q_other = q + d``.

    Differentiating in increments keeps the map's large near-identity part out of
    floating point: e.g. ``∂(q_other − q)/∂q`` is formed exactly by AD (``dq − dq = 0``)
    instead of as a difference of two rounded ``M/h`` terms, so the map's entries are
    accurate relative to the *change* per step, as Newton's per-step solve is."""
    n, m = system.n, system.m

    def parts(q, p, y, tk):
        # in increments: x = (q + d, μ), and the momentum line as p_other − p (a staged
        # rule's stage Q = q + d_Q is an increment too)
        x = y.at[:n].add(q)
        if rule.stages:
            x = x.at[n + m : 2 * n + m].add(q)
        return residual(system, rule, scheme, h, q, p, x, tk), new_momentum(
            system, rule, scheme, h, q, x, tk
        ) - p

    def at(point, tk):
        def f(y):
            return parts(y[:n], y[n : 2 * n], y[2 * n :], tk)

        def value_twice(y):
            value = f(y)
            return value, value

        # the values at the point come with the Jacobian (one trace of f, not two)
        (jr, jp), (r, pm) = jax.jacfwd(value_twice, has_aux=True)(point)
        r0, pm0 = f(jnp.zeros_like(point))
        return r, pm, r0, pm0, jr, jp

    return jax.vmap(at)(points, times)


@run_once_jit
def _values(system, rule, scheme, h, points, tk):
    """The residual and the momentum increment at each ``(q, p, d, μ)`` (no derivatives).

    The cheap half of detection: compiling values costs a fraction of compiling their
    Jacobians (:func:`_linearizations` differentiates ``∂L/∂v`` once more), so a clearly
    nonlinear model is turned away before the Jacobians are ever built."""
    n = system.n

    def f(y):
        q, p = y[:n], y[n : 2 * n]
        x = y[2 * n :].at[:n].add(q)
        return jnp.concatenate(
            [
                residual(system, rule, scheme, h, q, p, x, tk),
                new_momentum(system, rule, scheme, h, q, x, tk) - p,
            ]
        )

    return jax.vmap(f)(points)


#: a midpoint defect above this (relative) is nonlinearity, far beyond round-off; smaller
#: ones are left to the full test of the Jacobians, which is exact to ``detect_rtol``
_SCREEN_RTOL = 1e-6


def _clearly_nonlinear(system, rule, scheme, h, a, b, tk) -> bool:
    """``f((a+b)/2) ≠ (f(a) + f(b))/2`` at two points: the step equations are not affine.

    An affine ``f`` satisfies the midpoint identity exactly (up to round-off); any
    curvature between two generic points breaks it. Only a defect far above round-off
    counts, so an affine model is never turned away here."""
    points = np.stack([a, b, 0.5 * (a + b)])
    values = np.asarray(_values(system, rule, scheme, h, points, tk))
    if not np.all(np.isfinite(values)):
        return False  # left to the full test, which reports non-finite equations
    defect = np.abs(values[2] - 0.5 * (values[0] + values[1]))
    bound = np.abs(values[0]) + np.abs(values[1]) + np.abs(values[2])
    return bool(np.any(defect > _SCREEN_RTOL * np.maximum(bound, 1.0)))


def _refined_solve(a, factors, b):
    """``a⁻¹ b`` with one step of iterative refinement, the residual in extended precision.

    The map is applied thousands of times, so an error in it is systematic: it adds up
    linearly over the run, unlike the independent round-off of a per-step solve. One
    refinement with an extended-precision residual makes ``Φ`` accurate to about one
    rounding of its entries, whatever the conditioning of ``J_x`` (within reason).
    (Host LAPACK through SciPy: the map is built once, and device solves would each
    compile a program for this shape.)
    """
    x = sla.lu_solve(factors, b, check_finite=False)
    if a.shape[0] > _REFINE_LIMIT or not np.all(np.isfinite(x)):
        return x  # a singular J_x is reported by the caller
    wide = np.longdouble
    resid = (b.astype(wide) - a.astype(wide) @ x.astype(wide)).astype(np.float64)
    return x + sla.lu_solve(factors, resid, check_finite=False)


def _block_count(size: int) -> int:
    """``B``: the stack of ``B`` maps of ``size × size`` holds about 2¹⁸ numbers."""
    return int(np.clip(2**18 // max(size * size, 1), 1, 64))


def _block_maps(delta, offset):
    """``Δ_j, b_j`` with ``z_{k+j} = z_k + Δ_j z_k + b_j`` for ``j = 1..B``, in extended
    precision from the one-step ``Δ, b``: ``Δ_{j+1} = Δ_j + Δ (I + Δ_j)``,
    ``b_{j+1} = b_j + Δ b_j + b``. ``B`` keeps the stack near 2¹⁸ numbers."""
    size = delta.shape[0]
    count = _block_count(size)
    wide = np.longdouble
    d1, b1 = delta.astype(wide), offset.astype(wide)
    d, b = d1.copy(), b1.copy()
    powers, offsets = [d], [b]
    for _ in range(count - 1):
        d, b = d + d1 + d1 @ d, b + d1 @ b + b1
        powers.append(d)
        offsets.append(b)
    return np.stack(powers).astype(np.float64), np.stack(offsets).astype(np.float64)


#: extended-precision refinement costs O(n³) in slow generic loops; skip it beyond this
_REFINE_LIMIT = 400

#: the two-level map (:class:`ReducedMap`) is built for states z of at most this size
_REDUCE_LIMIT = 256

#: singular values of the increments ``[ΔΦ, Δb + b]`` above this (relative to the largest)
#: span ``V``; at most :data:`_NULL_RTOL` counts as zero (round-off of a structural zero).
#: A value in between is neither clearly a direction nor clearly none: no reduction then.
_RANK_RTOL = 1e-10
_NULL_RTOL = 1e-14


def _reduction(delta, offset) -> dict:
    """The arrays of a :class:`ReducedMap`.

    ``T`` is the leading left singular vectors of ``[ΔΦ, Δb + b]`` (formed in extended
    precision), taken only with a clear gap in the singular values and when ``Δ T``
    stays in its span to round-off (the invariance the recursion relies on); otherwise,
    and when ``dim V = dim z``, ``T = I``: the same two-level evaluation of the full
    block maps, without a reduction."""
    size = delta.shape[0]
    wide = np.longdouble
    d, b = delta.astype(wide), offset.astype(wide)
    cols = np.concatenate([d + d @ d, (d @ b + b)[:, None]], axis=1).astype(np.float64)
    basis = _invariant_basis(delta, cols)
    # the B-step maps P_j, c_j and the lifts T + P_j T, in extended precision
    rank = basis.shape[1]
    count = int(np.clip(2**18 // max(size * (size + rank), 1), 1, 256))
    t = basis.astype(wide)
    lifts, maps, offsets = [], [], []
    pj, cj = np.zeros((size, size), dtype=wide), np.zeros(size, dtype=wide)
    for _ in range(count):
        pj, cj = pj + d + d @ pj, cj + d @ cj + b
        lifts.append(t + pj @ t)
        maps.append(pj)
        offsets.append(cj)
    return dict(
        basis=basis,
        lifts=np.stack(lifts).astype(np.float64),
        maps=np.stack(maps).astype(np.float64),
        offsets=np.stack(offsets).astype(np.float64),
    )


def _invariant_basis(delta, cols) -> np.ndarray:
    """An orthonormal basis ``T`` of ``V = range(cols)`` (see :func:`_reduction`)."""
    size = delta.shape[0]
    identity = np.eye(size)
    u, sv, _ = np.linalg.svd(cols)
    top = sv[0] if sv.size else 0.0
    if not top > 0.0:
        return identity  # the state never moves
    rank = int(np.sum(sv > _RANK_RTOL * top))
    if rank >= size or np.any((sv > _NULL_RTOL * top) & (sv <= _RANK_RTOL * top)):
        return identity
    basis = u[:, :rank]
    # Coordinates whose increments are the same (joined ports, a series branch's charges)
    # or nil (a massless port's momentum) must stay so to the bit: an SVD's rows differ
    # by round-off, which the reconstruction z₁ + T y would turn into constraint
    # residuals of order ε|z|/h on a long run. Their rows of T are made identical (zero).
    _, first, group = np.unique(cols, axis=0, return_index=True, return_inverse=True)
    basis = basis[first[group.ravel()]]
    basis[~np.any(cols, axis=1)] = 0.0
    scale = max(float(np.max(np.abs(delta))), 1e-300)
    moved = delta @ basis
    if np.max(np.abs(moved - basis @ (basis.T @ moved)), initial=0.0) > 1e3 * _NULL_RTOL * scale:
        return identity
    return basis


def build(
    system, rule, scheme, h, q0, p0, solver: AffineSolver, t0: float = 0.0
) -> tuple[AffineStepMap | None, str, np.ndarray | None]:
    """``(step map, "affine", J)``, or ``(None, reason, J)`` when the equations are not
    affine. ``J`` is the first step's Jacobian ``∂r/∂(q_other, μ)`` at ``(q0, p0)`` when the
    probes computed it (an autonomous model, probed at ``t0``), else ``None``: the caller's
    solvability check needs no compilation of its own then."""
    n = system.n
    unknowns = unknown_count(system, rule)
    if unknowns > AFFINE_DENSE_LIMIT:
        limit = AFFINE_DENSE_LIMIT
        return None, f"{unknowns} unknowns exceed the dense step-map limit {limit}", None
    rng = np.random.default_rng(20261121)
    scale = 1.0 + float(np.max(np.abs(q0), initial=0.0)) + float(np.max(np.abs(p0), initial=0.0))
    size = 2 * n + unknowns
    points = np.stack(
        [
            np.zeros(size),
            np.concatenate([np.asarray(q0), np.asarray(p0), np.zeros(unknowns)]),
            scale * rng.uniform(-1.0, 1.0, size),
        ]
    )
    h, t0 = np.asarray(h, dtype=np.float64), np.asarray(t0, dtype=np.float64)
    if _clearly_nonlinear(system, rule, scheme, h, points[1], points[2], t0):
        return None, "the step equations are not affine", None
    driven = bool(system.time_dependent)
    # a driven model is probed at three different times (its Jacobians must not move)
    times = t0 + (np.array([0.0, 0.37, -1.91]) * (1.0 + abs(t0)) if driven else np.zeros(3))
    r, pm, r0, pm0, jr, jp = (
        np.asarray(a) for a in _linearizations(system, rule, scheme, h, points, times)
    )
    # probe 1 is (q0, p0) with no increment: there, ∂r/∂(d, μ) is the first step's J
    first = None if driven else jr[1][:, 2 * n :]
    if not (np.all(np.isfinite(jr)) and np.all(np.isfinite(jp))):
        return None, "the step equations are not finite at the probe points", None
    tol = solver.detect_rtol
    for name, val, val0, jac in (("residual", r, r0, jr), ("momentum line", pm, pm0, jp)):
        ref = max(1.0, float(np.max(np.abs(jac))))
        if np.max(np.abs(jac - jac[0])) > tol * ref:
            return None, f"the {name} of the step equations has a non-constant Jacobian", first
        linear = val0 + points @ jac[0].T
        bound = ref * np.max(np.abs(points), axis=1, keepdims=True) + np.abs(val0)
        if np.any(np.abs(val - linear) > tol * np.maximum(bound, 1.0)):
            return None, f"the {name} of the step equations is not affine", first
    j_all, p_all = jr[0], jp[0]
    j_z, j_x = j_all[:, : 2 * n], j_all[:, 2 * n :]
    p_z, p_x = p_all[:, : 2 * n], p_all[:, 2 * n :]
    rhs = np.concatenate([j_z, r[0][:, None]], axis=1)
    with warnings.catch_warnings():  # a singular J_x is reported below, by name
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        factors = sla.lu_factor(j_x, check_finite=False)
        sol = _refined_solve(j_x, factors, -rhs)
    if not np.all(np.isfinite(sol)):
        return None, "the step Jacobian is singular", first
    phi_x, b_x = sol[:, :-1], sol[:, -1]
    phi_p = p_z + p_x @ phi_x
    b_p = pm[0] + p_x @ b_x
    delta = np.concatenate([phi_x[:n], phi_p])
    offset = np.concatenate([b_x[:n], b_p])
    powers, power_offsets = _block_maps(delta, offset)
    # device_put, not jnp.asarray: the latter compiles a small program per shape
    arrays = jax.device_put(
        dict(
            delta=delta,
            offset=offset,
            powers=powers,
            power_offsets=power_offsets,
            mu_map=phi_x[n:],
            mu_offset=b_x[n:],
            inverse=np.linalg.inv(j_x),
            jacobian=j_x,
            momentum_x=p_x,
        )
    )
    # A driven model's offsets b(t_k) need not lie in one subspace, and a staged rule's
    # stage constraints are formed from the states (their residuals grew to 1e-11 on
    # the DC motor): both keep the one-level map, as do large models (the SVD and the
    # extended-precision products below are O(size³) in slow generic loops).
    reduced = None
    if not (driven or rule.stages) and delta.shape[0] <= _REDUCE_LIMIT:
        reduced = ReducedMap(**jax.device_put(_reduction(delta, offset)))
    step_map = AffineStepMap(
        **arrays, verify_rtol=solver.verify_rtol, driven=driven, reduced=reduced
    )
    return step_map, "affine", first
