"""``diracvi sweep``: a model file over a grid of parameters, embedded or on a Dask cluster."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from ..discretization.names import BUILT_IN as RULE_NAMES
from .common import (
    EXIT_USAGE,
    SOLVERS,
    _choice,
    _fail,
    _library_errors,
    _out,
    _positive_float,
    _positive_int,
    _rule_names,
    _solver_option,
)


def _parameter(text: str):
    """``NAME=start:stop:count`` (a linspace) or ``NAME=v1,v2,...`` → ``(name, values)``."""
    import numpy as np

    name, sep, spec = text.partition("=")
    name = name.strip()
    if not sep or not name.isidentifier() or not spec.strip():
        raise typer.BadParameter(
            f"{text!r}: write NAME=start:stop:count (evenly spaced) or NAME=v1,v2,... "
            "(a list), e.g. --param R=0.1:2:20 --param C=1,3,5."
        )
    try:
        if ":" in spec:
            start, stop, count = spec.split(":")
            if float(count) != int(float(count)) or int(float(count)) < 1:
                raise ValueError
            return name, np.linspace(float(start), float(stop), int(float(count)))
        return name, np.array([float(v) for v in spec.split(",")])
    except ValueError:
        raise typer.BadParameter(
            f"{text!r}: {spec!r} is neither start:stop:count (count a whole number ≥ 1) "
            "nor a comma-separated list of numbers; e.g. R=0.1:2:20 or C=1,3,5."
        ) from None


def _defaults(build) -> tuple[float | None, int | None]:
    """``dt`` and ``steps`` a model file's ``build()`` returns with its own defaults."""
    try:
        built = build()
    except Exception:  # a build without defaults: --dt and --steps are required
        return None, None
    if isinstance(built, tuple | list) and len(built) == 4 and isinstance(built[3], dict):
        built = built[3]  # (system, q0, p0, {"dt": ..., "steps": ...}), as `diracvi run` reads
    if isinstance(built, dict):
        return built.get("dt"), built.get("steps")
    return getattr(built, "dt", None), getattr(built, "steps", None)


def sweep_command(
    model: Annotated[
        Path,
        typer.Argument(
            help="A model file path/to/model.py whose build(**values) returns "
            "(system, q0, p0) (or a dict with system, q0, p0, dt, steps).",
            show_default=False,
        ),
    ],
    param: Annotated[
        list[str],
        typer.Option(
            "--param",
            metavar="NAME=SPEC",
            help="A swept parameter (repeatable): NAME=start:stop:count (evenly spaced) "
            "or NAME=v1,v2,... ; the sweep is the grid over all of them.",
        ),
    ],
    dt: Annotated[
        str | None,
        typer.Option(callback=_positive_float, metavar="FLOAT", help="Step size h."),
    ] = None,
    steps: Annotated[
        str | None,
        typer.Option(callback=_positive_int, metavar="INT", help="Number of steps."),
    ] = None,
    scheme: Annotated[
        str,
        typer.Option(callback=_choice(("plus", "minus")), metavar="plus|minus"),
    ] = "plus",
    discretization: Annotated[
        str,
        typer.Option(
            callback=_choice(_rule_names),
            metavar="|".join(RULE_NAMES),
        ),
    ] = "retraction",
    save_every: Annotated[
        str, typer.Option(callback=_positive_int, metavar="INT", help="Keep every k-th state.")
    ] = "1",
    batch_size: Annotated[
        str | None,
        typer.Option(callback=_positive_int, metavar="INT", help="Members per batch (256)."),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            metavar="ADDRESS",
            help="A Dask scheduler (tcp://host:8786) to run the batches on; default: here.",
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option(help="NetCDF file written batch by batch; rerun to resume."),
    ] = None,
    solver: Annotated[
        str | None,
        typer.Option(
            callback=_choice(SOLVERS),
            metavar="|".join(SOLVERS),
            help="Step solver of every member (default: automatic — the affine map for "
            "linear models, one per member, else Newton reusing its Jacobian), as for "
            "`diracvi run`. The dataset's solver variable says which ran.",
        ),
    ] = None,
) -> None:
    """Run a model file over a grid of parameter values (embedded, or on a Dask cluster)."""
    if not model.is_file():
        _fail(f"model file {str(model)!r} does not exist.", EXIT_USAGE)
    if out is not None and not out.parent.exists():
        _fail(f"--out {str(out)!r}: folder {str(out.parent)!r} does not exist.", EXIT_USAGE)
    if not param:
        _fail("give at least one --param NAME=start:stop:count or NAME=v1,v2,...", EXIT_USAGE)
    grid = dict(_parameter(p) for p in param)
    from ..model.modelfile import load_build

    with _library_errors():
        build = load_build(model)
    h, n_steps = dt, steps
    if h is None or n_steps is None:
        default_dt, default_steps = _defaults(build)
        h = h if h is not None else default_dt
        n_steps = n_steps if n_steps is not None else default_steps
    if h is None or n_steps is None:
        missing = " and ".join(o for o, v in (("--dt", h), ("--steps", n_steps)) if v is None)
        _fail(f"{str(model)!r} sets no default for {missing}: pass {missing}.", EXIT_USAGE)

    client = None
    if scheduler is not None:
        try:
            from distributed import Client
        except ImportError:
            _fail("--scheduler needs Dask: pip install 'diracvi[distributed]'.", EXIT_USAGE)
        from ..model.modelfile import ModelFileBuild

        # the workers need not see the file: its source travels with the tasks
        with _library_errors():
            build = ModelFileBuild(model)
        client = Client(scheduler)
    from .. import sweep as run_sweep

    try:
        with _library_errors():
            ds = run_sweep(
                build,
                grid,
                dt=h,
                steps=n_steps,
                scheme=scheme,
                discretization=discretization,
                save_every=save_every,
                batch_size=batch_size,
                client=client,
                out=out,
                solver=_solver_option(solver),
            )
    finally:
        if client is not None:
            client.close()
    import numpy as np

    status = np.asarray(ds["status"].values)
    table = Table(show_header=False, box=None, pad_edge=False)
    table.add_column(style="bold")
    table.add_column()
    shape = " × ".join(f"{name} ({len(v)})" for name, v in grid.items())
    table.add_row("model", model.name)
    table.add_row("members", f"{status.size:,} = {shape}")
    table.add_row("steps", f"{n_steps}, dt = {h:g}, {scheme}, {discretization}")
    solvers = sorted(set(np.asarray(ds["solver"].values).ravel().astype(str)) - {""})
    table.add_row("solver", ", ".join(solvers))
    table.add_row("failed", f"{int(np.sum(status != 0))}")
    _out().print(table)
    if out is not None:
        ds.close()
        _out().print(f"wrote {out}", markup=False, soft_wrap=True)
