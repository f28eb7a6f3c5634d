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
import json
import os
import sys
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..model.consistency import InconsistentInitialDataWarning
from ..model.validate import check_float, check_positive_int
from ..runtime.config import ensure_float64
from .batch import run_batch
from .points import Points, SweepSettings, check_build, sweep_points

#: default members per batch (independent of the cluster, so that the batches, and with
#: them the compiled programs and their round-off, are the same embedded and on Dask)
DEFAULT_BATCH_SIZE = 256


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
            "solver": "auto" if settings.solver is None else repr(settings.solver),
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
        "solver": "auto" if settings.solver is None else repr(settings.solver),
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
    out += [("message", "member", ("message", None)), ("solver", "member", ("solver", None))]
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
                if name in ("message", "solver"):
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
        if name in ("message", "solver"):
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
    solver=None,
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
        dt, steps, discretization, scheme, save_every, t0, solver: as for
            :func:`simulate`, whose plan chooses each member's stepping method: with
            ``solver=None`` the affine step map when the step equations are linear (one
            map per member), the default solver otherwise. A member equals
            ``dv.simulate(..., solver=solver)`` of it to round-off; the ``solver``
            variable of the result says which method ran.
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
        of :class:`Trajectory`), ``message``, ``steps_taken`` and ``solver``. Values after a
        member's failure are NaN.
    """
    ensure_float64()
    if isinstance(build, str | os.PathLike):
        from ..model.modelfile import ModelFileBuild

        build = ModelFileBuild(build)
    points = sweep_points(params, samples)
    check_build(build, points.names)
    settings = _settings(dt, steps, scheme, discretization, save_every, t0, solver)
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
        for name in ("q", "p", "energy", "violation", "status", "steps_taken", "message", "solver"):
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


def _settings(dt, steps, scheme, discretization, save_every, t0, solver=None) -> SweepSettings:
    from ..discretization.equations import SCHEMES
    from ..discretization.rules import RULES
    from ..driver.simulate import check_save_every, check_solver
    from ..model.validate import check_choice, check_positive_float

    scheme = check_choice("scheme", scheme, SCHEMES)
    discretization = check_choice("discretization", discretization, tuple(RULES))
    h = check_positive_float("dt", dt)
    steps = check_positive_int("steps", steps)
    k = check_save_every(steps, save_every)
    check_solver(solver)
    return SweepSettings(h, steps, scheme, discretization, k, check_float("t0", t0), solver)


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
