"""``diracvi``: the command line.

    diracvi list                         built-in problems
    diracvi run PROBLEM|model.py [...]   simulate, summarize, save NetCDF, plot
    diracvi sweep model.py --param R=0.1:2:20 [--scheduler tcp://...] [--out FILE.nc]
    diracvi plot FILE.nc [--out PNG] [--force]   plot a saved trajectory (no silent overwrite)
    diracvi reproduce --out DIR          the paper's §5: figures, summary.json, report
    diracvi bench [--quick] [--only NAME]...   benchmarks: one table of measured ratios

Exit codes: 0 success; 1 the model or the simulation failed (its message is printed,
without a traceback); 2 the command line was wrong (bad option value, unknown problem,
missing file). The work itself lives in the library (``diracvi.reproduce``,
``diracvi.plotting``); this module parses, reports and maps errors to exit codes.
"""

from __future__ import annotations

from typing import Annotated

import typer

from .bench import bench
from .cache import cache_app
from .common import (
    EXIT_FAILURE,
    EXIT_USAGE,
    _out,
)
from .plot import plot
from .reproduce import reproduce
from .run import list_problems, run
from .sweep import sweep_command

app = typer.Typer(
    name="diracvi",
    help="Interconnected Lagrange–Dirac systems and discrete Dirac variational integrators.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version(value: bool) -> None:
    if value:
        from .. import __version__

        _out().print(f"diracvi {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
) -> None:
    """Interconnected Lagrange–Dirac systems and discrete Dirac variational integrators."""


# each command lives in its own module (they import only .common); registered here in
# the order ``diracvi --help`` lists them
app.command("list")(list_problems)
app.command()(run)
app.command("sweep")(sweep_command)
app.command()(plot)
app.command()(reproduce)
app.command()(bench)
app.add_typer(cache_app, name="cache")

__all__ = ["EXIT_FAILURE", "EXIT_USAGE", "app"]

if __name__ == "__main__":
    app()
