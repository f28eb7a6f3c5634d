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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

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
from ..runtime.compile import stored_chunk_jit
from ..solvers.affine import AffineStepMap
from ..solvers.tiny import max_abs
from ..status import SolveStatus


def step_times(scheme: str, h, clock, offset, length: int):
    """``(t_k, index)`` of ``length`` steps from run step ``clock[1] + offset``."""
    index = clock[1] + offset + jnp.arange(length, dtype=clock.dtype)
    tk = clock[0] + index * h if scheme == "plus" else clock[0] - (index + 1.0) * h
    return tk, index


def _newton_block(system, rule, scheme, solver, h, k, carry, times):
    """``k`` solver steps from ``carry = (q, p, q_prev, μ_prev, state, failed)``."""

    def body(c, tk):
        q, p, q_prev, mu_prev, state, failed = c

        def advance(_):
            eqs = StepEquations(system, rule, scheme, h, q, p, tk)
            guess = first_guess(system, rule, q, 2.0 * q - q_prev, mu_prev)
            res = solver.solve(eqs, guess, state)
            q1, mu = split(system, res.x)
            p1 = solver.momentum(eqs, res.x, res.state)
            finite = jnp.all(jnp.isfinite(q1)) & jnp.all(jnp.isfinite(p1))
            status = jnp.where((res.status == 0) & ~finite, SolveStatus.NONFINITE, res.status)
            return (q1, p1, mu, res.iterations, res.residual_norm, status), res.state

        def frozen(_):
            # μ here is the whole tail of x (with a staged rule's (Q, ν))
            tail = first_guess(system, rule, q, q, mu_prev)[system.n :]
            out = (q, p, tail, jnp.asarray(0), jnp.asarray(jnp.nan, q.dtype), jnp.asarray(-1))
            return out, state

        out, state1 = jax.lax.cond(failed, frozen, advance, None)
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

    return jax.lax.scan(body, carry, times, length=k)


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


def _steps(system, rule, scheme, method, h, length, carry, times):
    """``length`` raw steps: ``(carry, (q1, p1, μ, iterations, residual, status))``."""
    if isinstance(method, AffineStepMap):
        return _affine_block(system, rule, scheme, method, h, length, carry, times)
    return _newton_block(system, rule, scheme, method, h, length, carry, times)


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

    def chunk(h, clock, carry):
        q, p = carry[:2]
        if isinstance(method, AffineStepMap):
            state = ()
        else:
            t_first = step_times(scheme, h, clock, 0, 1)[0][0]
            state = method.init(StepEquations(system, rule, scheme, h, q, p, t_first))
        carry, _, fail, saved = run(h, clock, carry, state)
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
    ``(h, clock, carry, state, fail=None) ↦ (carry, state, fail, saved)``. Consecutive
    chunks that thread the state and the failure record repeat the arithmetic of one long
    chunk exactly (the traced driver runs a checkpointed run as such segments)."""

    nodal = keeps_nodal(system, rule, save_states)

    def chunk(h, clock, carry, state, fail=None):
        q, p, q_prev, mu_prev = carry
        fail0 = (jnp.asarray(0), jnp.asarray(0), jnp.asarray(jnp.nan, q.dtype), q)
        if fail is not None:  # a failure in an earlier chunk keeps this one frozen
            fail0 = fail
        init = (q, p, q_prev, mu_prev, state, fail0[0] != 0)

        def block(inner, fail, offset, length):
            times, index = step_times(scheme, h, clock, offset, length)
            new, raw = _steps(system, rule, scheme, method, h, length, inner, times)
            checked = _checked(
                system, rule, scheme, method, h, inner[0], inner[1], raw, times, index, nodal
            )
            stages = stage_record(system, rule, scheme, inner[0], raw) if keep_stages else None
            raw = (*raw[:2], raw[2][..., : system.m], *raw[3:])  # saved: μ without stages
            fail = _first_failure(raw, checked, fail)
            return new, fail, raw, checked, stages

        flat = blocks * system.n <= FLAT_DIAGNOSTICS_VALUES
        flat = flat and not getattr(method, "diagnostics_per_step", False)
        if k == 1 and (save_states or flat):
            inner, fail, raw, checked, stages = block(init, fail0, 0.0, blocks)
            saved = _saved_every_step(raw, checked, save_states, stages)
            return inner[:4], inner[4], fail, saved

        def body(c, b):
            inner, fail = c
            inner, fail, raw, checked, _ = block(inner, fail, b * k, k)
            saved = _saved(*jax.tree.map(lambda a: a[None], (raw, checked)), k, save_states)
            return (inner, fail), jax.tree.map(lambda a: a[0], saved)

        offsets = jnp.arange(blocks, dtype=clock.dtype)
        (inner, fail), saved = jax.lax.scan(body, (init, fail0), offsets, length=blocks)
        return inner[:4], inner[4], fail, saved

    return chunk


#: models whose arrays hold at most this many numbers have them baked into the program
_CONSTANT_LIMIT = 1 << 16


def _with_constants(packed, constants, _none, h, clock, carry):
    return packed(constants, h, clock, carry)


class CompiledChunk:
    """A jitted chunk with the model's arrays passed as arguments (not baked in as
    constants): compilation stays fast for large models, and a call costs one dispatch.

    The outputs are packed into one float64 buffer and unpacked on the host as views: a
    transfer per array is what a short run's call time is made of.

    ``guard``: the initial-data check's linear test ``(M, c)`` (or ``None``); an
    unbatched chunk given one appends its :func:`input_verdict` to the output.
    """

    def __init__(
        self,
        system,
        rule,
        scheme,
        method,
        k,
        save_states,
        blocks,
        batched=False,
        guard=None,
        keep_stages=False,
    ):
        dynamic, static = eqx.partition((system, rule, method), eqx.is_array)
        n, m = system.n, system.m
        nodal = keeps_nodal(system, rule, save_states)
        # every step's stages are kept only when asked (a diagnostic's need)
        stage_width = rule.stages * (n + m) if keep_stages else 0

        def packed(dynamic, h, clock, carry):
            system_, rule_, method_ = eqx.combine(dynamic, static)
            chunk = chunk_runner(
                system_, rule_, scheme, method_, k, save_states, blocks, bool(stage_width)
            )
            (q, p, q_prev, mu), (code, its, res, q_bad), saved = chunk(h, clock, carry)
            cols = [saved["energy"][:, None], saved["violation"][:, None]]
            if save_states:
                cols += [saved["q"], saved["p"], saved["mu"], saved["con"]]
            if nodal:
                cols.append(saved["p_node"])
            if stage_width:
                cols.append(saved["stage"])
            steps_f = jnp.concatenate(cols, axis=1)
            steps_i = jnp.stack([saved["n_good"], saved["iterations"]], axis=1)
            final_f = jnp.concatenate([q, p, q_prev, mu, res[None], q_bad])
            final_i = jnp.stack([code, its])
            # one flat float64 buffer: one device-to-host transfer (the counts are exact)
            return jnp.concatenate(
                [
                    steps_f.ravel(),
                    steps_i.astype(steps_f.dtype).ravel(),
                    final_f,
                    final_i.astype(steps_f.dtype),
                ]
            )

        self._dynamic = dynamic
        size = sum(leaf.size for leaf in jax.tree.leaves(dynamic))
        baked = None
        if size <= _CONSTANT_LIMIT:
            # small models: the arrays become compile-time constants, so a call passes
            # only the state (dispatch cost does not grow with the number of subsystems)
            self._dynamic, baked = None, dynamic
            packed = partial(_with_constants, packed, dynamic)
        guarded = guard is not None and not batched
        self.layout = OutputLayout(n, m, blocks, save_states, nodal, guarded, stage_width)
        code_at = self.layout.code
        self._batched = batched
        if not batched:
            # one flat input (h, t0, first index, q, p, q_prev, μ): a jitted call costs
            # about a microsecond per argument array, more than the arithmetic of a step
            def flat(dynamic, x):
                carry = (x[3 : 3 + n], x[3 + n : 3 + 2 * n], x[3 + 2 * n : 3 + 3 * n])
                out = packed(dynamic, x[0], x[1:3], (*carry, x[3 + 3 * n :]))
                if not guarded:
                    return out
                return jnp.append(out, input_verdict(guard, x, out[code_at]))

            fn, kind = flat, "one run"
        elif isinstance(method, AffineStepMap):
            # Each affine run is already vectorized over its steps; batching members
            # only multiplies the size of every intermediate (memory-bound), so the
            # members run one after another inside the one compiled call (measured 3.5×
            # faster than vmap at 10³ members of the torn chain).
            def fn(dynamic, h, clock, carry):
                return jax.lax.map(lambda c: packed(dynamic, h, clock, c), carry)

            kind = "members one after another"
        else:
            # Newton's many tiny operations per step amortize well over a batch.
            fn, kind = jax.vmap(packed, in_axes=(None, None, None, 0)), "members vmapped"
        # kept on disk (diracvi.runtime.store) under everything the program closes over
        context = (kind, static, scheme, k, save_states, blocks, nodal, baked)
        if stage_width:  # (a separate entry: the programs of every other run keep their keys)
            context += ("stages", stage_width)
        if guarded:
            context += ("guard", *guard)
        self._fn = stored_chunk_jit(fn, "diracvi.driver.stepping.CompiledChunk", context)
        self._call = None  # the compiled program of an unbatched chunk, at first dispatch

    @staticmethod
    def flat_input(h, clock, carry) -> np.ndarray:
        """The one input vector ``(h, t0, first index, q, p, q_prev, μ)`` of :meth:`run`;
        ``h``, ``t0`` and the index may be Python floats."""
        return np.concatenate(((h, clock[0], clock[1]), *carry))

    def dispatch(self, x):
        """Run an unbatched chunk on the flat input ``x``; returns the (device) packed
        output (at once, before the run ends, where JAX's CPU dispatch is asynchronous:
        see :mod:`diracvi.runtime.dispatch`)."""
        if self._call is None:
            program, leaves = self._fn.program(self._dynamic, x)
            if program is None:
                self._call = partial(self._fn.plain, self._dynamic)
            else:  # the model's arrays, then x: the program's inputs in order
                self._call = partial(program, *leaves[:-1])
        return self._call(x)

    def run(self, x) -> np.ndarray:
        """The packed output (see :class:`OutputLayout`) of an unbatched chunk."""
        return np.asarray(self.dispatch(x))

    def __call__(self, h, clock, carry):
        """``(carry, fail, saved)`` as numpy arrays (views into the packed output);
        ``clock = (t0, index of the first step)`` as a float64 array."""
        if self._batched:
            flat = np.asarray(self._fn(self._dynamic, h, clock, carry))
        else:
            flat = self.run(self.flat_input(h, clock, carry))
        return self.layout.unpack(flat)


def input_verdict(guard, x, code):
    """``‖M z − c‖₂²`` for the run's initial state ``z = (q0, p0)`` in the flat input
    ``x``, or ``inf`` if ``x`` is not finite or the run did not take every step
    (``code ≠ 0``): a verdict ``≤ 1`` means the data pass the initial-data check
    (:meth:`~diracvi.model.consistency.Checker.quick_test`) and the run's output is whole.

    Computed inside the program, so a warm call reads one number instead of checking
    the data with NumPy operations of its own (each costs a few µs right after a
    program has run, its caches cold)."""
    matrix, offset = guard
    n2 = matrix.shape[1]
    r = matrix @ x[3 : 3 + n2]
    if offset is not None:
        r = r - offset
    ok = jnp.all(jnp.isfinite(x)) & (code == 0)
    return jnp.where(ok, r @ r, jnp.inf)


class OutputLayout:
    """Where each output of a chunk lies in its packed float64 buffer (leading batch
    axes allowed): ``blocks`` rows of :attr:`columns`, then the per-row
    ``(n_good, iterations)``, the final carry ``(q, p, q_prev, μ)``, the first failure's
    residual and state, its ``(code, iterations)``, and, in a guarded chunk, the
    :func:`input_verdict` at :attr:`verdict` (else ``None``). ``stage_width > 0``: each
    row ends with the step's :func:`stage_record` (column ``"stage"``)."""

    def __init__(
        self,
        n: int,
        m: int,
        blocks: int,
        save_states: bool,
        nodal: bool,
        guarded=False,
        stage_width: int = 0,
    ):
        names = [("energy", None), ("violation", None)]
        if save_states:
            names += [("q", n), ("p", n), ("mu", m), ("con", m)]
        if nodal:
            names.append(("p_node", n))
        if stage_width:
            names.append(("stage", stage_width))
        self.columns: dict = {}  # name → column (a scalar) or slice of columns
        width = 0
        for name, size in names:
            self.columns[name] = width if size is None else slice(width, width + size)
            width += 1 if size is None else size
        self.n, self.m, self.blocks, self.width = n, m, blocks, width
        self.rows_end = blocks * width  # [0, rows_end): the rows, row-major
        self.counts_end = self.rows_end + 2 * blocks  # then (n_good, iterations) per row
        self.final = self.counts_end  # then q, p, q_prev, μ, residual, q_bad
        self.code = self.final + 4 * n + m + 1  # then the failure code and its iterations
        self.verdict = self.code + 2 if guarded else None

    def unpack(self, flat):
        """``(carry, fail, saved)``: views into ``flat`` (the counts as int64 copies)."""
        n, m, blocks, width = self.n, self.m, self.blocks, self.width
        lead = flat.shape[:-1]
        rows = flat[..., : self.rows_end].reshape(*lead, blocks, width)
        counts = flat[..., self.rows_end : self.counts_end].reshape(*lead, blocks, 2)
        counts = counts.astype(np.int64)
        final = flat[..., self.final : self.code]
        codes = flat[..., self.code : self.code + 2].astype(np.int64)
        carry = tuple(final[..., i * n : (i + 1) * n] for i in range(3))
        carry += (final[..., 3 * n : 3 * n + m],)
        fail = (codes[..., 0], codes[..., 1], final[..., 3 * n + m], final[..., 3 * n + m + 1 :])
        saved = {name: rows[..., col] for name, col in self.columns.items()}
        saved.update(n_good=counts[..., 0], iterations=counts[..., 1])
        return carry, fail, saved
