"""``diracvi plot``: plot a saved trajectory."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import (
    EXIT_USAGE,
    _fail,
    _library_errors,
    _out,
)


def plot(
    file: Annotated[
        Path, typer.Argument(help="A trajectory saved by `diracvi run --out` (NetCDF).")
    ],
    out: Annotated[
        Path | None, typer.Option(help="Where to write the PNG (default: FILE with .png).")
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite the PNG if it already exists.")
    ] = False,
) -> None:
    """Plot a saved trajectory: positions, energy and constraint residuals.

    An existing PNG is never overwritten silently: the command refuses unless --force.
    """
    if not file.is_file():
        _fail(f"trajectory file {str(file)!r} does not exist.", EXIT_USAGE)
    png = out if out is not None else file.with_suffix(".png")
    if not png.parent.exists():
        _fail(f"--out {str(png)!r}: folder {str(png.parent)!r} does not exist.", EXIT_USAGE)
    if png.exists() and not force:
        _fail(
            f"{str(png)!r} already exists; pass --force to overwrite it, or --out NEW.png.",
            EXIT_USAGE,
        )
    from .. import load
    from ..plotting import plot_trajectory

    with _library_errors():
        traj = load(file)
    plot_trajectory(traj, png)
    _out().print(f"wrote {png}", markup=False, soft_wrap=True)
