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

import gc
from typing import Annotated

import typer

from . import common
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


class _Command(typer.Typer):
    """The app as a process runs it (the console script, ``python -m``): after the
    command, every object left is moved to the collector's permanent generation
    (``gc.freeze``), so the interpreter's exit does not traverse them.

    A process that has imported JAX, Equinox and SciPy holds a few million tracked
    objects, and the collections of the interpreter's shutdown walk them all: measured,
    0.3–0.4 CPU s of a warm 2-s ``diracvi run deck.cir`` (and of a bare ``import jax``
    process), ≈ 0 with the freeze. Objects are still freed as their references go;
    only reference cycles still alive at the exit are not collected, and their memory
    goes back with the process. Files are closed by then (every writer uses ``with``).
    ``typer.testing.CliRunner`` invokes the command, not this method, so a test process
    that runs many commands keeps collecting as usual."""

    def __call__(self, *args, **kwargs):
        common.PROCESS[0] = True  # the run may freeze what its imports made (_settle)
        try:
            return super().__call__(*args, **kwargs)
        finally:
            gc.freeze()


app = _Command(
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
