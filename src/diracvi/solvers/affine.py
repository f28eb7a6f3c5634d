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

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.equations import StepEquations, new_momentum, residual, unknown_count
from ..errors import ModelError
from ..runtime.compile import run_once_jit
from .base import StepSolver
from .newton import NewtonSolver
from .tiny import matvec

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

    def advance_blocks(self, starts, width: int, offsets=None):
        """The ``width`` states after each row of ``starts`` (shape (blocks, 2n) ↦
        (blocks, width, 2n)), each straight from its start: ``z_{k+j} = z_k + Δ_j z_k + b_j``.

        A scan of single steps pays the loop's overhead per step; these ``B``-step maps
        (formed once in extended precision) leave only the blocks' starts to a
        sequential recursion (:meth:`next_start`), and every state of the run to one
        matrix product. Each is an increment map rounded once, so the error per unit
        time is that of single steps. ``offsets`` (blocks, width, 2n): each block's own
        ``b_j`` (a driven model's, :meth:`block_offsets`) in place of the autonomous ones.
        """
        size = self.powers.shape[1]
        powers = self.powers[:width].reshape(width * size, size)
        # (width·2n, 2n) × (2n, blocks): one product for all blocks (one library call; as
        # elementwise code XLA would recompute it inside each consumer)
        steps = (powers @ starts.T).T.reshape(-1, width, size)
        if offsets is None:
            offsets = self.power_offsets[:width]
        return starts[:, None, :] + (steps + offsets)

    def next_start(self, z, width: int, offset=None):
        """The state ``width`` steps after ``z`` (the last row of :meth:`advance_blocks`;
        ``offset``: a driven block's ``b_width``)."""
        if offset is None:
            offset = self.power_offsets[width - 1]
        return z + (matvec(self.powers[width - 1], z) + offset)

    def block_offsets(self, offsets):
        r"""A driven model's ``b_j = Σ_{i<j} (I + Δ)^{j−1−i} b(t_i)``, ``j = 1..B``, for
        each block of one-step offsets ``b(t_i)`` (blocks, B, 2n): what the steps of a
        block add to ``z_{k+j} = z_k + Δ_j z_k + b_j`` beyond its start's image. The
        recursion ``b_{j+1} = b_j + Δ b_j + b(t_j)`` runs for all blocks at once, so a
        run of ``k`` steps is ``B + k/B`` sequential steps instead of ``k``.

        Measured on the driven RLC (1000 steps), a loop iteration's overhead is what a
        driven run costs beyond an autonomous one, so the products are elementwise
        (:func:`~diracvi.solvers.tiny.matvec`; a library call per iteration cost 40 % more).
        Fewer iterations did not pay: recursive doubling (``⌈log₂ B⌉`` products, each
        over the whole run) and sub-blocks of 8 (16 iterations instead of 64, and more
        kernels) both measured slower.
        """

        def step(total, b):
            after = self.next_start(total, 1, b)  # one step of the map, offset b(t_j)
            return after, after

        zero = jnp.zeros(offsets.shape[:1] + offsets.shape[2:], offsets.dtype)
        _, sums = jax.lax.scan(step, zero, jnp.moveaxis(offsets, 1, 0))
        return jnp.moveaxis(sums, 0, 1)

    def multipliers(self, z_from):
        """``μ`` of the steps taken from each row of ``z_from``."""
        return matvec(self.mu_map, z_from) + self.mu_offset

    def offsets_at(self, system, rule, scheme, h, times):
        """``(b(t_k), μ offset(t_k))`` for each ``t_k`` of ``times``: the driven offsets,
        ``b_x = −J_x⁻¹ r(t_k)`` and ``b = (b_x[:n], p(t_k) + P_x b_x)``, ``μ offset =
        b_x[n:]``, where ``r`` and ``p`` are the residual and the new momentum at the zero
        state.

        ``r`` and ``p`` of all steps are formed first, and held (an optimization barrier)
        before the two products. Otherwise XLA distributes a product over the parts of
        ``r``, and a part that is the same at every step (terms in ``h``, an input of the
        program) becomes a product of its own over all the steps: measured on the driven
        RLC, 1000 steps, the program took 182 µs that way and 170–173 µs this way."""
        n = system.n
        zero_q, zero_x = jnp.zeros(n), jnp.zeros(unknown_count(system, rule))

        def at_zero(tk):
            r0 = residual(system, rule, scheme, h, zero_q, zero_q, zero_x, tk)
            return r0, new_momentum(system, rule, scheme, h, zero_q, zero_x, tk)

        r0, p0 = jax.lax.optimization_barrier(jax.vmap(at_zero)(times))
        b_x = r0 @ -self.inverse.T
        return jnp.concatenate([b_x[:, :n], p0 + b_x @ self.momentum_x.T], axis=1), b_x[:, n:]

    def correction(self, eqs: StepEquations, x):
        """One Newton correction ``−J_x⁻¹ r(x)`` of a computed step."""
        return -matvec(self.inverse, eqs.residual(x))


def _linearize(system, rule, scheme, h, points, times):
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
        for j in rule.increment_stages():
            x = x.at[n + m + j * n : n + m + (j + 1) * n].add(q)
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


def _evaluate(system, rule, scheme, h, points, tk):
    """The residual and the momentum increment at each ``(q, p, d, μ)`` (no derivatives).

    The cheap half of detection: compiling values costs a fraction of compiling their
    Jacobians (:func:`_linearize` differentiates ``∂L/∂v`` once more), so a clearly
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


# one model (simulate's plan); the identities are the store's names of these programs
_linearizations = run_once_jit(_linearize, "diracvi.solvers.affine._linearizations")
_values = run_once_jit(_evaluate, "diracvi.solvers.affine._values")


def _each_member(probe):
    """``probe`` of one system, vmapped over members of one structure: the system's
    static part, then its array leaves stacked over the members (``equinox.partition``),
    each member with its own probe points."""

    def stacked(static, dynamic, rule, scheme, h, points, times):
        def one(leaves, member_points):
            system = eqx.combine(leaves, static)
            return probe(system, rule, scheme, h, member_points, times)

        return jax.vmap(one)(dynamic, points)

    return stacked


# members of a sweep: one program for all of them (traced once per structure and count)
_member_linearizations = run_once_jit(
    _each_member(_linearize), "diracvi.solvers.affine._member_linearizations"
)
_member_values = run_once_jit(_each_member(_evaluate), "diracvi.solvers.affine._member_values")

#: a midpoint defect above this (relative) is nonlinearity, far beyond round-off; smaller
#: ones are left to the full test of the Jacobians, which is exact to ``detect_rtol``
_SCREEN_RTOL = 1e-6


def _clearly_nonlinear(values) -> np.ndarray:
    """Per member, ``f((a+b)/2) ≠ (f(a) + f(b))/2`` at two points ``a``, ``b``: the step
    equations are not affine. ``values`` (members, 3, rows): ``f`` at ``a``, ``b``, their
    midpoint.

    An affine ``f`` satisfies the midpoint identity exactly (up to round-off); any
    curvature between two generic points breaks it. Only a defect far above round-off
    counts, so an affine model is never turned away here; nor is a member whose values
    are not finite (left to the full test, which reports non-finite equations)."""
    values = np.asarray(values)
    finite = np.all(np.isfinite(values), axis=(1, 2))
    with np.errstate(invalid="ignore", over="ignore"):  # (non-finite members: False)
        defect = np.abs(values[:, 2] - 0.5 * (values[:, 0] + values[:, 1]))
        bound = np.abs(values[:, 0]) + np.abs(values[:, 1]) + np.abs(values[:, 2])
        clearly = np.any(defect > _SCREEN_RTOL * np.maximum(bound, 1.0), axis=1)
    return finite & clearly


def _solve(a, b):
    """``a⁻¹ b`` for stacks (members, N, N) and (members, N, k); a member whose ``a`` is
    exactly singular gets NaN (LAPACK's LU, as ``numpy.linalg.solve``; it refuses a whole
    stack for one singular member, so those are then solved one by one)."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        out = np.full(b.shape, np.nan)
        for i in range(len(a)):
            try:
                out[i] = np.linalg.solve(a[i], b[i])
            except np.linalg.LinAlgError:
                pass
        return out


def _refined_solve(a, b):
    """``a⁻¹ b`` with one step of iterative refinement, the residual in extended precision
    (stacks over members, as :func:`_solve`).

    The map is applied thousands of times, so an error in it is systematic: it adds up
    linearly over the run, unlike the independent round-off of a per-step solve. One
    refinement with an extended-precision residual makes ``Φ`` accurate to about one
    rounding of its entries, whatever the conditioning of ``J_x`` (within reason).
    (Host LAPACK through NumPy: the map is built once per plan, and device solves would
    each compile a program for this shape. Not SciPy's ``lu_solve``: on a busy machine
    its threaded triangular solves took ~20 ms for a 4 × 4 system, against 5 µs here.)
    """
    x = _solve(a, b)
    if a.shape[-1] > _REFINE_LIMIT:
        return x
    wide = np.longdouble
    resid = (b.astype(wide) - a.astype(wide) @ x.astype(wide)).astype(np.float64)
    finite = np.all(np.isfinite(x), axis=(1, 2))  # a singular J_x is reported by the caller
    resid[~finite] = 0.0
    return np.where(finite[:, None, None], x + _solve(a, resid), x)


#: the longest block of steps that one map takes from its start (a run of k steps is
#: ⌈k / MAX_BLOCK⌉ blocks: the sequential part of an affine run)
MAX_BLOCK = 64


def _block_maps(delta, offset):
    """``Δ_j, b_j`` with ``z_{k+j} = z_k + Δ_j z_k + b_j`` for ``j = 1..B``, in extended
    precision from the one-step ``Δ, b``: ``Δ_{j+1} = Δ_j + Δ (I + Δ_j)``,
    ``b_{j+1} = b_j + Δ b_j + b``. ``B`` keeps each member's stack near 2¹⁸ numbers.
    Stacks over members: ``delta`` (members, 2n, 2n), ``offset`` (members, 2n) ↦
    (members, B, 2n, 2n), (members, B, 2n)."""
    size = delta.shape[-1]
    count = int(np.clip(2**18 // max(size * size, 1), 1, MAX_BLOCK))
    wide = np.longdouble
    d1, b1 = delta.astype(wide), offset.astype(wide)[..., None]
    d, b = d1.copy(), b1.copy()
    powers, offsets = [d], [b]
    for _ in range(count - 1):
        d, b = d + d1 + d1 @ d, b + d1 @ b + b1
        powers.append(d)
        offsets.append(b)
    return (
        np.stack(powers, axis=1).astype(np.float64),
        np.stack(offsets, axis=1)[..., 0].astype(np.float64),
    )


#: extended-precision refinement costs O(n³) in slow generic loops; skip it beyond this
_REFINE_LIMIT = 400


def _probe_points(q0s, p0s, unknowns: int) -> np.ndarray:
    """(members, 3, 2n + N): zero, the member's initial state ``(q0, p0, 0)``, and one
    pseudo-random direction (the same for all members) at the member's scale."""
    count, n = q0s.shape
    size = 2 * n + unknowns
    direction = np.random.default_rng(20261121).uniform(-1.0, 1.0, size)
    scale = (
        1.0 + np.max(np.abs(q0s), axis=1, initial=0.0) + np.max(np.abs(p0s), axis=1, initial=0.0)
    )
    points = np.zeros((count, 3, size))
    points[:, 1, :n], points[:, 1, n : 2 * n] = q0s, p0s
    points[:, 2] = scale[:, None] * direction
    return points


def _screen_points(points) -> np.ndarray:
    """(members, 3, 2n + N): the initial state ``a``, the pseudo-random point ``b`` and
    their midpoint, where :func:`_clearly_nonlinear` compares ``f``."""
    a, b = points[:, 1], points[:, 2]
    return np.stack([a, b, 0.5 * (a + b)], axis=1)


def _probe_times(t0, driven: bool) -> np.ndarray:
    """A driven model is probed at three different times (its Jacobians must not move)."""
    t0 = np.asarray(t0, dtype=np.float64)
    return t0 + (np.array([0.0, 0.37, -1.91]) * (1.0 + abs(t0)) if driven else np.zeros(3))


#: a member's reason when it has a map, and when its ``J_x`` could not be solved
AFFINE, SINGULAR = "affine", "the step Jacobian is singular"


#: the most numbers one vmapped probe call returns (Jacobians at 3 points per member):
#: 2²⁵ float64, 256 MB. A batch of members is probed in one call up to that size.
PROBE_NUMBERS = 2**25


class StackedMaps(NamedTuple):
    """The affine step maps of members that share one structure.

    ``step_map``: an :class:`AffineStepMap` whose leaves are NumPy stacks over the
    members (a member without a map holds a copy of the first good member's), or ``None``
    when no member is affine. ``reasons[i]``: ``"affine"``, or why member ``i`` has no
    map. ``first``: the first step's Jacobians ``∂r/∂(q_other, μ)`` at each member's
    ``(q0, p0)`` (members, N, N) when the probes formed them (an autonomous model whose
    Jacobians were formed), else ``None``.
    """

    step_map: AffineStepMap | None
    reasons: list
    first: np.ndarray | None

    @property
    def affine(self) -> np.ndarray:
        return np.array([r == AFFINE for r in self.reasons], dtype=bool)


#: how many times affine maps were assembled (one call forms every member's map; the
#: tests count it to show that a sweep builds its maps together, not member by member)
ASSEMBLY_COUNT = 0


def _assemble(linearizations, points, n: int, solver: AffineSolver, driven: bool):
    """The step maps of every member from its probes (stacks over members, host arrays):
    ``(arrays, reasons, first)`` as :class:`StackedMaps` holds them, ``arrays`` the
    :class:`AffineStepMap` fields (``None`` when no member is affine)."""
    global ASSEMBLY_COUNT
    ASSEMBLY_COUNT += 1
    r, pm, r0, pm0, jr, jp = (np.asarray(a) for a in linearizations)
    count = len(points)
    reasons = [AFFINE] * count
    # probe 1 is (q0, p0) with no increment: there, ∂r/∂(d, μ) is the first step's J
    first = None if driven else jr[:, 1, :, 2 * n :]

    def refuse(mask, reason):
        for i in np.nonzero(mask)[0]:
            if reasons[i] == AFFINE:
                reasons[i] = reason

    finite = np.all(np.isfinite(jr), axis=(1, 2, 3)) & np.all(np.isfinite(jp), axis=(1, 2, 3))
    refuse(~finite, "the step equations are not finite at the probe points")
    tol = solver.detect_rtol
    extent = np.max(np.abs(points), axis=2, keepdims=True)  # (members, 3, 1)
    for name, val, val0, jac in (("residual", r, r0, jr), ("momentum line", pm, pm0, jp)):
        with np.errstate(invalid="ignore"):  # non-finite members are refused above
            ref = np.maximum(1.0, np.max(np.abs(jac), axis=(1, 2, 3), initial=0.0))
            moved = np.max(np.abs(jac - jac[:, :1]), axis=(1, 2, 3), initial=0.0)
            refuse(
                moved > tol * ref, f"the {name} of the step equations has a non-constant Jacobian"
            )
            linear = val0 + points @ np.swapaxes(jac[:, 0], 1, 2)
            bound = ref[:, None, None] * extent + np.abs(val0)
            off = np.abs(val - linear) > tol * np.maximum(bound, 1.0)
            refuse(np.any(off, axis=(1, 2)), f"the {name} of the step equations is not affine")
    good = np.array([reason == AFFINE for reason in reasons])
    if not good.any():
        return None, reasons, first
    # the members without a map carry a copy of a good one's (a stack of one form)
    rows = np.where(good, np.arange(count), np.argmax(good))
    j_all, p_all = jr[rows, 0], jp[rows, 0]
    j_z, j_x = j_all[:, :, : 2 * n], j_all[:, :, 2 * n :]
    p_z, p_x = p_all[:, :, : 2 * n], p_all[:, :, 2 * n :]
    rhs = np.concatenate([j_z, r[rows, 0][:, :, None]], axis=2)
    sol = _refined_solve(j_x, -rhs)
    singular = ~np.all(np.isfinite(sol), axis=(1, 2))
    refuse(singular, SINGULAR)
    if singular.all():
        return None, reasons, first
    if singular.any():  # the same copy again, now of a member whose J_x is regular
        good &= ~singular
        keep = np.where(good, np.arange(count), np.argmax(good))
        j_x, p_z, p_x, sol = j_x[keep], p_z[keep], p_x[keep], sol[keep]
        rows = rows[keep]
    phi_x, b_x = sol[:, :, :-1], sol[:, :, -1]
    phi_p = p_z + p_x @ phi_x
    b_p = pm[rows, 0] + (p_x @ b_x[:, :, None])[:, :, 0]
    delta = np.concatenate([phi_x[:, :n], phi_p], axis=1)
    offset = np.concatenate([b_x[:, :n], b_p], axis=1)
    powers, power_offsets = _block_maps(delta, offset)
    arrays = dict(
        delta=delta,
        offset=offset,
        powers=powers,
        power_offsets=power_offsets,
        mu_map=phi_x[:, n:],
        mu_offset=b_x[:, n:],
        inverse=np.linalg.inv(j_x),
        jacobian=j_x,
        momentum_x=p_x,
    )
    return arrays, reasons, first


def build(
    system, rule, scheme, h, q0, p0, solver: AffineSolver, t0: float = 0.0
) -> tuple[AffineStepMap | None, str, np.ndarray | None]:
    """``(step map, "affine", J)``, or ``(None, reason, J)`` when the equations are not
    affine. ``J`` is the first step's Jacobian ``∂r/∂(q_other, μ)`` at ``(q0, p0)`` when the
    probes computed it (an autonomous model, probed at ``t0``), else ``None``: the caller's
    solvability check needs no compilation of its own then."""
    unknowns = unknown_count(system, rule)
    if unknowns > AFFINE_DENSE_LIMIT:
        limit = AFFINE_DENSE_LIMIT
        return None, f"{unknowns} unknowns exceed the dense step-map limit {limit}", None
    points = _probe_points(np.asarray(q0)[None], np.asarray(p0)[None], unknowns)
    h, t0 = np.asarray(h, dtype=np.float64), np.asarray(t0, dtype=np.float64)
    screen = _values(system, rule, scheme, h, _screen_points(points)[0], t0)
    if _clearly_nonlinear(np.asarray(screen)[None])[0]:
        return None, "the step equations are not affine", None
    driven = bool(system.time_dependent)
    found = _linearizations(system, rule, scheme, h, points[0], _probe_times(t0, driven))
    arrays, reasons, first = _assemble(
        [np.asarray(a)[None] for a in found], points, system.n, solver, driven
    )
    first = None if first is None else first[0]
    if arrays is None:
        return None, reasons[0], first
    # device_put, not jnp.asarray: the latter compiles a small program per shape
    arrays = jax.device_put({name: a[0] for name, a in arrays.items()})
    step_map = AffineStepMap(**arrays, verify_rtol=solver.verify_rtol, driven=driven)
    return step_map, "affine", first


def build_stacked(
    system, static, dynamic, rule, scheme, h, q0s, p0s, solver: AffineSolver, t0: float = 0.0
) -> StackedMaps:
    """The affine step maps of members of one structure, built together: ``dynamic`` is
    the members' array leaves stacked (``equinox.partition(member, equinox.is_array)``),
    ``static`` their shared rest, ``system`` any one member (for its sizes), ``q0s``,
    ``p0s`` (members, n). Each member's map is the one :func:`build` forms for it (the
    same probes, tests, solves and block maps); here the probes of all members are one
    vmapped program (traced once per structure and member count) and the solves and
    block maps are stacked host operations, not a loop over members."""
    count = len(q0s)
    unknowns = unknown_count(system, rule)
    if unknowns > AFFINE_DENSE_LIMIT:
        reason = f"{unknowns} unknowns exceed the dense step-map limit {AFFINE_DENSE_LIMIT}"
        return StackedMaps(None, [reason] * count, None)
    points = _probe_points(np.asarray(q0s), np.asarray(p0s), unknowns)
    h, t0 = np.asarray(h, dtype=np.float64), np.asarray(t0, dtype=np.float64)
    screen = _member_values(static, dynamic, rule, scheme, h, _screen_points(points), t0)
    nonlinear = _clearly_nonlinear(screen)
    if nonlinear.all():
        return StackedMaps(None, ["the step equations are not affine"] * count, None)
    driven = bool(system.time_dependent)
    times = _probe_times(t0, driven)
    # the Jacobians at 3 points per member: for large members, slices of a fixed size
    # (one program, the last slice padded) keep the probes' output bounded
    per_member = 3 * (unknowns + system.n) * points.shape[2]
    size = max(1, PROBE_NUMBERS // per_member)
    size = count if size >= count else 1 << (size.bit_length() - 1)
    found = []
    for start in range(0, count, size):

        def part(a, start=start):
            a = np.asarray(a)[start : start + size]
            return np.concatenate([a, np.repeat(a[-1:], size - len(a), axis=0)])

        sliced = jax.tree.map(part, dynamic)
        found.append(_member_linearizations(static, sliced, rule, scheme, h, part(points), times))
    found = [np.concatenate(parts)[:count] for parts in zip(*found, strict=True)]
    arrays, reasons, first = _assemble(found, points, system.n, solver, driven)
    reasons = [
        "the step equations are not affine" if bad else reason
        for bad, reason in zip(nonlinear, reasons, strict=True)
    ]
    if arrays is None or AFFINE not in reasons:
        return StackedMaps(None, reasons, first)
    step_map = AffineStepMap(**arrays, verify_rtol=solver.verify_rtol, driven=driven)
    return StackedMaps(step_map, reasons, first)
