r"""The points of a sweep: parameter grids and tables, the settings every batch shares,
and the checks of ``build`` (its signature, what it returns)."""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import NamedTuple

import numpy as np

from ..errors import ModelError
from ..model.system import DiracSystem

#: names the result uses for its own dimensions and variables
RESERVED = ("time", "step", "step_time", "sample", "status", "message", "steps_taken", "energy")
RESERVED += ("constraint_violation", "batch", "batch_done", "solver")


class SweepSettings(NamedTuple):
    """What every batch shares (checked once, sent to the workers with each batch)."""

    dt: float
    steps: int
    scheme: str
    discretization: str
    save_every: int
    t0: float
    solver: object = None  # as simulate's solver=: None chooses as simulate does


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
        # the example must itself be accepted: a grid's columns may differ in length, a
        # table's may not (one value per parameter for every sample)
        example = (
            "{'R': np.linspace(0.1, 2, 20), 'C': [1.0, 3.0]}"
            if which == "params"
            else "{'R': [0.5, 1.0, 2.0], 'C': [1.0, 3.0, 2.0]}"
        )
        raise ModelError(
            f"{which}={_short(table)} is not a mapping: pass {{name: values}}, e.g. "
            f"{which}={example} (a pandas DataFrame also works for samples=)."
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
    elif isinstance(built, tuple | list) and len(built) == 4 and isinstance(built[3], Mapping):
        system, q0, p0 = built[:3]  # a model file's (system, q0, p0, {dt, steps}): the
        # sweep's own dt and steps are its arguments
    elif isinstance(built, Mapping) and {"system", "q0", "p0"} <= set(built):
        system, q0, p0 = built["system"], built["q0"], built["p0"]
    elif all(hasattr(built, k) for k in ("system", "q0", "p0")):
        system, q0, p0 = built.system, built.q0, built.p0
    else:
        raise ModelError(
            f"{where} returned {type(built).__name__}; build must return (system, q0, p0), "
            "(system, q0, p0, {'dt': ..., 'steps': ...}) or a dict/object with system, q0, p0."
        )
    if not isinstance(system, DiracSystem):
        raise ModelError(
            f"{where} returned system={_short(system)}, which is not a diracvi system: "
            "build it with dv.LagrangeDiracSystem(...) or dv.interconnect(...)."
        )
    return system, q0, p0
