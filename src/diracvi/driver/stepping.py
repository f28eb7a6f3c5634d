r"""Compiled chunks of a run: ``blocks × save_every`` steps in one ``lax.scan``.

A chunk is an outer scan over *blocks* of ``save_every`` steps; each block runs an inner
scan of single steps and then reduces it to what is saved: the state at the end of the
block, that step's multipliers, energy and constraint residual, the largest constraint
violation over the block and the Newton iterations it took. Memory is therefore
O(n · steps / save_every) with states, O(steps / save_every) without, and O(n · save_every)
inside the block — never O(steps × n²).

Two steppers share the block machinery:

* a :class:`~diracvi.solvers.base.StepSolver` (Newton, partitioned) solves each step's
  equations from an extrapolated guess; after a failed step the carry freezes, so
  everything before it is returned intact;
* an :class:`~diracvi.solvers.affine.AffineStepMap` advances by one matrix product per
  step; each step is then *verified* (one Newton correction must vanish to the solver's
  tolerance) with the diagnostics, vectorized over the block.

Energy and constraint residuals are evaluated after the inner scan, vectorized over the
block, rather than inside the Newton loop.

Time enters through a *clock* ``(t0, first step index)``: step ``j`` of the run covers
``[t_j, t_j + h]`` with ``t_j = t0 + j h`` (plus) or ``t0 − (j + 1) h`` (minus), computed
from the integer index, so a resumed run sees bitwise the same times as an uninterrupted
one. Autonomous systems never read them (the computation is dead code to XLA).
"""

from __future__ import annotations

from functools import partial

import jax
import jax.numpy as jnp

from ..discretization.diagnostics import step_diagnostics
from ..discretization.equations import (
    StepEquations,
    first_guess,
    nodal_momentum,
    ordered,
    split,
    split_stage,
    stage_of,
)
from ..solvers.affine import AffineStepMap
from ..solvers.tiny import max_abs
from ..status import SolveStatus


def step_times(scheme: str, h, clock, offset, length: int):
    """``(t_k, index)`` of ``length`` steps from run step ``clock[1] + offset``."""
    index = clock[1] + offset + jnp.arange(length, dtype=clock.dtype)
    tk = clock[0] + index * h if scheme == "plus" else clock[0] - (index + 1.0) * h
    return tk, index


def _newton_block(system, rule, scheme, solver, h, k, carry, times, active=None):
    """``k`` solver steps from ``carry = (q, p, q_prev, μ_prev, state, failed)``.

    ``active`` (k booleans, or ``None``: all): a step past the run's runtime length is
    not solved (the frozen branch) and leaves the carry as it was, with status 0."""
    if active is None:
        step = partial(_newton_step, system, rule, scheme, solver, h)
        return jax.lax.scan(step, carry, times, length=k)

    def body(c, xs):
        tk, act = xs
        new, out = _newton_step(system, rule, scheme, solver, h, c, tk, ~act)
        # the frozen branch keeps (q, p, q_prev, μ_prev, state) as they were; an idle
        # step must not mark the run failed either
        new = (*new[:5], jnp.where(act, new[5], c[5]))
        return new, (*out[:5], jnp.where(act, out[5], 0))

    return jax.lax.scan(body, carry, (times, active), length=k)


def _newton_step(system, rule, scheme, solver, h, c, tk, idle=False):
    """One solver step of :func:`_newton_block` (frozen after a failure or when ``idle``)."""
    q, p, q_prev, mu_prev, state, failed = c

    def advance(_):
        eqs = StepEquations(system, rule, scheme, h, q, p, tk)
        guess = first_guess(system, rule, q, 2.0 * q - q_prev, mu_prev)
        res = solver.solve(eqs, guess, state)
        q1, mu = split(system, res.x)
        # the momentum line in increment form: the positions' rounding stays out of p
        p1 = eqs.carried_momentum(solver.momentum(eqs, res.x, res.state), res.x)
        finite = jnp.all(jnp.isfinite(q1)) & jnp.all(jnp.isfinite(p1))
        status = jnp.where((res.status == 0) & ~finite, SolveStatus.NONFINITE, res.status)
        return (q1, p1, mu, res.iterations, res.residual_norm, status), res.state

    advance = solver.step_program(advance)

    def frozen(_):
        # μ here is the whole tail of x (with a staged rule's (Q, ν))
        tail = first_guess(system, rule, q, q, mu_prev)[system.n :]
        out = (q, p, tail, jnp.asarray(0), jnp.asarray(jnp.nan, q.dtype), jnp.asarray(-1))
        return out, state

    out, state1 = jax.lax.cond(failed | idle, frozen, advance, None)
    q1, p1, mu, _, _, status = out
    ok = status == 0
    new = (
        jnp.where(ok, q1, q),
        jnp.where(ok, p1, p),
        jnp.where(ok, q, q_prev),
        jnp.where(ok, mu[: system.m], mu_prev),
        state1,
        failed | ~ok,
    )
    return new, out


#: up to this many blocks the recursion of their starts is unrolled
_UNROLL_BLOCKS = 8


def _affine_block(system, rule, scheme, step_map, h, k, carry, times):
    q, p, _, _, state, failed = carry
    n = q.shape[0]
    z0 = jnp.concatenate([q, p])
    width = step_map.powers.shape[0]
    # blocks of equal width ≤ B: only the blocks' starts form a sequential recursion;
    # every state then follows from its block's start at once
    blocks = -(-k // width)
    width = -(-k // blocks)
    offsets = None  # an autonomous map's own b_j
    if step_map.driven:
        # a driven linear model: z_{k+1} = z_k + Δ z_k + b(t_k), one offset per step;
        # z_{k+j} = z_k + Δ_j z_k + b_j in blocks as for an autonomous map, where
        # b_j = Σ_{i<j} (I + Δ)^{j−1−i} b(t_{k+i}) does not depend on the state
        step_offsets, mu_offsets = step_map.offsets_at(system, rule, scheme, h, times)
        padded = jnp.concatenate([step_offsets, jnp.zeros((blocks * width - k, 2 * n))])
        offsets = step_map.block_offsets(padded.reshape(blocks, width, 2 * n))
    if k == 1:  # one step: elementwise, no library call
        zs = step_map.next_start(z0, 1, None if offsets is None else offsets[0, 0])[None]
    elif width == 1:  # single steps (a map too large for blocks): the recursion is the run

        def single(z, b):
            z1 = step_map.next_start(z, 1, b)
            return z1, z1

        steps_b = None if offsets is None else offsets[:, 0]
        _, zs = jax.lax.scan(single, z0, steps_b, length=k, unroll=2)
    elif blocks == 1:
        zs = step_map.advance_blocks(z0[None], width, offsets)[0]
    else:

        def start(z, b):
            z1 = step_map.next_start(z, width, b)
            return z1, z1

        # a few blocks are unrolled (no loop), many looped
        unroll = blocks if blocks <= _UNROLL_BLOCKS else 1
        ends_b = None if offsets is None else offsets[:, -1]
        _, ends = jax.lax.scan(start, z0, ends_b, length=blocks, unroll=unroll)
        zs = step_map.advance_blocks(jnp.concatenate([z0[None], ends[:-1]]), width, offsets)
        # each block ends where the next starts, bitwise (the recursion's own result)
        zs = zs.at[:, -1].set(ends).reshape(-1, z0.shape[0])[:k]
    z_end = zs[-1]
    z_from = jnp.concatenate([z0[None], zs[:-1]])
    mus = step_map.multipliers(z_from)
    if step_map.driven:
        mus = mus - step_map.mu_offset + mu_offsets
    for j in rule.increment_stages():  # the map gives these stages as increments Q − q
        mus = mus.at[:, system.m + j * n : system.m + (j + 1) * n].add(z_from[:, :n])
    q1s, p1s = zs[:, :n], zs[:, n:]
    zero = jnp.zeros(k, dtype=jnp.int32)
    nan = jnp.full(k, jnp.nan, dtype=q.dtype)
    status = jnp.zeros(k, dtype=jnp.int32)  # set by the verification
    q_prev1 = q1s[-2] if k > 1 else q
    new = (z_end[:n], z_end[n:], q_prev1, mus[-1, : system.m], state, failed)
    return new, (q1s, p1s, mus, zero, nan, status)


def _steps(system, rule, scheme, method, h, length, carry, times, count=None):
    """``length`` raw steps: ``(carry, (q1, p1, μ, iterations, residual, status))``;
    with ``count`` (a runtime integer, a solver's steps), only the first ``count`` of
    them are taken, and the carry is the state after them."""
    if isinstance(method, AffineStepMap):
        if count is not None:
            # its blocks' width follows the length; a runtime width measured 25–50 %
            # slower warm (see Plan.chunk), so its programs keep a static length
            raise ValueError("the affine map's run has a static length (count=None)")
        return _affine_block(system, rule, scheme, method, h, length, carry, times)
    active = None if count is None else jnp.arange(length) < count
    return _newton_block(system, rule, scheme, method, h, length, carry, times, active)


def keeps_nodal(system, rule, save_states: bool) -> bool:
    """Whether a run stores :func:`~diracvi.discretization.equations.nodal_momentum`
    beside ``p`` (only when it differs: there are constraints and the rule shares their impulse)."""
    return bool(save_states) and system.m > 0 and rule.impulse_share() != 0.0


def _checked(system, rule, scheme, method, h, q, p, raw, times, index, nodal: bool):
    """Energy, constraint residual, (affine) verified status and nodal momentum of each
    raw step, vectorized over the steps. ``(q, p)`` is the state before the first."""
    q1s, p1s, mus, its, res, status = raw
    q_from = jnp.concatenate([q[None], q1s[:-1]])
    p_from = jnp.concatenate([p[None], p1s[:-1]])
    qk, qk1 = ordered(scheme, q_from, q1s)
    affine = isinstance(method, AffineStepMap)

    diagnostics = step_diagnostics(system, rule, scheme, h)

    def one(a, b, q_, p_, x, p1, tk, first):
        stage = stage_of(system, rule, scheme, a, b, x)
        energy, con = diagnostics(a, b, tk, stage)
        mu = x[system.n : system.n + system.m]
        p_node = nodal_momentum(system, rule, scheme, h, q_, mu, p1, tk, first) if nodal else p1
        if not affine:
            return energy, con, jnp.zeros((), q_.dtype), p_node
        dx = method.correction(StepEquations(system, rule, scheme, h, q_, p_, tk), x)
        size = jnp.maximum(max_abs(x), max_abs(q_))
        return energy, con, max_abs(dx) / jnp.maximum(size, 1e-300), p_node

    x = jnp.concatenate([q1s, mus], axis=1)
    energy, con, correction, p_node = jax.vmap(one)(
        qk, qk1, q_from, p_from, x, p1s, times, index == 0
    )
    if affine:
        bad = ~(correction <= method.verify_rtol) | ~jnp.all(jnp.isfinite(q1s), axis=1)
        status = jnp.where(bad, SolveStatus.AFFINE_REJECTED, status)
        res = correction
    return energy, con, its, res, status, p_node


def stage_record(system, rule, scheme, q, raw):
    """Each raw step's internal stages and stage multipliers, flattened to one row of
    ``s·(n + m)`` numbers: ``[Q₁ … Q_s]`` (shape (n, s), the rule's stages in time order,
    see :func:`~diracvi.discretization.equations.stage_of`) then ``ν`` (shape (m, s)).
    ``q`` is the state before the first step. What a run keeps with ``keep_stages=True``
    (the Dirac diagnostic of a staged rule, :mod:`diracvi.dirac._stagewise`, reads it)."""
    q1s, mus = raw[0], raw[2]
    q_from = jnp.concatenate([q[None], q1s[:-1]])
    qk, qk1 = ordered(scheme, q_from, q1s)
    x = jnp.concatenate([q1s, mus], axis=1)

    def one(a, b, xs):
        stage = stage_of(system, rule, scheme, a, b, xs)
        nu = split_stage(system, xs, rule.stages)[3]
        return jnp.concatenate([stage.ravel(), nu.ravel()])

    return jax.vmap(one)(qk, qk1, x)


def _first_failure(raw, checked, fail):
    """Record the first failing step of the run (code, iterations, residual, state)."""
    q1s = raw[0]
    _, _, its, res, status, _ = checked
    ok = status == 0
    bad = jnp.argmin(ok)  # the first failing step (0 when all are fine)
    first = (fail[0] == 0) & ~jnp.all(ok)
    return jax.tree.map(
        lambda new, old: jnp.where(first, new, old),
        (status[bad], its[bad], res[bad], q1s[bad]),
        fail,
    )


def _good_prefix(ok):
    """How many of ``ok``'s entries (last axis) are true before the first false one:
    ``Σ cumprod(ok)``, as one reduction (a cumulative product is a chain of kernels)."""
    return jnp.where(jnp.all(ok, axis=-1), ok.shape[-1], jnp.argmin(ok, axis=-1))


def _saved(raw, checked, k: int, save_states: bool):
    """Reduce steps shaped ``(blocks, k, …)`` to one saved record per block."""
    q1s, p1s, mus = raw[:3]
    energy, con, its, _, status, p_node = checked
    n_good = _good_prefix(status == 0).astype(jnp.int32)
    last = jnp.maximum(n_good - 1, 0)

    def at(a):
        return jnp.take_along_axis(a, last.reshape(last.shape + (1,) * (a.ndim - 1)), axis=1)[:, 0]

    good = jnp.arange(k) < n_good[:, None]
    abs_con = max_abs(con)
    saved = {
        "n_good": n_good,
        "energy": at(energy),
        "violation": jnp.max(jnp.where(good, abs_con, 0.0), axis=1),
        "iterations": jnp.sum(jnp.where(good, its, 0), axis=1),
    }
    if save_states:
        saved.update(q=at(q1s), p=at(p1s), mu=at(mus), con=at(con), p_node=at(p_node))
    return saved


def _saved_every_step(raw, checked, save_states: bool, stages=None):
    """:func:`_saved` for ``k = 1``: every step is its own record (with ``stages``, the
    :func:`stage_record` of every step)."""
    q1s, p1s, mus = raw[:3]
    energy, con, its, _, status, p_node = checked
    # 1 up to the first failing step, 0 from there on
    saved = {
        "n_good": (jnp.arange(status.shape[0]) < _good_prefix(status == 0)).astype(jnp.int32),
        "energy": energy,
        "violation": max_abs(con),
        "iterations": its,
    }
    if save_states:
        saved.update(q=q1s, p=p1s, mu=mus, con=con, p_node=p_node)
    if stages is not None:
        saved["stage"] = stages
    return saved


def chunk_runner(
    system, rule, scheme, method, k: int, save_states: bool, blocks: int, keep_stages=False
):
    """A function ``(h, clock, carry) ↦ (carry, fail, saved)`` for ``blocks`` blocks of
    ``k`` steps; ``clock = (t0, index of the chunk's first step)``,
    ``carry = (q, p, q_prev, μ_prev)``, ``fail`` the first failure's details.

    With ``k = 1`` the chunk is one flat scan whose diagnostics are vectorized over the
    whole chunk (every step is saved anyway); with ``k > 1`` an outer scan over blocks
    keeps only one record per block, so memory stays O(blocks) beyond one block. A long
    ``k = 1`` chunk of a large model that saves no states runs as blocks of one step
    (:data:`FLAT_DIAGNOSTICS_VALUES`), so its memory stays O(n + steps).
    ``keep_stages`` (a staged rule, ``k = 1``, states saved): ``saved["stage"]`` holds
    every step's :func:`stage_record`.
    """

    run = stateful_chunk_runner(system, rule, scheme, method, k, save_states, blocks, keep_stages)

    def chunk(h, clock, carry, count=None):
        q, p = carry[:2]
        if isinstance(method, AffineStepMap):
            state = ()
        else:
            t_first = step_times(scheme, h, clock, 0, 1)[0][0]
            state = method.init(StepEquations(system, rule, scheme, h, q, p, t_first))
        carry, _, fail, saved = run(h, clock, carry, state, count=count)
        return carry, fail, saved

    return chunk


#: without saved states, a chunk longer than this many (steps × n) values computes its
#: diagnostics step by step inside the scan: vectorized over the chunk they would hold
#: every step's state at once (8 GB for 10⁶ coordinates × 1000 steps)
FLAT_DIAGNOSTICS_VALUES = 1 << 22


def stateful_chunk_runner(
    system, rule, scheme, method, k: int, save_states: bool, blocks: int, keep_stages=False
):
    """:func:`chunk_runner` with the solver state passed in and returned:
    ``(h, clock, carry, state, fail=None, count=None) ↦ (carry, state, fail, saved)``.
    Consecutive chunks that thread the state and the failure record repeat the arithmetic
    of one long chunk exactly (the traced driver runs a checkpointed run as such segments).

    ``count`` (a runtime integer ≤ ``blocks``, or ``None``: all): only the first ``count``
    records are run; the rest of ``saved`` is filler and the carry is the state after
    them. The steps taken repeat the arithmetic of a chunk of ``count`` blocks exactly
    (a Newton step past the end takes the frozen branch, a block past it is skipped), so
    one program serves every length. (A run of the affine map with ``k = 1`` takes no
    ``count``: its blocks' width depends on the length.)"""

    nodal = keeps_nodal(system, rule, save_states)

    def chunk(h, clock, carry, state, fail=None, count=None):
        q, p, q_prev, mu_prev = carry
        fail0 = (jnp.asarray(0), jnp.asarray(0), jnp.asarray(jnp.nan, q.dtype), q)
        if fail is not None:  # a failure in an earlier chunk keeps this one frozen
            fail0 = fail
        init = (q, p, q_prev, mu_prev, state, fail0[0] != 0)

        def block(inner, fail, offset, length, count=None):
            times, index = step_times(scheme, h, clock, offset, length)
            new, raw = _steps(system, rule, scheme, method, h, length, inner, times, count)
            checked = _checked(
                system, rule, scheme, method, h, inner[0], inner[1], raw, times, index, nodal
            )
            if count is not None:  # the steps past the run's end are no failures
                status = jnp.where(jnp.arange(length) < count, checked[4], 0)
                checked = (*checked[:4], status, checked[5])
            stages = stage_record(system, rule, scheme, inner[0], raw) if keep_stages else None
            raw = (*raw[:2], raw[2][..., : system.m], *raw[3:])  # saved: μ without stages
            fail = _first_failure(raw, checked, fail)
            return new, fail, raw, checked, stages

        flat = blocks * system.n <= FLAT_DIAGNOSTICS_VALUES
        flat = flat and not getattr(method, "diagnostics_per_step", False)
        if k == 1 and (save_states or flat):
            inner, fail, raw, checked, stages = block(init, fail0, 0.0, blocks, count)
            saved = _saved_every_step(raw, checked, save_states, stages)
            return inner[:4], inner[4], fail, saved

        def body(c, b, taken=None):
            inner, fail = c
            inner, fail, raw, checked, _ = block(inner, fail, b * k, k, taken)
            saved = _saved(*jax.tree.map(lambda a: a[None], (raw, checked)), k, save_states)
            return (inner, fail), jax.tree.map(lambda a: a[0], saved)

        offsets = jnp.arange(blocks, dtype=clock.dtype)
        if count is None:
            (inner, fail), saved = jax.lax.scan(body, (init, fail0), offsets, length=blocks)
            return inner[:4], inner[4], fail, saved

        # a block past the run's end takes none of its steps (each the frozen branch):
        # the carry passes it unchanged, its record is cut off on the host. (Skipping the
        # block by a lax.cond instead changed the diagnostics of the blocks taken by a
        # few ulp: a block compiled inside a conditional is another program.)
        def counted(c, b):
            return body(c, b, jnp.where(b < count, k, 0))

        (inner, fail), saved = jax.lax.scan(counted, (init, fail0), offsets, length=blocks)
        return inner[:4], inner[4], fail, saved

    return chunk
