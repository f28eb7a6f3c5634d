r"""A compiled chunk: the march of :mod:`~diracvi.driver.stepping` as one program.

:class:`CompiledChunk` jits a chunk runner with the model's arrays as arguments (or baked
in, for a small model), one flat input and one flat float64 output (:class:`OutputLayout`).

**Not a program per step count.** The chunk's number of saved records (``blocks``)
would be the static length of its scans, so every new step count compiled the march
anew (10 s of a cold lobatto call of a small mechanism). An unbatched chunk stepped by a
solver is therefore compiled for a *capacity* (:func:`capacity`: a rung of a geometric
ladder), and the run's own number of blocks is a runtime value, the last entry of the
flat input: the steps past it are not solved (a Newton step's frozen branch) and their
rows are cut off on the host (:class:`SizedChunk`). The steps that are taken repeat the
arithmetic of a program of their own length exactly (see
:func:`~diracvi.driver.stepping.stateful_chunk_runner`). The affine map's runs, batched
chunks and traced runs keep a program per length (see
:meth:`~diracvi.driver.plan.Plan.chunk`).
"""

from __future__ import annotations

import copy
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..runtime.compile import stored_chunk_jit
from ..solvers.affine import AffineStepMap
from .stepping import chunk_runner, keeps_nodal

#: models whose arrays hold at most this many numbers have them baked into the program
_CONSTANT_LIMIT = 1 << 16


def _with_constants(packed, constants, _none, h, clock, carry, count=None):
    return packed(constants, h, clock, carry, count)


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
        counted=False,
    ):
        dynamic, static = eqx.partition((system, rule, method), eqx.is_array)
        n, m = system.n, system.m
        nodal = keeps_nodal(system, rule, save_states)
        # every step's stages are kept only when asked (a diagnostic's need)
        stage_width = rule.stages * (n + m) if keep_stages else 0

        def packed(dynamic, h, clock, carry, count=None):
            system_, rule_, method_ = eqx.combine(dynamic, static)
            chunk = chunk_runner(
                system_, rule_, scheme, method_, k, save_states, blocks, bool(stage_width)
            )
            (q, p, q_prev, mu), (code, its, res, q_bad), saved = chunk(h, clock, carry, count)
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
            # one flat input (h, t0, first index, q, p, q_prev, μ[, blocks]): a jitted
            # call costs about a microsecond per argument array, more than the arithmetic
            # of a step
            def flat(dynamic, x):
                carry = (x[3 : 3 + n], x[3 + n : 3 + 2 * n], x[3 + 2 * n : 3 + 3 * n])
                carry += (x[3 + 3 * n : 3 + 3 * n + m],)
                count = x[-1].astype(jnp.int32) if counted else None
                out = packed(dynamic, x[0], x[1:3], carry, count)
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
        if counted:  # (a separate entry: a program of a static length keeps its key)
            context += ("counted",)
        if stage_width:  # (a separate entry: the programs of every other run keep their keys)
            context += ("stages", stage_width)
        if guarded:
            context += ("guard", *guard)
        self._fn = stored_chunk_jit(fn, "diracvi.driver.chunk.CompiledChunk", context)
        self._call = None  # the compiled program of an unbatched chunk, at first dispatch
        self.tail = np.zeros(0)  # what follows μ in the flat input (a counted chunk: blocks)

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
        self.rows = blocks  # the rows a run filled (of a counted chunk's capacity)
        self.rows_end = blocks * width  # [0, rows_end): the rows, row-major
        self.counts_end = self.rows_end + 2 * blocks  # then (n_good, iterations) per row
        self.final = self.counts_end  # then q, p, q_prev, μ, residual, q_bad
        self.code = self.final + 4 * n + m + 1  # then the failure code and its iterations
        self.verdict = self.code + 2 if guarded else None

    def filled(self, rows: int) -> OutputLayout:
        """This layout for a run that filled only the first ``rows`` rows."""
        layout = copy.copy(self)
        layout.rows = rows
        return layout

    def table(self, flat):
        """The filled rows (a view): shape ``(…, rows, width)``."""
        lead = flat.shape[:-1]
        rows = flat[..., : self.rows_end].reshape(*lead, self.blocks, self.width)
        return rows[..., : self.rows, :]

    def unpack(self, flat):
        """``(carry, fail, saved)``: views into ``flat`` (the counts as int64 copies)."""
        n, m, blocks = self.n, self.m, self.blocks
        lead = flat.shape[:-1]
        rows = self.table(flat)
        counts = flat[..., self.rows_end : self.counts_end].reshape(*lead, blocks, 2)
        counts = counts[..., : self.rows, :].astype(np.int64)
        final = flat[..., self.final : self.code]
        codes = flat[..., self.code : self.code + 2].astype(np.int64)
        carry = tuple(final[..., i * n : (i + 1) * n] for i in range(3))
        carry += (final[..., 3 * n : 3 * n + m],)
        fail = (codes[..., 0], codes[..., 1], final[..., 3 * n + m], final[..., 3 * n + m + 1 :])
        saved = {name: rows[..., col] for name, col in self.columns.items()}
        saved.update(n_good=counts[..., 0], iterations=counts[..., 1])
        return carry, fail, saved


#: a counted chunk's capacity is a multiple of this many records at least
MIN_CAPACITY = 16


def capacity(blocks: int) -> int:
    """The capacity of the counted chunk that runs ``blocks`` records: ``blocks`` rounded
    up to a multiple of ``g = max(16, 2^(⌊log₂ blocks⌋ − 3))``, so 8 to 16 rungs per
    octave. The filler past a run's records (computed: its diagnostics, a Newton step's
    frozen branch) is then under 16 rows or 1/8 of the run: measured, half the rows
    filler made a tiny pendulum's warm run 1.56× slower (``benchmarks/counted_march.py``);
    this ladder keeps it within about 8 %, and a new step count within 1/8 of the last
    compiles nothing."""
    step = max(MIN_CAPACITY, 1 << max(int(blocks).bit_length() - 4, 0))
    return max(1, -(-int(blocks) // step)) * step


class SizedChunk:
    """A counted :class:`CompiledChunk` run for ``blocks`` of its capacity: the input
    carries the count, the output layout cuts the rows past it off."""

    def __init__(self, compiled: CompiledChunk, blocks: int):
        self.compiled, self.blocks = compiled, int(blocks)
        self.layout = compiled.layout.filled(self.blocks)
        self.tail = np.array([float(self.blocks)])  # the last entry of the flat input

    def flat_input(self, h, clock, carry) -> np.ndarray:
        """``(h, t0, first index, q, p, q_prev, μ, blocks)``, the input of :meth:`run`."""
        return np.concatenate(((h, clock[0], clock[1]), *carry, self.tail))

    def dispatch(self, x):
        return self.compiled.dispatch(x)

    def run(self, x) -> np.ndarray:
        return np.asarray(self.compiled.dispatch(x))

    def __call__(self, h, clock, carry):
        """``(carry, fail, saved)`` as :meth:`CompiledChunk.__call__`, ``blocks`` rows."""
        return self.layout.unpack(self.run(self.flat_input(h, clock, carry)))
