"""What every command shares: exit codes, consoles, error reporting, option checks and
the resolution of a model argument (a built-in problem, a model file or a netlist)."""

from __future__ import annotations

import gc
import math
import warnings
from contextlib import contextmanager
from pathlib import Path

import typer
from rich.console import Console

EXIT_FAILURE = 1
EXIT_USAGE = 2
#: set by ``cli/main.py: _Command`` when the app runs as the process (the console script,
#: ``python -m``), not under ``typer.testing.CliRunner``: see :func:`_settle`
PROCESS = [False]


def _settle() -> None:
    """Before a run, in a ``diracvi`` process: move every object that exists now — the
    imported modules (JAX's, Equinox's, SciPy's, diracvi's), the model — to the
    collector's permanent generation (``gc.freeze``). They live until the process ends,
    and each full collection of the run (tracing makes many objects) would walk them
    again: measured on a cold ng_rtlinv, the full collections' CPU 0.59 → 0.21 s. Garbage
    in cycles made before this point is left to the process's end. Under ``CliRunner``
    (a test process running many commands) nothing is frozen."""
    if PROCESS[0]:
        gc.freeze()


def _out() -> Console:
    return Console(highlight=False)


def _err() -> Console:
    return Console(stderr=True, highlight=False)


def _fail(message: str, code: int = EXIT_FAILURE):
    """Print ``Error: message`` to stderr (never wrapped mid-path) and exit with ``code``."""
    _err().print(f"Error: {message}", markup=False, soft_wrap=True)
    raise typer.Exit(code)


def _note(message: str) -> None:
    _err().print(message, markup=False, soft_wrap=True)


@contextmanager
def _plain_warnings():
    """Print each warning raised inside as ``warning: text`` on stderr."""
    # Warnings (inconsistent initial data, float64 switched back on) are shown as one plain
    # line each, not in Python's "file:line: Category: text" format.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")
        try:
            yield
        finally:
            for warning in caught:
                _note(f"warning: {warning.message}")


@contextmanager
def _library_errors(partial_out: Path | None = None):
    """Turn diracvi's own exceptions into a message and exit code 1, without a traceback.

    A :class:`StepFailure` still carries every step completed before the failure; with
    ``--out`` that partial trajectory is saved, and the message says so.
    """
    from .. import DiracviError, StepFailure

    try:
        with _plain_warnings():
            yield
    except StepFailure as exc:
        message = str(exc)
        if partial_out is not None:
            exc.trajectory.save(partial_out)
            message += (
                f"\nThe {exc.trajectory.steps} steps completed before the failure were "
                f"saved to {str(partial_out)!r}."
            )
        _fail(message)
    except DiracviError as exc:
        _fail(str(exc))


# ---------------------------------------------------------------- option parsing
def _positive_float(ctx: typer.Context, param, value: str | None) -> float | None:
    if value is None:
        return None
    try:
        number = float(value)
    except ValueError:
        from ..spice._values import number as spice_number

        number = spice_number(value)  # SPICE's scale suffixes: 5u, 10n, 1meg
        if number is None:
            raise typer.BadParameter(
                f"{value!r} is not a number; give a step > 0, e.g. 0.01 or 5u."
            ) from None
    if not math.isfinite(number) or number <= 0.0:
        raise typer.BadParameter(f"{value} is not a finite number > 0; e.g. 0.01.")
    return number


def _positive_int(ctx: typer.Context, param, value: str | None) -> int | None:
    if value is None:
        return None
    try:
        number = int(value)
    except ValueError:
        raise typer.BadParameter(f"{value!r} is not a whole number; e.g. 1000.") from None
    if number < 1:
        raise typer.BadParameter(f"{value} is not ≥ 1; give the number of steps, e.g. 1000.")
    return number


def _choice(options):
    """A typer callback accepting only ``options`` (a tuple, or a function giving one when
    the command runs: the rule registry may grow after this module is imported)."""

    def check(ctx: typer.Context, param, value: str | None) -> str | None:
        names = options() if callable(options) else options
        if value is not None and value not in names:
            raise typer.BadParameter(f"{value!r} is not one of {', '.join(names)}.")
        return value

    return check


def _rule_names() -> tuple[str, ...]:
    """Every registered rule's name (``--discretization``'s choices), read when a command
    runs: importing the rules (JAX, Equinox) is not part of ``diracvi --help``."""
    from ..discretization.rules import rule_names

    return rule_names()


#: ``--solver`` choices of ``run`` and ``sweep`` (the solvers are imported when a run
#: needs one)
SOLVERS = ("newton", "newton-full", "affine", "partitioned")


def _solver_option(name: str | None):
    """The solver ``--solver NAME`` asks for (None: automatic, as ``solver=None``)."""
    if name is None:
        return None
    from .. import AffineSolver, NewtonSolver, PartitionedSolver

    return {
        "newton": NewtonSolver,
        "newton-full": lambda: NewtonSolver(reuse_jacobian=False),
        "affine": AffineSolver,
        "partitioned": PartitionedSolver,
    }[name]()


#: the endings of a SPICE netlist's file name: ngspice reads any, so these are the ones
#: its users write (``.cir.out`` is the deck eSim writes from a KiCad schematic and
#: hands to ngspice, ``.spi`` ngspice's examples' and LTspice's export's)
NETLIST_SUFFIXES = (".cir", ".sp", ".spice", ".net", ".ckt", ".spi", ".cir.out")


def is_netlist(target) -> bool:
    """Whether ``target``'s file name ends as a SPICE netlist's (:data:`NETLIST_SUFFIXES`)."""
    return str(target).lower().endswith(NETLIST_SUFFIXES)


def _resolve_model(target: str):
    """A built-in problem name or a model file path → a ModelSpec-like object."""
    path = Path(target)
    if is_netlist(target):
        if not path.is_file():
            _fail(f"netlist {target!r} does not exist.", EXIT_USAGE)
        from .. import spice

        with _library_errors():
            return spice.read(path)
    # (after the netlists: a netlist run imports neither the problems nor model files)
    from .. import problems
    from ..model.modelfile import load_model_file

    looks_like_path = target.endswith(".py") or "/" in target or "\\" in target
    if looks_like_path or (path.is_file() and target not in problems.REGISTRY):
        if not path.is_file():
            _fail(f"model file {target!r} does not exist.", EXIT_USAGE)
        if path.suffix.lower() != ".py":
            _fail(
                f"{target!r} is neither a model file (.py) nor a netlist by its name (a SPICE "
                f"netlist ends in {', '.join(NETLIST_SUFFIXES)}, a robot in .urdf); a netlist "
                "named otherwise: copy it to a name ending in .cir",
                EXIT_USAGE,
            )
        with _library_errors():
            return load_model_file(path)
    if target not in problems.REGISTRY:
        _fail(
            f"unknown problem {target!r}. Built-in problems: "
            f"{', '.join(problems.REGISTRY)} (see `diracvi list`); or give the path to "
            "a model file ending in .py.",
            EXIT_USAGE,
        )
    return problems.get(target)
