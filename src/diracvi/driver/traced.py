r"""``simulate`` under JAX transformations: ``jax.jit``, ``jax.grad``, ``jax.jvp``, ``jax.vmap``.

When ``simulate`` is called inside a transformation (or with tracers among ``q0``,
``p0``, ``t0`` or the system's array leaves) nothing can be sent to the host: there is no
plan cache keyed by the system's identity, no NumPy affine map, no host-side checks and no
checkpoint file. The run is then one pure JAX function of the system, the initial state
and ``t0``, built from the same chunk code as an untraced run
(:func:`~diracvi.driver.stepping.stateful_chunk_runner`), so its numbers are those of the
untraced run with the same step solver.

**Derivatives of a step** come from the implicit function theorem, never from Newton's
iterations: the solved step is a :func:`jax.custom_jvp` function whose rule forms the step
Jacobian ``∂r/∂x`` once, at the converged step, inverts it (plain-``lax`` Gauss–Jordan,
:func:`_inverse`) and applies ``dx = −(∂r/∂x)⁻¹ ∂r/∂θ dθ`` (forward mode). Reverse mode is
JAX's linearize-then-transpose of that rule: the inverse is computed in the forward sweep
and each step's backward pass is one product ``(∂r/∂x)⁻ᵀ x̄`` and the VJP of ``r`` in its
parameters. A linear model, which an untraced run steps by the precomputed affine map, is
stepped by Newton here: it converges in one iteration, and its derivative is the same
implicit-function one.

**Reverse mode over the time loop** (``adjoint="checkpoint"``, the default) rematerializes
each step: :class:`ImplicitStep` with ``remat=True`` runs the step's program under
:func:`jax.checkpoint` with a policy that keeps each step's solution ``x`` (and its
status, iteration count, residual) and nothing else. The forward sweep is then the
forward run plus each step's solution and inputs written down; the backward pass re-forms
each step's linearization (momentum lines, ``∂r/∂x`` at the solution and its inverse,
the VJPs) from them, never its Newton solve, and uses it at once. Storing that
linearization instead, as ``adjoint="full"`` does, costs more time than recomputing it:
the torn double pendulum's 200 midpoint steps kept 147 arrays per step (358 kB) against
44 (87 kB) rematerialized, and its gradient ÷ forward run went 2.3–2.7 → 1.8 (CPU time,
min of 30, load 12–13; the RLC's 100 steps 1.8 → 1.3). When the run's stored
intermediates would exceed :data:`STORE_ALL_BYTES` the run is also split into about
√(steps) segments under the same policy, so that only the segments' ends and each step's
solution are kept across the whole run. Memory O(steps · (n + m)) — each step's solution,
as much as a saved trajectory — against ``adjoint="full"``, which stores every step's
intermediates, the inverse included (O(steps · (n + m)²)).
"""

from __future__ import annotations

import math
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.ad_checkpoint import checkpoint_name

from ..discretization.equations import StepEquations
from ..discretization.rules import get_rule
from ..errors import ModelError
from ..solvers.affine import AffineSolver
from ..solvers.base import StepResult, StepSolver
from ..solvers.partitioned import PartitionedSolver
from .stepping import keeps_nodal, stateful_chunk_runner, step_times
from .trajectory import Trajectory

ADJOINTS = ("checkpoint", "full")
#: the name of each step's solution in a checkpointed segment (the values it saves)
SOLUTION_NAME = "diracvi_step_solution"


try:  # the active trace, looked up once here rather than on every call
    from jax._src.core import EvalTrace as _EvalTrace
    from jax._src.core import trace_ctx as _trace_ctx
except ImportError:  # pragma: no cover - another JAX version
    _trace_ctx = None


def is_traced(*trees) -> bool:
    """Whether a JAX transformation is active, or any leaf of ``trees`` is a tracer.

    The first test catches a system whose *closures* capture traced values (a model
    built inside the differentiated function), which no leaf would reveal.
    """
    if _trace_ctx is not None and not isinstance(_trace_ctx.trace, _EvalTrace):
        return True
    return bool(trees) and any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(trees))


#: up to this many unknowns the elimination is unrolled (straight-line code, no loop)
_UNROLL_SIZE = 16


def _inverse(a):
    r"""``a⁻¹`` by Gauss–Jordan elimination with partial pivoting, in plain ``lax`` ops.

    Column ``j``: exchange row ``j`` with the row ``p ≥ j`` of the largest ``|a_pj|`` (the
    pivot LAPACK's ``getrf`` takes), written as the rank-one update
    ``A ← A + (e_j − e_p)(a_p − a_j)ᵀ`` so no gather is needed, then clear column ``j`` in
    every other row; applied to ``[A | I]`` this leaves ``[D | D a⁻¹]`` with ``D``
    diagonal. Not ``jnp.linalg.inv``: in the backward pass of a checkpointed scan under
    ``jax.jit`` (JAX 0.10.2, CPU) XLA receives LAPACK's ``getrf`` as an untyped custom
    call and refuses to run it ("No registered implementation for untyped custom call to
    lapack_dgetrf_ffi for Host"; rechecked on this version with the filter_grad test's
    model). Small matrices (the dense Newton models) are eliminated in straight-line
    code, larger ones in a loop.
    """
    size = a.shape[0]
    rows = jnp.arange(size)

    def eliminate(j, ab):
        a, b = ab
        column = jax.lax.dynamic_index_in_dim(a, j, axis=1, keepdims=False)
        pivot = jnp.argmax(jnp.where(rows >= j, jnp.abs(column), -1.0))
        exchange = (rows == j).astype(a.dtype) - (rows == pivot).astype(a.dtype)
        # row j ↔ row p: e_j − e_p times (row p − row j), i.e. −exchange @ A
        a = a - jnp.outer(exchange, exchange @ a)
        b = b - jnp.outer(exchange, exchange @ b)
        row_a = jax.lax.dynamic_index_in_dim(a, j, axis=0, keepdims=False)
        row_b = jax.lax.dynamic_index_in_dim(b, j, axis=0, keepdims=False)
        column = jax.lax.dynamic_index_in_dim(a, j, axis=1, keepdims=False)
        factors = jnp.where(rows != j, column / row_a[j], 0.0)
        return a - jnp.outer(factors, row_a), b - jnp.outer(factors, row_b)

    ab = (a, jnp.eye(size, dtype=a.dtype))
    if size <= _UNROLL_SIZE:
        for j in range(size):
            ab = eliminate(j, ab)
    else:
        ab = jax.lax.fori_loop(0, size, eliminate, ab)
    a, b = ab
    return b / jnp.diagonal(a)[:, None]


def _zero_tangent(leaf):
    """The tangent of a non-differentiated output: float0 for integers and booleans."""
    if jnp.issubdtype(leaf.dtype, jnp.inexact):
        return jnp.zeros_like(leaf)
    return np.zeros(leaf.shape, dtype=jax.dtypes.float0)


def _hoisted(fn, example):
    """``fn(x)`` as ``(converted(x, *values), values)``: every traced value ``fn`` captures
    is lifted to an argument (:func:`jax.closure_convert` lifts only those being
    differentiated and leaves the others captured, which a ``custom_jvp`` cannot take)."""
    closed, shape = jax.make_jaxpr(fn, return_shape=True)(example)
    tree = jax.tree.structure(shape)
    jaxpr, consts = closed.jaxpr, closed.consts
    traced = [isinstance(c, jax.core.Tracer) for c in consts]
    kept = [None if t else c for c, t in zip(consts, traced, strict=True)]

    def converted(x, *values):
        it = iter(values)
        full = [next(it) if t else c for c, t in zip(kept, traced, strict=True)]
        return jax.tree.unflatten(tree, jax.core.eval_jaxpr(jaxpr, full, x))

    return converted, tuple(c for c, t in zip(consts, traced, strict=True) if t)


@partial(jax.custom_jvp, nondiff_argnums=(0, 1))
def _implicit_root(solve, residual, guess, solve_consts, residual_consts):
    """``(x, *aux) = solve(guess, *solve_consts)`` with ``residual(x, *residual_consts) = 0``
    differentiated by the implicit function theorem (the JVP rule below)."""
    return solve(guess, *solve_consts)


@_implicit_root.defjvp
def _implicit_root_jvp(solve, residual, primals, tangents):
    r"""``dx = −(∂r/∂x)⁻¹ (∂r/∂θ dθ)`` with ``∂r/∂x`` formed and inverted once, at the
    converged ``x``.

    The inverse is a primal value of this rule, so under reverse mode JAX's
    linearize-then-transpose computes it in the forward sweep and the transposed tangent
    is one product ``(∂r/∂x)⁻ᵀ x̄`` per step, followed by the VJP of ``r`` in ``θ``;
    forward mode applies it to ``∂r/∂θ dθ``. The guess and the solver's own inputs get no
    derivative: the solution depends on ``θ`` only through ``r(x, θ) = 0``.
    """
    guess, solve_consts, residual_consts = primals
    residual_dots = tangents[2]
    out = solve(guess, *solve_consts)
    # named so a checkpointed segment keeps them (the solution, its status, iterations and
    # residual; not the solver's factors): its recomputation then skips the Newton solve
    out = (*(checkpoint_name(leaf, SOLUTION_NAME) for leaf in out[:4]), *out[4:])
    x = out[0]
    jacobian = jax.jacfwd(lambda y: residual(y, *residual_consts))(x)
    inverse = _inverse(jacobian)
    _, rhs = jax.jvp(lambda *c: residual(x, *c), tuple(residual_consts), tuple(residual_dots))
    x_dot = -(inverse @ rhs)
    return out, (x_dot, *(_zero_tangent(leaf) for leaf in out[1:]))


class ImplicitStep(StepSolver):
    """A step solver whose solution is differentiated by the implicit function theorem.

    The wrapped solver runs inside :func:`_implicit_root` (a ``custom_jvp``); its status,
    iteration count and state (factors) pass through as non-differentiated outputs.

    ``remat=True`` (``adjoint="checkpoint"``): each step's program is a
    :func:`jax.checkpoint` that saves only the step's solution (:data:`SOLUTION_NAME`),
    so reverse mode keeps per step the solution and the step's inputs, and the backward
    pass re-forms the step's linearization from them (``∂r/∂x`` at the solution, its
    inverse, the momentum line's derivatives), never its Newton solve.
    """

    inner: StepSolver
    remat: bool = eqx.field(static=True, default=False)

    def step_program(self, advance):
        if not self.remat:
            return advance
        policy = jax.checkpoint_policies.save_only_these_names(SOLUTION_NAME)
        return jax.checkpoint(advance, prevent_cse=False, policy=policy)

    def check(self, system, rule, scheme):
        self.inner.check(system, rule, scheme)

    def init(self, eqs):
        return self.inner.init(eqs)

    def momentum(self, eqs, x, state=None):
        return self.inner.momentum(eqs, x, state)

    def solve(self, eqs, guess, state, atol=None) -> StepResult:
        trees = []

        def solve(x0):
            res = self.inner.solve(eqs, x0, state, atol)
            aux = (res.status, res.iterations, res.residual_norm, res.state)
            leaves, tree = jax.tree.flatten(aux)
            trees[:] = [tree]
            return (res.x, *leaves)

        # the traced values both functions capture (the state, the system's parameters,
        # traced closures) become explicit arguments, so the JVP rule can differentiate
        solve_c, solve_consts = _hoisted(solve, guess)
        residual_c, residual_consts = _hoisted(eqs.residual, guess)
        x, *leaves = _implicit_root(
            solve_c, residual_c, guess, tuple(solve_consts), tuple(residual_consts)
        )
        status, iterations, res_norm, new_state = jax.tree.unflatten(trees[0], leaves)
        if isinstance(self.inner, PartitionedSolver):
            # the stacked subsystem parameters feed the momentum line: keep their
            # derivatives (the solver's auxiliary outputs carry none)
            new_state = (state[0], *new_state[1:])
        return StepResult(x, status, iterations, res_norm, new_state)


def _step_solver(system, rule, scheme, solver) -> StepSolver:
    from .plan import default_solver

    if isinstance(solver, StepSolver):
        return solver
    if isinstance(solver, AffineSolver):
        return solver.fallback
    return default_solver(system, rule, scheme)


#: ``adjoint="checkpoint"`` stores every step's intermediates when they take at most this
#: many bytes (:func:`stored_bytes`): recomputing segments then saves memory no one
#: needs, at the price of a second linearization of every step (measured on the RLC of
#: ``diracvi bench --only gradients``, 400 steps: gradient ÷ forward 4.5 checkpointed,
#: 2.0 stored whole, under the same load)
STORE_ALL_BYTES = 8 << 20


def stored_bytes(system, rule, steps: int) -> int:
    """An upper estimate of what ``adjoint="full"`` keeps for the backward pass: per step
    the inverse Jacobian of the ``N = (n + m)(1 + stages)`` unknowns and a few more
    ``N × N`` and ``N``-sized intermediates (float64)."""
    unknowns = (system.n + system.m) * (1 + rule.stages)
    return 8 * steps * (4 * unknowns * unknowns + 16 * unknowns)


def segment_length(blocks: int) -> int:
    """Blocks per checkpointed segment: about √blocks, a divisor of ``blocks`` when one
    is near (a remainder costs a second compiled chunk)."""
    root = max(1, math.isqrt(blocks))
    for d in sorted(range(max(1, root // 2), 2 * root + 1), key=lambda d: abs(d - root)):
        if blocks % d == 0:
            return d
    return root


def check_traced_options(checkpoint, project_initial) -> None:
    if checkpoint is not None:
        raise ModelError(
            f"checkpoint={checkpoint!r} cannot be used when simulate is traced (inside "
            "jax.jit, jax.grad, jax.vmap, ...): a traced run cannot write files. Fix: drop "
            "checkpoint=, or call simulate outside the transformation."
        )
    if project_initial:
        raise ModelError(
            "project_initial=True cannot be used when simulate is traced (inside jax.jit, "
            "jax.grad, jax.vmap, ...): the projection is a host-side least-squares step. "
            "Fix: project once outside the transformation (dv.simulate(..., steps=1, "
            "project_initial=True) and take traj.q[0], traj.p[0]), then trace from there."
        )


def _as_state(arg, value, n):
    arr = jnp.asarray(value, dtype=jnp.float64)
    if arr.shape != (n,):
        raise ModelError(
            f"{arg} has shape {arr.shape} but the system has {n} coordinates: pass a 1-D "
            f"array of length {n}."
        )
    return arr


def simulate_traced(
    system, q0, p0, t0, run, solver, *, save_states: bool, throw: bool, adjoint: str
) -> Trajectory:
    """The pure-JAX run of :func:`diracvi.simulate` (see the module documentation)."""
    scheme, shape = run.scheme, run.shape
    rule = get_rule(run.discretization)
    inner = _step_solver(system, rule, scheme, solver)
    inner.check(system, rule, scheme)
    method = ImplicitStep(inner, remat=adjoint == "checkpoint")
    q0 = _as_state("q0", q0, shape.n)
    p0 = _as_state("p0", p0, shape.n)
    t0 = jnp.asarray(t0, dtype=jnp.float64)
    if t0.shape != ():
        raise ModelError(f"t0 has shape {t0.shape}: it must be a single number.")
    return _run(
        system, rule, scheme, method, inner, (q0, p0, t0), run, bool(save_states), throw, adjoint
    )


def _run(system, rule, scheme, method, inner, start, run, save_states, throw, adjoint):
    q0, p0, t0 = start
    h, steps, k, shape = run.h, run.steps, run.save_every, run.shape
    m = shape.m
    blocks = steps // k
    seg = blocks
    if adjoint == "checkpoint" and stored_bytes(system, rule, steps) > STORE_ALL_BYTES:
        seg = segment_length(blocks)
    count, rest = divmod(blocks, seg)
    h_arr = jnp.asarray(h, dtype=jnp.float64)
    nodal = keeps_nodal(system, rule, save_states)

    carry = (q0, p0, q0, jnp.zeros(m, dtype=q0.dtype))
    t_first = step_times(scheme, h_arr, jnp.stack([t0, 0.0]), 0, 1)[0][0]
    state = method.init(StepEquations(system, rule, scheme, h_arr, q0, p0, t_first))
    fail = (jnp.asarray(0), jnp.asarray(0), jnp.asarray(jnp.nan, q0.dtype), q0)
    runner = stateful_chunk_runner(system, rule, scheme, method, k, save_states, seg)

    def segment(c, first):
        carry, state, fail = c
        clock = jnp.stack([t0, first])
        carry, state, fail, saved = runner(h_arr, clock, carry, state, fail)
        return (carry, state, fail), saved

    if adjoint == "checkpoint" and count > 1:
        policy = jax.checkpoint_policies.save_only_these_names(SOLUTION_NAME)
        segment = jax.checkpoint(segment, prevent_cse=False, policy=policy)
    firsts = jnp.arange(count, dtype=jnp.float64) * (seg * k)
    (carry, state, fail), saved = jax.lax.scan(segment, (carry, state, fail), firsts)
    saved = jax.tree.map(lambda a: a.reshape(count * seg, *a.shape[2:]), saved)
    if rest:
        tail = stateful_chunk_runner(system, rule, scheme, method, k, save_states, rest)
        clock = jnp.stack([t0, jnp.asarray(count * seg * k, dtype=jnp.float64)])
        carry, state, fail, more = tail(h_arr, clock, carry, state, fail)
        saved = jax.tree.map(lambda a, b: jnp.concatenate([a, b]), saved, more)

    code = fail[0]
    q = p = p_nodal = mu = con = None
    if save_states:
        q = jnp.concatenate([q0[None], saved["q"]])
        p = jnp.concatenate([p0[None], saved["p"]])
        mu, con = saved["mu"], saved["con"]
        if nodal:
            p_nodal = jnp.concatenate([p0[None], saved["p_node"]])
    if throw:
        # on every output a caller may read, so no use of the result escapes the check
        carry, q, p, energy = eqx.error_if(
            (carry, q, p, saved["energy"]),
            code != 0,
            "a step failed in a traced dv.simulate (status != 0: 1 Newton did not converge, "
            "2 singular step equations, 3 NaN/Inf); pass throw=False to get the status in "
            "traj.status instead",
        )
    index = np.arange(blocks + 1, dtype=np.int64) * k
    sign = 1.0 if scheme == "plus" else -1.0
    return Trajectory.traced(
        t=t0 + sign * h * jnp.asarray(index, dtype=jnp.float64),
        q=q,
        p=p,
        p_nodal=p_nodal,
        multipliers=mu,
        energy=energy if throw else saved["energy"],
        constraint_residual=con,
        newton_iterations=saved["iterations"],
        constraint_violation=saved["violation"],
        step_index=index,
        save_every=k,
        final_state=carry,
        coords=shape.coords,
        constraint_names=shape.constraint_names,
        dt=h,
        scheme=scheme,
        discretization=rule.name,
        system_name=shape.name,
        status=code,
        steps_requested=steps,
        solver=f"{inner!r} (traced; implicit-function derivatives, adjoint={adjoint!r})",
    )
