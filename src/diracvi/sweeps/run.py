r"""``sweep``: one model over a grid or a table of parameter values, batched and resumable.

A sweep is split into *batches* of consecutive members (``batch_size``). A batch is a
pure function of its members' parameter values (:func:`run_batch`): it calls
``build(**values)`` for each member, checks the member's initial data and the
solvability of its first step as :func:`~diracvi.simulate` does, groups the members
whose systems share one structure, and steps each group with one compiled, vmapped
program. Batches run in this process (``client=None``) or as tasks of a
``dask.distributed`` cluster; since a batch is pure, a retried batch (its worker died)
gives bitwise the same numbers.

**Grouping.** A member's system is split with ``equinox.partition(system,
equinox.is_array)``; members whose static parts are equal and whose array leaves have
the same shapes are stacked and stepped by ``jax.jit(jax.vmap(member))``, where
``member`` rebuilds the system with ``equinox.combine`` and runs the pure chunk program
of :mod:`diracvi.driver.stepping`. Programs are cached per structure, so a grid over ``R`` and
``C`` of an ``equinox.Module`` Lagrangian compiles once. A plain function's captured
arrays and float constants are lifted to leaves when the system is built
(:mod:`diracvi.runtime.program`), so closures that compute the same thing group too; a function
that cannot be rewritten that way is its own structure: such members still run, but one
compiled program per member.

**Storage.** ``out=PATH`` creates a NetCDF file (h5netcdf) of the whole result up front,
writes every batch into its region as soon as it is done and marks it done in the
``batch_done`` variable, so memory holds one batch at a time, and a rerun with the same
``out`` skips the finished batches. The file carries a fingerprint of the sweep
(parameter values, step, scheme, ``batch_size``, ``build``); a different sweep is
refused.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import json
import os
import sys
import warnings
from collections import OrderedDict
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.equations import first_guess, residual
from ..discretization.rules import get_rule
from ..driver.plan import equation_names, unknown_names
from ..driver.simulate import check_run
from ..driver.stepping import chunk_runner
from ..errors import DiracviError, ModelError, UnsolvableStepError
from ..model.consistency import Checker, InconsistentInitialDataWarning
from ..model.system import DiracSystem
from ..model.validate import check_float, check_positive_int
from ..runtime.compile import run_once_jit, stored_chunk_jit
from ..runtime.config import ensure_float64
from ..solvers import NewtonSolver
from ..solvers.solvability import DENSE_CHECK_LIMIT, check_step_jacobian
from ..status import SolveStatus

#: names the result uses for its own dimensions and variables
RESERVED = ("time", "step", "step_time", "sample", "status", "message", "steps_taken", "energy")
RESERVED += ("constraint_violation", "batch", "batch_done")

#: default members per batch (independent of the cluster, so that the batches, and with
#: them the compiled programs and their round-off, are the same embedded and on Dask)
DEFAULT_BATCH_SIZE = 256

#: how many times a batch's trace ran (the tests count compilations with it)
TRACE_COUNT = 0


class SweepSettings(NamedTuple):
    """What every batch shares (checked once, sent to the workers with each batch)."""

    dt: float
    steps: int
    scheme: str
    discretization: str
    save_every: int
    t0: float


# ------------------------------------------------------------------ the points
def _as_values(arg: str, value) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelError(
            f"{arg}={_short(value)} is not numeric: give a 1-D array of parameter values, "
            "e.g. np.linspace(0.1, 2.0, 20)."
        ) from exc
    if arr.ndim == 0:
        arr = arr[None]
    if arr.ndim != 1:
        raise ModelError(
            f"{arg} has shape {arr.shape}; give a 1-D array of values (a grid is formed "
            "over the product of the parameters; for a table of points use samples=)."
        )
    if arr.size == 0:
        raise ModelError(f"{arg} is empty: give at least one value.")
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{arg} contains NaN or Inf: give finite values.")
    return arr


def _short(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _check_name(arg: str, name) -> str:
    if not isinstance(name, str) or not name.isidentifier():
        raise ModelError(
            f"{arg}: parameter name {name!r} is not a Python identifier; build() receives "
            "the parameters as keyword arguments, so name them like R, C or mass_1."
        )
    if name in RESERVED:
        raise ModelError(
            f"{arg}: parameter name {name!r} is reserved for the result's own "
            f"dimensions and variables {RESERVED}; rename it (e.g. {name}_value)."
        )
    return name


class Points(NamedTuple):
    """The members: ``values[i]`` are member i's parameter values (in ``names`` order)."""

    names: tuple[str, ...]
    values: np.ndarray  # (members, parameters)
    dims: tuple[str, ...]  # ("R", "C") for a grid, ("sample",) for a table
    shape: tuple[int, ...]
    axes: dict  # dimension coordinates of a grid: name -> values


def sweep_points(params, samples) -> Points:
    """Check ``params`` (a grid) or ``samples`` (a table) and list the members."""
    if (params is None) == (samples is None):
        raise ModelError(
            "give exactly one of params= (a grid: {name: 1-D values}, every combination is "
            "run) and samples= (a table: {name: values}, one member per row)."
            if params is None
            else "params= and samples= were both given: a sweep is either a grid (params=) "
            "or a table of points (samples=); pass one of them."
        )
    which = "params" if params is not None else "samples"
    table = params if params is not None else samples
    if hasattr(table, "items") and callable(table.items):
        columns = dict(table.items())
    elif getattr(getattr(table, "dtype", None), "names", None):
        columns = {n: table[n] for n in table.dtype.names}  # a structured array
    else:
        raise ModelError(
            f"{which}={_short(table)} is not a mapping: pass {{name: values}}, e.g. "
            f"{which}={{'R': np.linspace(0.1, 2, 20), 'C': [1.0, 3.0]}} (a pandas "
            "DataFrame also works for samples=)."
        )
    if not columns:
        raise ModelError(f"{which}={{}} is empty: name at least one parameter.")
    names = tuple(_check_name(which, n) for n in columns)
    values = [_as_values(f"{which}[{n!r}]", v) for n, v in columns.items()]
    if params is not None:
        shape = tuple(len(v) for v in values)
        grid = np.meshgrid(*values, indexing="ij")
        flat = np.stack([g.ravel() for g in grid], axis=1)
        return Points(names, flat, names, shape, dict(zip(names, values, strict=True)))
    lengths = {n: len(v) for n, v in zip(names, values, strict=True)}
    if len(set(lengths.values())) > 1:
        raise ModelError(
            f"samples= columns have different lengths {lengths}: a table needs one value "
            "per parameter for every sample; give arrays of equal length."
        )
    flat = np.stack(values, axis=1)
    return Points(names, flat, ("sample",), (len(flat),), {})


def check_build(build, names) -> None:
    """``build`` is callable with the parameters as keywords, or a ModelError says why."""
    if not callable(build):
        raise ModelError(
            f"build={_short(build)} is not callable: pass a function build(**values) that "
            "returns (system, q0, p0)."
        )
    try:
        signature = inspect.signature(build)
    except (TypeError, ValueError):
        return  # cannot tell: the first call will
    try:
        signature.bind(**dict.fromkeys(names, 0.0))
    except TypeError as exc:
        params = signature.parameters
        takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
        unknown = [n for n in names if n not in params and not takes_any]
        if unknown:
            raise ModelError(
                f"params: build{signature} does not accept the parameter(s) {unknown}; "
                f"rename them to arguments of build ({', '.join(params) or 'none'}) or add "
                f"them to its signature."
            ) from None
        raise ModelError(
            f"params: build{signature} cannot be called with the swept parameters "
            f"{list(names)} ({exc}); give every required argument of build a value in "
            "params= (or samples=), or a default in build."
        ) from None


# ------------------------------------------------------------------ one batch
def _described(names, values) -> str:
    return ", ".join(f"{n}={v:g}" for n, v in zip(names, values, strict=True))


def _unpack(built, where: str):
    if isinstance(built, tuple | list) and len(built) == 3:
        system, q0, p0 = built
    elif isinstance(built, Mapping) and {"system", "q0", "p0"} <= set(built):
        system, q0, p0 = built["system"], built["q0"], built["p0"]
    elif all(hasattr(built, k) for k in ("system", "q0", "p0")):
        system, q0, p0 = built.system, built.q0, built.p0
    else:
        raise ModelError(
            f"{where} returned {type(built).__name__}; build must return (system, q0, p0) "
            "(or a dict/object with system, q0, p0)."
        )
    if not isinstance(system, DiracSystem):
        raise ModelError(
            f"{where} returned system={_short(system)}, which is not a diracvi system: "
            "build it with dv.LagrangeDiracSystem(...) or dv.interconnect(...)."
        )
    return system, q0, p0


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


def _program(static, rule, scheme, solver, k: int, blocks: int):
    """``jit(vmap(member))`` over stacked array leaves and carries (cached per structure)."""

    def member(dynamic, h, clock, carry):
        global TRACE_COUNT
        TRACE_COUNT += 1  # runs once per trace, i.e. once per compilation
        system = eqx.combine(dynamic, static)
        chunk = chunk_runner(system, rule, scheme, solver, k, True, blocks)
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

    batched = jax.vmap(member, in_axes=(0, None, None, 0))
    return _cached(
        "chunk",
        (static, rule.name, scheme, repr(solver), k, blocks),
        lambda: stored_chunk_jit(
            batched, "diracvi.sweeps.run.member", ("chunk", static, rule, scheme, solver, k, blocks)
        ),
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
            "diracvi.sweeps.run.step_jacobians",
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
            jax.vmap(one, in_axes=(0, 0, None)), "diracvi.sweeps.run.legendre", ("legendre", static)
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
    solver = NewtonSolver()
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

        # as simulate does before stepping: the first step must be solvable ...
        singular = np.zeros(len(index), bool)
        if system0.n + system0.m <= DENSE_CHECK_LIMIT:
            jacs = _step_jacobians(static, rule, scheme, h, settings.t0, dynamic, q0s, p0s)
            singular = _singular_members(jacs)[: len(index)]
        # ... and the initial data consistent (a warning, as in simulate)
        bad = _inconsistent_members(system0, static, settings.t0, dynamic, q0s, p0s)
        inconsistent.extend(int(i) for i in index[bad[: len(index)]])

        carry = (q0s, p0s, q0s, np.zeros((size, system0.m)))
        fn = _program(static, rule, scheme, solver, k, blocks)
        res = jax.tree.map(np.asarray, fn(dynamic, np.float64(h), clock, carry))
        res = {key: value[: len(index)] for key, value in res.items()}

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
            try:
                check_step_jacobian(
                    jacs[j],
                    unknown_names=unknown_names(system, scheme, rule),
                    equation_names=equation_names(system, rule),
                    where=f"the first ({scheme}) step of member {_described(names, values[i])}"
                    f" at t = {tk:g}",
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


# ------------------------------------------------------------------ storage
def fingerprint(build, points: Points, settings: SweepSettings, batch_size: int) -> str:
    """A hash of everything that determines the sweep's numbers and its batches."""
    description = json.dumps(
        {
            "build": _build_name(build),
            "names": list(points.names),
            "dims": list(points.dims),
            "shape": list(points.shape),
            "settings": [
                float(settings.dt).hex(),
                settings.steps,
                settings.scheme,
                settings.discretization,
                settings.save_every,
                float(settings.t0).hex(),
            ],
            "batch_size": batch_size,
            "solver": repr(NewtonSolver()),
        },
        sort_keys=True,
    ).encode()
    digest = hashlib.sha256(description)
    digest.update(np.ascontiguousarray(points.values).tobytes())
    return digest.hexdigest()


def _build_name(build) -> str:
    """A name of ``build`` that is stable across processes (no addresses)."""
    if isinstance(build, functools.partial):
        keywords = sorted(build.keywords.items())
        return f"partial({_build_name(build.func)}, {build.args!r}, {keywords!r})"
    name = getattr(build, "__qualname__", None) or type(build).__qualname__
    return f"{getattr(build, '__module__', '')}.{name}"


def _times(settings: SweepSettings) -> np.ndarray:
    sign = 1.0 if settings.scheme == "plus" else -1.0
    k, blocks = settings.save_every, settings.steps // settings.save_every
    return settings.t0 + sign * settings.dt * k * np.arange(blocks + 1)


def _attrs(settings: SweepSettings, coords, key: str, batch_size: int) -> dict:
    return {
        "dt": settings.dt,
        "steps": settings.steps,
        "scheme": settings.scheme,
        "discretization": settings.discretization,
        "save_every": settings.save_every,
        "t0": settings.t0,
        "solver": repr(NewtonSolver()),
        "coords": json.dumps(list(coords)),
        "batch_size": batch_size,
        "sweep_fingerprint": key,
        "created_by": "diracvi.sweep",
    }


def _variables(coords):
    """``(name, kind, source)`` of every data variable: kind is "time", "step" or "member"."""
    out = [(c, "time", ("q", i)) for i, c in enumerate(coords)]
    out += [(f"p({c})", "time", ("p", i)) for i, c in enumerate(coords)]
    out += [
        ("energy", "step", ("energy", None)),
        ("constraint_violation", "step", ("violation", None)),
    ]
    out += [
        ("status", "member", ("status", None)),
        ("steps_taken", "member", ("steps_taken", None)),
    ]
    out += [("message", "member", ("message", None))]
    return out


def _pick(result, source):
    name, column = source
    a = result[name]
    return a if column is None else a[..., column]


class _Store:
    """The ``out=`` NetCDF file: created whole, filled batch by batch."""

    def __init__(self, path: Path, points: Points, settings, key, batch_size, n_batches):
        self.path, self.points, self.settings = path, points, settings
        self.key, self.batch_size, self.n_batches = key, batch_size, n_batches

    def done(self) -> np.ndarray | None:
        """Which batches a previous run finished (``None``: no file yet)."""
        if not self.path.exists():
            return None
        import h5netcdf

        try:
            with h5netcdf.File(self.path, "r") as f:
                key = f.attrs.get("sweep_fingerprint")
                done = np.asarray(f.variables["batch_done"][...]) if key == self.key else None
        except (OSError, KeyError) as exc:
            raise ModelError(
                f"out={str(self.path)!r} exists but is not a readable diracvi sweep ({exc}); "
                "delete it or choose another path."
            ) from exc
        if key != self.key:
            raise ModelError(
                f"out={str(self.path)!r} holds a different sweep (other build, parameter "
                "values, dt, steps, scheme, discretization, save_every, t0 or batch_size); "
                "delete it to start afresh, or choose another path."
            )
        return done.astype(bool)

    def create(self, coords) -> None:
        import h5netcdf
        import h5py

        pts, blocks = self.points, self.settings.steps // self.settings.save_every
        times = _times(self.settings)
        if not self.path.parent.exists():
            raise ModelError(
                f"out={str(self.path)!r}: folder {str(self.path.parent)!r} does not exist; "
                "create it first."
            )
        tmp = self.path.with_name(f".{self.path.name}.creating")
        with h5netcdf.File(tmp, "w") as f:
            dims = dict(zip(pts.dims, pts.shape, strict=True))
            dims.update(time=blocks + 1, step=blocks, batch=self.n_batches)
            f.dimensions = dims
            if pts.dims == ("sample",):
                for j, name in enumerate(pts.names):
                    f.create_variable(name, ("sample",), float, data=pts.values[:, j])
            else:
                for name, axis in pts.axes.items():
                    f.create_variable(name, (name,), float, data=axis)
            f.create_variable("time", ("time",), float, data=times)
            f.create_variable("step_time", ("step",), float, data=times[1:])
            for name, kind, _ in _variables(coords):
                var_dims = pts.dims + ((kind,) if kind != "member" else ())
                if name == "message":
                    f.create_variable(name, var_dims, dtype=h5py.string_dtype())
                elif name in ("status", "steps_taken"):
                    f.create_variable(name, var_dims, np.int64, fillvalue=-1)
                else:
                    f.create_variable(name, var_dims, float, fillvalue=np.nan, chunks=True)
            f.create_variable("batch_done", ("batch",), np.int8, data=np.zeros(self.n_batches))
            f.attrs.update(_attrs(self.settings, coords, self.key, self.batch_size))
            f.variables["status"].attrs["flag_meanings"] = (
                "0 success, 1 Newton did not "
                "converge, 2 singular step equations, 3 NaN or Inf, -1 not run yet"
            )
        tmp.replace(self.path)

    def write(self, batch: int, start: int, result) -> None:
        import h5netcdf

        with h5netcdf.File(self.path, "a") as f:
            for name, _, source in _variables(result["coords"]):
                data = _pick(result, source)
                var = f.variables[name]
                for region, rows in _regions(self.points.shape, start, len(data)):
                    var[region] = data[rows]
            f.variables["batch_done"][batch] = 1


def _regions(shape, start: int, count: int):
    """Split the flat (C-order) members ``start .. start + count`` of a grid of ``shape``
    into hyperslabs: ``(index of the slab, slice of the batch's rows)``."""
    last = shape[-1]
    i, end = start, start + count
    while i < end:
        row = i - i % last
        j = min(end, row + last)
        lead = np.unravel_index(row, shape)[:-1] if len(shape) > 1 else ()
        region = (*(int(x) for x in lead), slice(i - row, j - row))
        yield region, slice(i - start, j - start)
        i = j


def _dataset(points: Points, settings, coords, flat: dict, key, batch_size):
    import xarray as xr

    times = _times(settings)
    data = {}
    for name, kind, source in _variables(coords):
        a = _pick(flat, source)
        if name == "message":
            a = a.astype(str)
        a = a.reshape(points.shape + a.shape[1:])
        data[name] = (points.dims + ((kind,) if kind != "member" else ()), a)
    coordinates = {"time": times, "step_time": (("step",), times[1:])}
    if points.dims == ("sample",):
        for j, name in enumerate(points.names):
            coordinates[name] = (("sample",), points.values[:, j])
    else:
        coordinates.update(points.axes)
    return xr.Dataset(data, coords=coordinates, attrs=_attrs(settings, coords, key, batch_size))


# ------------------------------------------------------------------ the driver
def _progress_bar(enabled, total: int, label: str):
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        return None
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeRemainingColumn

    progress = Progress(
        "[progress.description]{task.description}",
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=False,
    )
    progress.start()
    progress.add_task(label, total=total)
    return progress


def sweep(
    build: Callable,
    params: Mapping | None = None,
    *,
    samples=None,
    dt,
    steps,
    discretization: str = "retraction",
    scheme: str = "plus",
    save_every: int = 1,
    t0: float = 0.0,
    client=None,
    batch_size: int | None = None,
    out=None,
    progress: bool | None = None,
):
    r"""Run ``build(**values)`` over a grid or a table of parameter values.

    Args:
        build: ``build(**values) -> (system, q0, p0)`` (or a dict/object with those),
            or the path of a model file defining it (its source is sent to the workers
            of a cluster, which need not see the file).
            Give parameters as array leaves (e.g. an ``equinox.Module`` Lagrangian
            holding ``jnp.asarray(R)``) so that all members share one compiled program;
            values captured by plain closures still work, one compilation per member.
        params: ``{name: 1-D values}``: every combination is run (a grid).
        samples: ``{name: values}`` of equal lengths (or a DataFrame): one member per
            row (Monte Carlo, Latin hypercube). Give ``params`` or ``samples``.
        dt, steps, discretization, scheme, save_every, t0: as for :func:`simulate`.
            Every member is stepped by Newton (``dv.NewtonSolver()``), so it equals
            ``dv.simulate(..., solver=dv.NewtonSolver())`` of that member to round-off.
        client: ``None`` runs the batches in this process; a
            ``dask.distributed.Client`` runs each batch as a task on its cluster.
        batch_size: members per batch (default 256). Batches are the unit of work, of
            retry and of resumption; results are bitwise reproducible for a given
            ``batch_size``, embedded or on any cluster.
        out: a NetCDF path: every finished batch is written there, only one batch is
            held in memory, and a rerun with the same ``out`` skips finished batches.
            The returned dataset then reads from the file lazily.
        progress: show a progress bar (default: when stderr is a terminal).

    Returns:
        An ``xarray.Dataset`` with dimensions ``(*params, time)`` for a grid or
        ``(sample, time)`` for a table: one variable per coordinate name (positions) and
        ``p(name)`` (momenta) over ``time``; ``energy`` and ``constraint_violation``
        (the largest over each saved interval) over ``step`` (coordinate ``step_time``,
        the end of the interval); per member ``status`` (0 = every step taken; the codes
        of :class:`Trajectory`), ``message`` and ``steps_taken``. Values after a
        member's failure are NaN.
    """
    ensure_float64()
    if isinstance(build, str | os.PathLike):
        from ..model.modelfile import ModelFileBuild

        build = ModelFileBuild(build)
    points = sweep_points(params, samples)
    check_build(build, points.names)
    settings = _settings(dt, steps, scheme, discretization, save_every, t0)
    members = len(points.values)
    size = (
        DEFAULT_BATCH_SIZE if batch_size is None else check_positive_int("batch_size", batch_size)
    )
    size = min(size, members)
    starts = list(range(0, members, size))
    key = fingerprint(build, points, settings, size)

    store = None
    done = np.zeros(len(starts), bool)
    if out is not None:
        store = _Store(Path(out), points, settings, key, size, len(starts))
        previous = store.done()
        if previous is not None:
            done = previous
    todo = [b for b in range(len(starts)) if not done[b]]

    flat = None if store is not None else {}
    inconsistent: list = []
    coords = None

    def collect(b, result):
        nonlocal coords, flat
        if coords is None:
            coords = result["coords"]
        elif result["coords"] != coords:
            raise ModelError(
                f"batch {b} of the sweep has coordinates {result['coords']} but an earlier "
                f"one {coords}: every member of a sweep must have the same coordinates."
            )
        inconsistent.extend(result["inconsistent"])
        if store is not None:
            if not store.path.exists():
                store.create(coords)
            store.write(b, starts[b], result)
            return
        for name in ("q", "p", "energy", "violation", "status", "steps_taken", "message"):
            if name not in flat:
                shape = (members, *result[name].shape[1:])
                flat[name] = np.empty(shape, dtype=result[name].dtype)
            flat[name][starts[b] : starts[b] + len(result[name])] = result[name]

    bar = _progress_bar(progress, len(todo), "sweep" if client is None else _cluster_label(client))
    try:
        if client is None:
            for b in todo:
                collect(
                    b,
                    run_batch(build, points.names, _rows(points, starts, b, size), settings, size),
                )
                if bar is not None:
                    bar.advance(bar.task_ids[0])
        else:
            _run_on_cluster(client, build, points, starts, size, todo, settings, key, collect, bar)
    finally:
        if bar is not None:
            bar.stop()

    if inconsistent:
        total = sum(c for c, _ in inconsistent)
        warnings.warn(
            f"{total} member(s) of the sweep start from inconsistent initial data; the "
            f"first, {inconsistent[0][1]}",
            InconsistentInitialDataWarning,
            stacklevel=2,
        )
    if store is not None:
        import xarray as xr

        if coords is None and not store.path.exists():  # nothing ran (cannot happen)
            raise ModelError(f"out={str(out)!r}: the sweep produced no batch.")
        ds = xr.open_dataset(store.path, engine="h5netcdf")
        return ds.drop_vars("batch_done").set_coords("step_time")
    return _dataset(points, settings, coords, flat, key, size)


def _settings(dt, steps, scheme, discretization, save_every, t0) -> SweepSettings:
    from ..discretization.equations import SCHEMES
    from ..discretization.rules import RULES
    from ..driver.simulate import check_save_every
    from ..model.validate import check_choice, check_positive_float

    scheme = check_choice("scheme", scheme, SCHEMES)
    discretization = check_choice("discretization", discretization, tuple(RULES))
    h = check_positive_float("dt", dt)
    steps = check_positive_int("steps", steps)
    k = check_save_every(steps, save_every)
    return SweepSettings(h, steps, scheme, discretization, k, check_float("t0", t0))


def _rows(points: Points, starts, b: int, size: int) -> np.ndarray:
    return points.values[starts[b] : starts[b] + size]


def _cluster_label(client) -> str:
    link = getattr(client, "dashboard_link", None)
    return f"sweep on {client.scheduler.address}" + (f" (dashboard {link})" if link else "")


def _run_pickled_batch(payload: bytes, names, values, settings, cap) -> dict:
    """:func:`run_batch` of a ``build`` serialized by cloudpickle (a Dask task)."""
    import cloudpickle

    return run_batch(cloudpickle.loads(payload), names, values, settings, cap)


def _run_on_cluster(client, build, points, starts, size, todo, settings, key, collect, bar):
    """Each batch a Dask task; results are collected (and written) as they finish."""
    try:
        from distributed import as_completed
    except ImportError as exc:  # pragma: no cover - a client implies distributed
        raise ModelError(
            "client= needs dask.distributed: pip install 'diracvi[distributed]'."
        ) from exc
    import cloudpickle

    # cloudpickle, not Dask's first choice (plain pickle), so that a build registered with
    # cloudpickle.register_pickle_by_value (a model file, a script) travels by value
    payload = cloudpickle.dumps(build)
    futures = [
        client.submit(
            _run_pickled_batch,
            payload,
            points.names,
            _rows(points, starts, b, size),
            settings,
            size,
            key=f"diracvi-sweep-{key[:16]}-{b}",
            pure=False,
            retries=2,
        )
        for b in todo
    ]
    batch_of = {f.key: b for f, b in zip(futures, todo, strict=True)}
    try:
        for future in as_completed(futures):
            result = future.result()
            collect(batch_of[future.key], result)
            future.release()
            if bar is not None:
                bar.advance(bar.task_ids[0])
    finally:
        client.cancel(futures)


__all__ = ["fingerprint", "run_batch", "sweep", "sweep_points"]
