r"""One batch of a sweep: build its members, plan them as :func:`~diracvi.simulate`
does, and step each group of alike members with one compiled, vmapped program.

A batch is a pure function of its members' parameter values (:func:`run_batch`), so a
retried Dask task gives bitwise the same numbers. Each group's stepping method is the
one :class:`~diracvi.driver.plan.Plan` chooses for a ``simulate`` call of its members:
the affine step map when their step equations are linear (one map per member, all of
them built together by :func:`~diracvi.driver.plan.plan_members` and stepped vmapped),
the given or default solver otherwise.
"""

from __future__ import annotations

import warnings
from collections import OrderedDict
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.equations import first_guess, residual
from ..discretization.rules import get_rule
from ..driver.plan import MemberPlan, equation_names, plan_members, unknown_names
from ..driver.simulate import check_run
from ..driver.stepping import chunk_runner
from ..errors import DiracviError, ModelError, UnsolvableStepError
from ..model.consistency import Checker
from ..runtime.compile import run_once_jit, stored_chunk_jit
from ..runtime.config import ensure_float64
from ..solvers.solvability import DENSE_CHECK_LIMIT, check_step_jacobian, singular_members
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


def _take(tree, rows, size: int):
    """The rows ``rows`` of every (stacked) array leaf of ``tree``, padded to ``size``."""
    return jax.tree.map(lambda a: _pad(np.asarray(a)[rows], size), tree)


class _Group(NamedTuple):
    """Members of one structure, their array leaves and initial data stacked and padded."""

    index: np.ndarray  # the members' rows in the batch
    static: object  # their systems' shared non-array part
    system: object  # one of them
    dynamic: object  # their array leaves, (size, ...)
    q0: np.ndarray  # (size, n)
    p0: np.ndarray

    def rows(self, rows: np.ndarray, size: int) -> _Group:
        """The members ``rows`` (positions in this group), padded to ``size``."""
        dynamic, q0, p0 = _take((self.dynamic, self.q0, self.p0), rows, size)
        return _Group(self.index[rows], self.static, self.system, dynamic, q0, p0)


def _plan(group: _Group, rule, settings: SweepSettings) -> MemberPlan:
    """The stepping method :func:`~diracvi.simulate` would choose for each member."""
    return plan_members(
        group.system,
        group.static,
        group.dynamic,
        rule,
        settings.scheme,
        settings.dt,
        settings.solver,
        group.q0,
        group.p0,
        settings.t0,
    )


def _refuse(out: dict, i: int, member, message: str, described: str) -> None:
    """Member ``i`` is not stepped: its first step is not solvable (``message``)."""
    _, q0, p0, _ = member
    out["q"][i, 0], out["p"][i, 0] = q0, p0
    out["status"][i], out["steps_taken"][i] = int(SolveStatus.SINGULAR), 0
    out["message"][i], out["solver"][i] = message, described


def _run_rows(out: dict, group: _Group, method, per_member: bool, members, names, values, rule,
              settings: SweepSettings) -> None:  # fmt: skip
    """Step the members of ``group`` by ``method`` (a solver shared by all, or with
    ``per_member`` an affine step map whose leaves are stacked over them) in one
    compiled, vmapped program, and write their rows of ``out``."""
    scheme, h, k = settings.scheme, settings.dt, settings.save_every
    blocks = settings.steps // k
    index, size, system0 = group.index, len(group.q0), group.system
    count = len(index)
    coords = system0.coords
    method_dynamic, method_static = eqx.partition(method, eqx.is_array)
    singular = np.zeros(count, bool)
    if per_member:  # the plan checked each member's step Jacobian already
        described = "affine step map"
    else:  # as simulate does before stepping: the first step must be solvable
        described = repr(method)
        if system0.n + system0.m <= DENSE_CHECK_LIMIT:
            jacs = _step_jacobians(
                group.static, rule, scheme, h, settings.t0, group.dynamic, group.q0, group.p0
            )
            singular = singular_members(jacs)[:count]

    carry = (group.q0, group.p0, group.q0, np.zeros((size, system0.m)))
    clock = np.array([settings.t0, 0.0])
    fn = _program(group.static, rule, scheme, method_static, per_member, k, blocks)
    res = fn(group.dynamic, method_dynamic, np.float64(h), clock, carry)
    res = {key: np.asarray(value)[:count] for key, value in res.items()}
    out["solver"][index] = described

    n_good = res["n_good"]
    full = n_good == k
    whole = np.where(full.all(axis=1), blocks, np.argmin(full, axis=1))
    rows = np.arange(count)
    partial = np.where(whole < blocks, n_good[rows, np.minimum(whole, blocks - 1)], 0)
    taken = whole * k + partial
    kept = np.arange(blocks)[None, :] < whole[:, None]
    status = np.where(whole < blocks, res["code"], 0)

    q0, p0 = group.q0[:count], group.p0[:count]
    q = np.concatenate([q0[:, None], res["q"]], axis=1)
    p = np.concatenate([p0[:, None], res["p"]], axis=1)
    keep_state = np.concatenate([np.ones((count, 1), bool), kept], axis=1)
    out["q"][index] = np.where(keep_state[..., None], q, np.nan)
    out["p"][index] = np.where(keep_state[..., None], p, np.nan)
    out["energy"][index] = np.where(kept, res["energy"], np.nan)
    out["violation"][index] = np.where(kept, res["violation"], np.nan)
    out["status"][index] = status
    out["steps_taken"][index] = taken
    sign = 1.0 if scheme == "plus" else -1.0
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
        tk = settings.t0 if scheme == "plus" else settings.t0 - h
        try:
            check_step_jacobian(
                jacs[j],
                unknown_names=unknown_names(system0, scheme, rule),
                equation_names=equation_names(system0, rule),
                where=f"the first ({scheme}) step of member "
                f"{_described(names, values[i])} at t = {tk:g}",
            )
        except UnsolvableStepError as exc:
            _refuse(out, i, members[i], str(exc), described)
            out["q"][i, 1:] = out["p"][i, 1:] = np.nan
            out["energy"][i] = out["violation"][i] = np.nan
        # (else: the batched test is slightly stricter; the exact one has the say)

    # a step the affine map's verification rejected: simulate goes on with Newton
    # from there; here the member is run by simulate itself (rare: not batched)
    for j in np.nonzero((status == SolveStatus.AFFINE_REJECTED) & ~singular)[0]:
        _rerun(out, index[j], members[index[j]], settings)


def run_batch(build, names, values, settings: SweepSettings, cap: int | None = None) -> dict:
    """Run the members ``values`` (rows of parameter values) of a sweep.

    A pure function of its arguments (nothing but compiled programs is cached), so a
    Dask task that reruns it after a worker died computes bitwise the same arrays.
    Returns flat arrays over the members and the warnings to show.
    """
    ensure_float64()
    values = np.asarray(values, dtype=np.float64)
    rule = get_rule(settings.discretization)
    blocks = settings.steps // settings.save_every
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

    for alike in groups.values():
        index = np.array([i for i, _, _ in alike])
        # one structure: padded to the batch size (every batch one program); several:
        # each group to a power of two
        size = cap if len(groups) == 1 else _bucket(len(index), cap)
        group = _Group(
            index,
            alike[0][2],
            members[index[0]][0],
            jax.tree.map(lambda a, s=size: _pad(a, s), _stack([d for _, d, _ in alike])),
            _pad(np.stack([members[i][1] for i in index]), size),
            _pad(np.stack([members[i][2] for i in index]), size),
        )
        # the initial data consistent (a warning, as in simulate)
        bad = _inconsistent_members(
            group.system, group.static, settings.t0, group.dynamic, group.q0, group.p0
        )
        inconsistent.extend(int(i) for i in index[bad[: len(index)]])

        # the stepping method simulate would choose for each member: the affine maps
        # (their matrices depend on the parameters) are built for all of them at once
        plan = _plan(group, rule, settings)
        affine = plan.affine[: len(index)]
        refused = np.zeros(len(index), bool)
        for j, exc in plan.refused.items():
            if j < len(index):
                refused[j] = True
                message = f"member {_described(names, values[index[j]])}: {exc}"
                _refuse(out, index[j], members[index[j]], message, "affine step map")
        if plan.step_map is not None:
            parts = [(affine, plan.step_map, True), (~affine & ~refused, plan.solver, False)]
        else:
            parts = [(~refused, plan.solver, False)]
        for chosen, method, per_member in parts:
            rows = np.nonzero(chosen)[0]
            if len(rows) == 0:
                continue
            if len(rows) == len(index):
                part = group
            else:  # some members of the group: their own (smaller) padded batch
                part = group.rows(rows, _bucket(len(rows), cap))
            if per_member and part is not group:  # their rows of the stacked maps
                method = _take(method, rows, len(part.q0))
            _run_rows(out, part, method, per_member, members, names, values, rule, settings)

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
