r"""One batch of a sweep: build its members, plan them as :func:`~diracvi.simulate`
does, and step each group of alike members with one compiled, vmapped program.

A batch is a pure function of its members' parameter values (:func:`run_batch`), so a
retried Dask task gives bitwise the same numbers. Each group's stepping method is the
one :class:`~diracvi.driver.plan.Plan` chooses for a ``simulate`` call of its members:
the affine step map when their step equations are linear (one map per member, stacked
and vmapped), the given or default solver otherwise.
"""

from __future__ import annotations

import warnings
from collections import OrderedDict

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.equations import first_guess, residual
from ..discretization.rules import get_rule
from ..driver.plan import Plan, default_solver, equation_names, unknown_names
from ..driver.simulate import check_run
from ..driver.stepping import chunk_runner
from ..errors import DiracviError, ModelError, UnsolvableStepError
from ..model.consistency import Checker
from ..runtime.compile import run_once_jit, stored_chunk_jit
from ..runtime.config import ensure_float64
from ..solvers.base import StepSolver
from ..solvers.solvability import DENSE_CHECK_LIMIT, check_step_jacobian
from ..status import SolveStatus
from .points import SweepSettings, _described, _unpack

#: how many times a batch's trace ran (the tests count compilations with it)
TRACE_COUNT = 0


def _build_member(build, names, values, settings: SweepSettings):
    """``(system, q0, p0, layout)`` of one member, every argument checked."""
    kwargs = {n: float(v) for n, v in zip(names, values, strict=True)}
    where = f"build({_described(names, values)})"
    try:
        built = build(**kwargs)
    except DiracviError as exc:
        raise type(exc)(f"{where}: {exc}") from exc
    except Exception as exc:
        raise ModelError(
            f"{where} raised {type(exc).__name__}: {exc}. Fix build, or leave these values "
            "out of the sweep."
        ) from exc
    system, q0, p0 = _unpack(built, where)
    try:
        run = check_run(
            system,
            settings.scheme,
            settings.discretization,
            settings.dt,
            settings.steps,
            settings.save_every,
            None,
        )
        shape = run.shape
        from ..model.validate import check_state

        q0 = check_state("q0", q0, shape.n, shape.coords)
        p0 = check_state("p0", p0, shape.n, shape.coords)
    except ModelError as exc:
        raise ModelError(f"{where}: {exc}") from exc
    return system, q0, p0, shape


def _structure_key(system):
    dynamic, static = eqx.partition(system, eqx.is_array)
    leaves, treedef = jax.tree.flatten(dynamic)
    shapes = tuple((np.shape(a), np.dtype(a.dtype).str) for a in leaves)
    key = (static, treedef, shapes)
    try:
        hash(key)
    except TypeError:
        return None, dynamic, static  # unhashable static part: a group of its own
    return key, dynamic, static


_PROGRAMS: OrderedDict = OrderedDict()
#: compiled programs kept (least recently used dropped): members that never group would
#: otherwise keep one program each
_PROGRAM_LIMIT = 64


def _program(static, rule, scheme, method_static, per_member: bool, k: int, blocks: int):
    """``jit(vmap(member))`` over stacked array leaves and carries (cached per structure).

    The stepping method is ``eqx.combine(method_dynamic, method_static)``: a solver
    shared by the members, or (``per_member``) one affine step map per member, stacked.
    """

    def member(dynamic, method_dynamic, h, clock, carry):
        global TRACE_COUNT
        TRACE_COUNT += 1  # runs once per trace, i.e. once per compilation
        system = eqx.combine(dynamic, static)
        method = eqx.combine(method_dynamic, method_static)
        chunk = chunk_runner(system, rule, scheme, method, k, True, blocks)
        (q, p, _, _), (code, its, res, q_bad), saved = chunk(h, clock, carry)
        return {
            "q": saved["q"],
            "p": saved["p"],
            "energy": saved["energy"],
            "violation": saved["violation"],
            "n_good": saved["n_good"],
            "final_q": q,
            "final_p": p,
            "code": code,
            "iterations": its,
            "residual": res,
            "q_bad": q_bad,
        }

    batched = jax.vmap(member, in_axes=(0, 0 if per_member else None, None, None, 0))
    context = ("chunk", static, rule, scheme, method_static, per_member, k, blocks)
    return _cached(
        "chunk",
        (static, rule.name, scheme, method_static, per_member, k, blocks),
        lambda: stored_chunk_jit(batched, "diracvi.sweeps.batch.member", context),
    )


def _bucket(count: int, cap: int) -> int:
    """Groups are padded to a power of two (at most ``cap``): few distinct batch shapes,
    so few compilations, whatever the group sizes."""
    return max(count, min(cap, 1 << (count - 1).bit_length()))


def _cached(kind, key, make):
    """A compiled program per ``(kind, key)``; ``key=None`` (unhashable) is not cached."""
    try:
        full = (kind, *key)
        hash(full)
    except TypeError:
        return make()
    if full in _PROGRAMS:
        _PROGRAMS.move_to_end(full)
        return _PROGRAMS[full]
    _PROGRAMS[full] = fn = make()
    while len(_PROGRAMS) > _PROGRAM_LIMIT:
        _PROGRAMS.popitem(last=False)
    return fn


def _step_jacobians(static, rule, scheme, h, t0, dynamic, q0, p0):
    """The first step's Jacobian ``∂r/∂(q_other, μ)`` of every member, (B, N, N)."""

    def make():
        def one(dyn, q, p, h, t0):
            system = eqx.combine(dyn, static)
            tk = t0 if scheme == "plus" else t0 - h
            x0 = first_guess(system, rule, q, q, jnp.zeros(system.m))
            return jax.jacfwd(lambda x: residual(system, rule, scheme, h, q, p, x, tk))(x0)

        return run_once_jit(
            jax.vmap(one, in_axes=(0, 0, 0, None, None)),
            "diracvi.sweeps.batch.step_jacobians",
            ("jacobian", static, rule, scheme),
        )

    fn = _cached("jacobian", (static, rule.name, scheme), make)
    return np.asarray(fn(dynamic, q0, p0, np.float64(h), np.float64(t0)))


def _singular_members(jacs) -> np.ndarray:
    """Which of the Jacobians ``(B, N, N)`` are rank-deficient or not finite (batched
    version of :func:`~diracvi.solvers.solvability.null_directions`)."""
    finite = np.all(np.isfinite(jacs), axis=(1, 2))
    safe = np.where(finite[:, None, None], jacs, 0.0)
    rows = np.max(np.abs(safe), axis=2, keepdims=True)
    scaled = safe / np.where(rows > 0, rows, 1.0)
    cols = np.max(np.abs(scaled), axis=1, keepdims=True)
    scaled = scaled / np.where(cols > 0, cols, 1.0)
    s = np.linalg.svd(scaled, compute_uv=False)
    tol = 1e-11 * max(scaled.shape[1:]) * np.where(s[:, :1] > 0, s[:, :1], 1.0)
    rank = np.sum(s > tol, axis=1)
    return ~finite | (rank < scaled.shape[1])


def _legendre_batch(static, t0, dynamic, q0):
    """``∂L/∂v(q, 0)``, ``∂²L/∂v²(q, 0)`` and ``A(q)`` of every member at ``t0``."""

    def make():
        def one(dyn, q, t0):
            system = eqx.combine(dyn, static)
            zero = jnp.zeros_like(q)
            g = jax.grad(system.lagrangian, argnums=1)(q, zero, t0)
            w = jax.hessian(system.lagrangian, argnums=1)(q, zero, t0)
            return g, w, system.constraint_forms(q, t0)

        return run_once_jit(
            jax.vmap(one, in_axes=(0, 0, None)),
            "diracvi.sweeps.batch.legendre",
            ("legendre", static),
        )

    fn = _cached("legendre", (static,), make)
    return [np.asarray(a) for a in fn(dynamic, q0, np.float64(t0))]


def _inconsistent_members(system, static, t0, dynamic, q0, p0) -> np.ndarray:
    """Which members' initial data :class:`~diracvi.model.consistency.Checker` would warn
    about (ports apart, momenta outside the Legendre image), batched."""
    checker = Checker(system)
    n = q0.shape[1]
    bad = np.zeros(len(q0), bool)
    q_scale = np.maximum(1.0, np.max(np.abs(q0), axis=1))
    p_scale = np.maximum(1.0, np.max(np.abs(p0), axis=1))
    for group in checker.groups:
        bad |= np.ptp(q0[:, group], axis=1) > 1e-12 * q_scale
    if checker.holonomic:  # g(q0, t0) = 0 is checked member by member
        for i in range(len(q0)):
            bad[i] |= checker.violations(q0[i], p0[i], t0)["holonomic"] > 1e-12 * q_scale[i]
    from ..model.consistency import MOMENTUM_CHECK_LIMIT

    if n <= MOMENTUM_CHECK_LIMIT:
        g, w, forms = _legendre_batch(static, t0, dynamic, q0)
        basis = np.concatenate([w, np.swapaxes(forms, 1, 2)], axis=2)
        if basis.shape[2] == 0:
            proj = g
        else:
            cutoff = np.finfo(np.float64).eps * max(basis.shape[1:])
            coef = np.linalg.pinv(basis, rcond=cutoff) @ (p0 - g)[:, :, None]
            proj = g + (basis @ coef)[:, :, 0]
        bad |= np.max(np.abs(p0 - proj), axis=1) > 1e-10 * p_scale
    return bad


def _stack(trees):
    return jax.tree.map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *trees)


def _pad(a, size):
    if len(a) == size:
        return a
    return np.concatenate([a, np.repeat(a[-1:], size - len(a), axis=0)])


def _group_plans(group, rule, settings: SweepSettings, size: int):
    """The stepping method of a group of alike members, chosen by simulate's
    :class:`~diracvi.driver.plan.Plan` (solver choice, affine map, solvability checks).

    Returns ``(solver, None)`` when the members share a solver, or ``(plans, (static,
    dynamic))`` when the plan is the affine step map: one plan per member (the
    :class:`UnsolvableStepError` of a member it refused in its place) and their maps'
    array leaves stacked and padded to ``size``.
    """
    solver, scheme = settings.solver, settings.scheme
    if isinstance(solver, StepSolver):
        return solver, None
    plans: list = []
    for system, q0, p0, _ in group:
        try:
            plan = Plan(system, rule, scheme, settings.dt, solver, q0, p0, settings.t0)
        except UnsolvableStepError as exc:
            plans.append(exc)
            continue
        if plan.step_map is None:  # not linear (alike members: none is): the plan's solver
            return plan.fallback, None
        plans.append(plan)
    good = [p for p in plans if isinstance(p, Plan)]
    parts = [eqx.partition(p.step_map, eqx.is_array) for p in good]
    shapes = {
        (jax.tree.structure(d), tuple(np.shape(a) for a in jax.tree.leaves(d))) for d, _ in parts
    }
    if not good or len(shapes) > 1 or any(st != parts[0][1] for _, st in parts):
        # every member refused (their checks report it), or maps of different forms
        system0 = group[0][0]
        return (default_solver(system0, rule, scheme) if solver is None else solver.fallback), None
    dynamic = [parts[0][0] if isinstance(p, UnsolvableStepError) else None for p in plans]
    it = iter(d for d, _ in parts)
    dynamic = [d if d is not None else next(it) for d in dynamic]
    stacked = jax.tree.map(lambda a, s=size: _pad(a, s), _stack(dynamic))
    return plans, (parts[0][1], stacked)


def _rerun(out: dict, i: int, member, settings: SweepSettings) -> None:
    """Member ``i`` run by :func:`~diracvi.simulate` itself, into row ``i`` of ``out``."""
    from ..driver.simulate import simulate

    system, q0, p0, _ = member
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the batch reports inconsistent data once
        traj = simulate(
            system,
            q0,
            p0,
            dt=settings.dt,
            steps=settings.steps,
            scheme=settings.scheme,
            discretization=settings.discretization,
            t0=settings.t0,
            solver=settings.solver,
            save_every=settings.save_every,
            throw=False,
        )
    rows = traj.q.shape[0]
    for name, value in (("q", traj.q), ("p", traj.p)):
        out[name][i] = np.nan
        out[name][i, :rows] = value
    for name, value in (("energy", traj.energy), ("violation", traj.constraint_violation)):
        out[name][i] = np.nan
        out[name][i, : rows - 1] = value
    out["status"][i], out["steps_taken"][i] = traj.status, traj.steps
    out["message"][i], out["solver"][i] = traj.message, traj.solver


def run_batch(build, names, values, settings: SweepSettings, cap: int | None = None) -> dict:
    """Run the members ``values`` (rows of parameter values) of a sweep.

    A pure function of its arguments (nothing but compiled programs is cached), so a
    Dask task that reruns it after a worker died computes bitwise the same arrays.
    Returns flat arrays over the members and the warnings to show.
    """
    ensure_float64()
    values = np.asarray(values, dtype=np.float64)
    rule = get_rule(settings.discretization)
    scheme, h, k = settings.scheme, settings.dt, settings.save_every
    blocks = settings.steps // k
    cap = len(values) if cap is None else max(cap, len(values))

    members = [_build_member(build, names, v, settings) for v in values]
    coords = members[0][3].coords
    for i, (_, _, _, shape) in enumerate(members):
        if shape.coords != coords:
            raise ModelError(
                f"build({_described(names, values[i])}) returned a system with coordinates "
                f"{shape.coords}, but build({_described(names, values[0])}) one with "
                f"{coords}: every member of a sweep must have the same coordinates."
            )
    count, n = len(members), len(coords)
    out = {
        "q": np.full((count, blocks + 1, n), np.nan),
        "p": np.full((count, blocks + 1, n), np.nan),
        "energy": np.full((count, blocks), np.nan),
        "violation": np.full((count, blocks), np.nan),
        "status": np.zeros(count, np.int64),
        "steps_taken": np.zeros(count, np.int64),
        "message": np.full(count, "success", dtype=object),
        "solver": np.full(count, "", dtype=object),
    }
    inconsistent: list[int] = []

    groups: dict = {}
    for i, (system, _, _, _) in enumerate(members):
        key, dynamic, static = _structure_key(system)
        groups.setdefault(key if key is not None else ("member", i), []).append(
            (i, dynamic, static)
        )

    sign = 1.0 if scheme == "plus" else -1.0
    clock = np.array([settings.t0, 0.0])
    for group in groups.values():
        index = np.array([i for i, _, _ in group])
        static = group[0][2]
        system0 = members[index[0]][0]
        q0 = np.stack([members[i][1] for i in index])
        p0 = np.stack([members[i][2] for i in index])
        # one structure: padded to the batch size (every batch one program); several:
        # each group to a power of two
        size = cap if len(groups) == 1 else _bucket(len(index), cap)
        dynamic = jax.tree.map(lambda a, s=size: _pad(a, s), _stack([d for _, d, _ in group]))
        q0s, p0s = _pad(q0, size), _pad(p0, size)

        # the stepping method simulate would choose for these members (one plan each
        # when it is the affine map: its matrices depend on the parameters)
        plans, maps = _group_plans([members[i] for i in index], rule, settings, size)
        singular = np.zeros(len(index), bool)
        if maps is not None:  # the plans checked each member's step Jacobian already
            method_static, method_dynamic = maps
            singular = np.array([isinstance(p, UnsolvableStepError) for p in plans])
            described = "affine step map"
        else:  # as simulate does before stepping: the first step must be solvable ...
            method_dynamic, method_static = eqx.partition(plans, eqx.is_array)
            described = repr(plans)
            if system0.n + system0.m <= DENSE_CHECK_LIMIT:
                jacs = _step_jacobians(static, rule, scheme, h, settings.t0, dynamic, q0s, p0s)
                singular = _singular_members(jacs)[: len(index)]
        # ... and the initial data consistent (a warning, as in simulate)
        bad = _inconsistent_members(system0, static, settings.t0, dynamic, q0s, p0s)
        inconsistent.extend(int(i) for i in index[bad[: len(index)]])

        carry = (q0s, p0s, q0s, np.zeros((size, system0.m)))
        fn = _program(static, rule, scheme, method_static, maps is not None, k, blocks)
        res = fn(dynamic, method_dynamic, np.float64(h), clock, carry)
        res = {key: np.asarray(value)[: len(index)] for key, value in res.items()}
        out["solver"][index] = described

        n_good = res["n_good"]
        full = n_good == k
        whole = np.where(full.all(axis=1), blocks, np.argmin(full, axis=1))
        rows = np.arange(len(index))
        partial = np.where(whole < blocks, n_good[rows, np.minimum(whole, blocks - 1)], 0)
        taken = whole * k + partial
        kept = np.arange(blocks)[None, :] < whole[:, None]
        status = np.where(whole < blocks, res["code"], 0)

        q = np.concatenate([q0[:, None], res["q"]], axis=1)
        p = np.concatenate([p0[:, None], res["p"]], axis=1)
        keep_state = np.concatenate([np.ones((len(index), 1), bool), kept], axis=1)
        out["q"][index] = np.where(keep_state[..., None], q, np.nan)
        out["p"][index] = np.where(keep_state[..., None], p, np.nan)
        out["energy"][index] = np.where(kept, res["energy"], np.nan)
        out["violation"][index] = np.where(kept, res["violation"], np.nan)
        out["status"][index] = status
        out["steps_taken"][index] = taken
        for j in np.nonzero(status)[0]:
            out["message"][index[j]] = SolveStatus(int(status[j])).explain(
                step=int(taken[j]),
                t=settings.t0 + sign * h * int(taken[j]),
                iterations=int(res["iterations"][j]),
                res_norm=float(res["residual"][j]),
                coords=coords,
                q=res["q_bad"][j],
            )
        for j in np.nonzero(singular)[0]:
            i = index[j]
            system, q0_i, p0_i, _ = members[i]
            tk = settings.t0 if scheme == "plus" else settings.t0 - h
            if maps is not None:  # the member's plan refused it
                message = f"member {_described(names, values[i])}: {plans[j]}"
            else:
                try:
                    check_step_jacobian(
                        jacs[j],
                        unknown_names=unknown_names(system, scheme, rule),
                        equation_names=equation_names(system, rule),
                        where=f"the first ({scheme}) step of member "
                        f"{_described(names, values[i])} at t = {tk:g}",
                    )
                except UnsolvableStepError as exc:
                    message = str(exc)
                else:  # the batched test is slightly stricter; the exact one has the say
                    continue
            out["status"][i] = int(SolveStatus.SINGULAR)
            out["message"][i] = message
            out["steps_taken"][i] = 0
            out["q"][i, 1:] = out["p"][i, 1:] = np.nan
            out["energy"][i] = out["violation"][i] = np.nan

        # a step the affine map's verification rejected: simulate goes on with Newton
        # from there; here the member is run by simulate itself (rare: not batched)
        for j in np.nonzero((status == SolveStatus.AFFINE_REJECTED) & ~singular)[0]:
            _rerun(out, index[j], members[index[j]], settings)

    messages = []
    if inconsistent:
        first = inconsistent[0]
        system, q0_i, p0_i, _ = members[first]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            Checker(system).check(q0_i, p0_i, project_initial=False, t0=settings.t0)
        text = str(caught[0].message) if caught else "inconsistent initial data"
        messages.append((len(inconsistent), f"member {_described(names, values[first])}: {text}"))
    out["inconsistent"] = messages
    out["coords"] = coords
    return out
