r"""``simulate`` under JAX transformations: ``jax.jit``, ``jax.grad``, ``jax.jvp``, ``jax.vmap``.

When ``simulate`` is called inside a transformation (or with tracers among ``q0``,
``p0``, ``t0`` or the system's array leaves) nothing can be sent to the host: there is no
plan cache keyed by the system's identity, no NumPy affine map, no host-side checks and no
checkpoint file. The run is then one pure JAX function of the system, the initial state
and ``t0``, built from the same chunk code as an untraced run
(:func:`~diracvi.driver.stepping.stateful_chunk_runner`), so its numbers are those of the
untraced run with the same step solver.

**Derivatives of a step** come from the implicit function theorem, never from Newton's
iterations: the step solver runs inside :func:`jax.lax.custom_root`, whose derivative
solves with the step Jacobian ``∂r/∂x`` at the converged step, ``dx = −(∂r/∂x)⁻¹ ∂r/∂θ dθ``
(forward mode) or its transpose (reverse mode). A linear model, which an untraced run
steps by the precomputed affine map, is stepped by Newton here: it converges in one
iteration, and its derivative is the same implicit-function one.

**Reverse mode over the time loop** stores, by default (``adjoint="checkpoint"``), only
the state at the start of each of about √(steps) segments of the run and recomputes a
segment's steps when its cotangents are needed (:func:`jax.checkpoint`): memory
O(√steps · n) for ≈ one extra forward pass. ``adjoint="full"`` stores every step's
residuals: fastest, memory O(steps · n).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.equations import StepEquations
from ..discretization.rules import get_rule
from ..errors import ModelError
from ..solvers.affine import AffineSolver
from ..solvers.base import StepResult, StepSolver
from ..solvers.partitioned import PartitionedSolver
from .stepping import keeps_nodal, stateful_chunk_runner, step_times
from .trajectory import Trajectory

ADJOINTS = ("checkpoint", "full")


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


def _tangent_solve(g, y):
    """Solve ``g(x) = y`` for the linearized step residual ``g`` (dense, (n+m)²)."""
    return _gauss_solve(jax.jacfwd(g)(y), y)


def _gauss_solve(a, b):
    """``a⁻¹ b`` by Gaussian elimination with partial pivoting, in plain ``lax`` ops.

    Not ``jnp.linalg.solve``: in the backward pass of a checkpointed scan under
    ``jax.jit`` (JAX 0.10, CPU), XLA receives the LAPACK call of this solve as an untyped
    custom call and refuses to compile it ("No registered implementation for untyped
    custom call to lapack_dgetrf_ffi"). The same elimination LAPACK's ``getrf`` does
    (row exchange to the largest pivot, then the Schur update), so the accuracy is the
    same; the cost, O((n+m)³) per step, is what the dense solve cost already.
    """
    size = a.shape[0]
    rows = jnp.arange(size)

    def eliminate(j, ab):
        a, b = ab
        pivot = jnp.argmax(jnp.where(rows >= j, jnp.abs(a[:, j]), -1.0))
        swap = rows.at[j].set(pivot).at[pivot].set(j)
        a, b = a[swap], b[swap]
        factors = jnp.where(rows > j, a[:, j] / a[j, j], 0.0)
        return a - factors[:, None] * a[j][None, :], b - factors * b[j]

    a, b = jax.lax.fori_loop(0, size, eliminate, (a, b))

    def substitute(i, x):
        k = size - 1 - i
        return x.at[k].set((b[k] - a[k] @ x) / a[k, k])

    return jax.lax.fori_loop(0, size, substitute, jnp.zeros_like(b))


class ImplicitStep(StepSolver):
    """A step solver whose solution is differentiated by the implicit function theorem.

    The wrapped solver's iterations run under :func:`jax.lax.custom_root`; its status,
    iteration count and state (factors) pass through as non-differentiated outputs.
    """

    inner: StepSolver

    def check(self, system, rule, scheme):
        self.inner.check(system, rule, scheme)

    def init(self, eqs):
        return self.inner.init(eqs)

    def momentum(self, eqs, x, state=None):
        return self.inner.momentum(eqs, x, state)

    def solve(self, eqs, guess, state) -> StepResult:
        dtypes = []

        def solve(_f, x0):
            res = self.inner.solve(eqs, x0, state)
            aux = (res.status, res.iterations, res.residual_norm, res.state)
            leaves, tree = jax.tree.flatten(aux)
            dtypes[:] = [tree, [leaf.dtype for leaf in leaves]]
            # as floats: custom_root (JAX 0.10) gives integer auxiliary outputs tangents
            # of the wrong type; the counts and pivots are exact in float64
            return res.x, [leaf.astype(x0.dtype) for leaf in leaves]

        def residual(x):  # a plain closure: custom_root hashes its functions
            return eqs.residual(x)

        x, leaves = jax.lax.custom_root(residual, guess, solve, _tangent_solve, has_aux=True)
        tree, types = dtypes
        leaves = [leaf.astype(t) for leaf, t in zip(leaves, types, strict=True)]
        status, iterations, res_norm, new_state = jax.tree.unflatten(tree, leaves)
        if isinstance(self.inner, PartitionedSolver):
            # the stacked subsystem parameters feed the momentum line: keep their
            # derivatives (custom_root's auxiliary outputs carry none)
            new_state = (state[0], *new_state[1:])
        return StepResult(x, status, iterations, res_norm, new_state)


def _step_solver(system, rule, scheme, solver) -> StepSolver:
    from .plan import default_solver

    if isinstance(solver, StepSolver):
        return solver
    if isinstance(solver, AffineSolver):
        return solver.fallback
    return default_solver(system, rule, scheme)


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
    method = ImplicitStep(inner)
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
    seg = segment_length(blocks) if adjoint == "checkpoint" else blocks
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
        segment = jax.checkpoint(segment, prevent_cse=False)
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
