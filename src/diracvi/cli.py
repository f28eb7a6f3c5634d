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

import math
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.table import Table

EXIT_FAILURE = 1
EXIT_USAGE = 2

app = typer.Typer(
    name="diracvi",
    help="Interconnected Lagrange–Dirac systems and discrete Dirac variational integrators.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


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
    from . import DiracviError, StepFailure

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
        raise typer.BadParameter(
            f"{value!r} is not a number; give a step > 0, e.g. 0.01."
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


def _choice(options: tuple[str, ...]):
    def check(ctx: typer.Context, param, value: str | None) -> str | None:
        if value is not None and value not in options:
            raise typer.BadParameter(f"{value!r} is not one of {', '.join(options)}.")
        return value

    return check


def _version(value: bool) -> None:
    if value:
        from . import __version__

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


# ---------------------------------------------------------------------- list
@app.command("list")
def list_problems() -> None:
    """List the built-in problems (names for `diracvi run`)."""
    from . import problems

    table = Table(title="diracvi built-in problems", title_justify="left")
    table.add_column("name", style="bold", no_wrap=True)
    table.add_column("description")
    for name, description in problems.available().items():
        table.add_row(name, description)
    _out().print(table)


# ----------------------------------------------------------------------- run
#: files read as SPICE netlists by `diracvi run`
NETLIST_SUFFIXES = (".cir", ".sp", ".spice", ".net", ".ckt")


def _resolve_model(target: str):
    """A built-in problem name or a model file path → a ModelSpec-like object."""
    from . import problems
    from ._modelfile import load_model_file

    path = Path(target)
    if path.suffix.lower() in NETLIST_SUFFIXES:
        if not path.is_file():
            _fail(f"netlist {target!r} does not exist.", EXIT_USAGE)
        from . import spice

        with _library_errors():
            return spice.read(path)
    looks_like_path = target.endswith(".py") or "/" in target or "\\" in target
    if looks_like_path or (path.is_file() and target not in problems.REGISTRY):
        if not path.is_file():
            _fail(f"model file {target!r} does not exist.", EXIT_USAGE)
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


def _positive_step(ctx: typer.Context, param, value: str | None) -> float | None:
    """A step > 0 in SPICE's number syntax (``5u``, ``1e-6``, ``0.01``)."""
    if value is None:
        return None
    from .spice._values import number

    step = number(value.strip())
    if step is None or not math.isfinite(step) or step <= 0.0:
        raise typer.BadParameter(
            f"{value!r} is not a step > 0; give a number, SPICE suffixes allowed (0.01, 5u, 2.5m)."
        )
    return step


@app.command()
def run(
    problem: Annotated[
        str,
        typer.Argument(
            help="A built-in problem (see `diracvi list`), a model file path/to/model.py "
            "defining build() -> (system, q0, p0) or a dict with system, q0, p0, and "
            "optionally dt, steps, or a SPICE netlist (.cir, .sp, .spice, .net, .ckt; "
            "its .tran gives dt and steps, the NetCDF holds v(<node>) and i(<element>)).",
            show_default=False,
        ),
    ],
    dt: Annotated[
        str | None,
        typer.Option(
            callback=_positive_step,
            metavar="FLOAT",
            help="Step size h, SPICE suffixes allowed (5u) (default: the problem's).",
        ),
    ] = None,
    steps: Annotated[
        str | None,
        typer.Option(
            callback=_positive_int, metavar="INT", help="Number of steps (default: the problem's)."
        ),
    ] = None,
    scheme: Annotated[
        str,
        typer.Option(
            callback=_choice(("plus", "minus")),
            metavar="plus|minus",
            help="(+) forward or (−) backward discrete Dirac equations.",
        ),
    ] = "plus",
    discretization: Annotated[
        str | None,
        typer.Option(
            callback=_choice(("retraction", "midpoint", "lobatto")),
            metavar="retraction|midpoint|lobatto",
            help="Quadrature rule (default: the problem's first solvable one, usually retraction).",
        ),
    ] = None,
    out: Annotated[
        Path | None, typer.Option(help="Save the trajectory as NetCDF (e.g. run.nc).")
    ] = None,
    plot: Annotated[
        bool, typer.Option("--plot", help="Also write a PNG plot next to --out (or ./NAME.png).")
    ] = False,
    raw: Annotated[
        Path | None,
        typer.Option(help="Also write an ngspice raw file of a netlist's saved vectors."),
    ] = None,
) -> None:
    """Simulate a built-in problem or a model file and print a short summary."""
    for flag, target in (("--out", out), ("--raw", raw)):
        if target is not None and not target.parent.exists():
            _fail(
                f"{flag} {str(target)!r}: folder {str(target.parent)!r} does not exist.", EXIT_USAGE
            )
    model = _resolve_model(problem)
    if raw is not None and not hasattr(model, "assembly"):
        _fail(f"--raw writes a SPICE netlist's vectors; {problem!r} is not a netlist.", EXIT_USAGE)
    h = dt if dt is not None else getattr(model, "dt", None)
    n_steps = steps if steps is not None else getattr(model, "steps", None)
    if steps is None and dt is not None and getattr(model, "stop", None) is not None:
        n_steps = max(1, math.ceil(model.stop / h - 1e-9))  # a netlist still ends at TSTOP
    if h is None or n_steps is None:
        missing = " and ".join(o for o, v in (("--dt", h), ("--steps", n_steps)) if v is None)
        _fail(
            f"model file {problem!r} sets no default for {missing}: pass {missing} or "
            "return dt/steps from build().",
            EXIT_USAGE,
        )
    rules = tuple(getattr(model, "discretizations", ("retraction", "midpoint")))
    rule = discretization or rules[0]
    if rule not in rules:
        _note(f"note: {model.name!r} lists only {rules} as solvable; trying {rule!r} anyway.")

    from . import simulate

    with _library_errors(partial_out=out):
        traj = simulate(
            model.system,
            model.q0,
            model.p0,
            dt=h,
            steps=n_steps,
            scheme=scheme,
            discretization=rule,
            t0=getattr(model, "t0", 0.0),
        )
    _print_summary(model.name, traj)
    netlist = hasattr(model, "assembly")
    for note in getattr(model, "notes", ()):
        _note(f"note: {note}")
    if out is not None:
        with _library_errors():
            if netlist:
                from .spice import to_dataset

                traj.save(out, dataset=to_dataset(model, traj))
            else:
                traj.save(out)
        _out().print(f"wrote {out}", markup=False, soft_wrap=True)
    if raw is not None:
        from .spice import Result, waveforms, write_raw

        with _library_errors():
            write_raw(Result(model, traj, waveforms(model, traj)), raw)
        _out().print(f"wrote {raw}", markup=False, soft_wrap=True)
    if plot:
        png = out.with_suffix(".png") if out is not None else Path(f"{model.name}.png")
        if netlist:
            from .plotting import plot_waveforms
            from .spice import waveforms

            with _library_errors():  # (a run too short for the waveforms)
                shown = waveforms(model, traj)
            plot_waveforms(traj.t, shown, png, title=model.title)
        else:
            from .plotting import plot_trajectory

            plot_trajectory(traj, png, name=model.name)
        _out().print(f"wrote {png}", markup=False, soft_wrap=True)


def _print_summary(name: str, traj) -> None:
    import numpy as np

    residual = float(np.max(np.abs(traj.constraint_residual), initial=0.0))
    table = Table(show_header=False, box=None, pad_edge=False)
    table.add_column(style="bold")
    table.add_column()
    rows = [
        ("problem", name),
        ("scheme", f"{traj.scheme}, {traj.discretization}"),
        ("steps", f"{traj.steps} of {traj.steps_requested}, dt = {traj.dt:g}"),
        ("time", f"{traj.t[0]:g} → {traj.t[-1]:g}"),
        ("energy", f"initial {traj.energy[0]:.10g}, final {traj.energy[-1]:.10g}"),
        ("max |constraint residual|", f"{residual:.3e}"),
        (
            "Newton iterations",
            f"{traj.newton_iterations.sum()} total, "
            f"{traj.newton_iterations.mean():.2f} per step (max {traj.newton_iterations.max()})",
        ),
        ("status", traj.message.splitlines()[0]),
    ]
    for key, value in rows:
        table.add_row(key, value)
    _out().print(table)


# --------------------------------------------------------------------- sweep
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
    if isinstance(built, dict):
        return built.get("dt"), built.get("steps")
    return getattr(built, "dt", None), getattr(built, "steps", None)


@app.command("sweep")
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
            callback=_choice(("retraction", "midpoint", "lobatto")),
            metavar="retraction|midpoint|lobatto",
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
) -> None:
    """Run a model file over a grid of parameter values (embedded, or on a Dask cluster)."""
    if not model.is_file():
        _fail(f"model file {str(model)!r} does not exist.", EXIT_USAGE)
    if out is not None and not out.parent.exists():
        _fail(f"--out {str(out)!r}: folder {str(out.parent)!r} does not exist.", EXIT_USAGE)
    if not param:
        _fail("give at least one --param NAME=start:stop:count or NAME=v1,v2,...", EXIT_USAGE)
    grid = dict(_parameter(p) for p in param)
    from ._modelfile import load_build

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
        from ._modelfile import ModelFileBuild

        # the workers need not see the file: its source travels with the tasks
        with _library_errors():
            build = ModelFileBuild(model)
        client = Client(scheduler)
    from . import sweep as run_sweep

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
    table.add_row("failed", f"{int(np.sum(status != 0))}")
    _out().print(table)
    if out is not None:
        ds.close()
        _out().print(f"wrote {out}", markup=False, soft_wrap=True)


# ---------------------------------------------------------------------- plot
@app.command()
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
    from . import load
    from .plotting import plot_trajectory

    with _library_errors():
        traj = load(file)
    plot_trajectory(traj, png)
    _out().print(f"wrote {png}", markup=False, soft_wrap=True)


# ----------------------------------------------------------------- reproduce
@app.command()
def reproduce(
    out: Annotated[
        Path, typer.Option(help="Output folder for the figures, summary.json and report.")
    ] = Path("reproduce-out"),
    quick: Annotated[
        bool,
        typer.Option("--quick", help="Smoke run: 20 timing repeats and a 10,000-step long run."),
    ] = False,
    repeats: Annotated[
        str | None,
        typer.Option(
            callback=_positive_int,
            metavar="INT",
            help="Timing repeats (default 1000, or 20 with --quick).",
        ),
    ] = None,
) -> None:
    """Reproduce the paper's §5 (spring chain, RLC circuit): figures, summary and report."""
    if out.exists() and not out.is_dir():
        _fail(f"--out {str(out)!r} exists and is not a folder.", EXIT_USAGE)
    from .reproduce import reproduce as run_reproduce
    from .reproduce.progress import RichProgress
    from .reproduce.report import fmt

    with _library_errors(), RichProgress(console=_err()) as progress:
        outcome = run_reproduce(out, quick=quick, repeats=repeats, progress=progress)

    table = Table(title=f"Parks & Leok §5 reproduced → {out}", title_justify="left")
    for col in (
        "example",
        "max |Δq| vs monolithic",
        "vs hand-built",
        "port deviation",
        "time ratio (paper)",
    ):
        table.add_column(col)
    for key, s in outcome.summary["examples"].items():
        d = s["max_position_difference"]
        t = s["timing"]
        table.add_row(
            key,
            fmt(d["interconnected_vs_monolithic"]),
            fmt(d["interconnected_vs_reduced"]),
            fmt(s["constraint_deviation"]["position_max"]),
            f"{fmt(t['ratio_interconnected_to_reduced'])} ({fmt(t['paper']['ratio'])})",
        )
    console = _out()
    console.print(table)
    console.print(
        f"wrote {len(outcome.figures)} figures, {outcome.summary_path.name}, "
        f"{outcome.report_md.name} and {outcome.report_html.name} in {out}",
        markup=False,
        soft_wrap=True,
    )


# --------------------------------------------------------------------- bench
@app.command()
def bench(
    quick: Annotated[
        bool,
        typer.Option(
            "--quick",
            help="Smoke run in well under a minute: few repeats, chains up to N = 10^3, "
            "500 pendulum steps, 100 ensemble members, one compile-latency problem.",
        ),
    ] = False,
    only: Annotated[
        list[str] | None,
        typer.Option(
            "--only",
            metavar="NAME",
            help="Run only this benchmark (repeatable): spring-chain, rlc, chain-scaling, "
            "pendulum, ensemble, sweep, compile.",
        ),
    ] = None,
    json_path: Annotated[
        Path | None, typer.Option("--json", metavar="PATH", help="Also write the results as JSON.")
    ] = None,
    repeats: Annotated[
        str | None,
        typer.Option(
            callback=_positive_int,
            metavar="INT",
            help="Repeats of the paper's timing protocol (default 1000, or 10 with --quick); "
            "the longer timings use at most this many.",
        ),
    ] = None,
) -> None:
    """Benchmarks: the two sides of each ratio timed interleaved, printed as one table.

    A missed target is shown in the table (exit code 0); a benchmark that could not run
    at all is shown as an error and makes the exit code 1.
    """
    from .bench import BENCHMARKS, Settings
    from .bench import run as run_benchmarks
    from .bench.report import machine_lines, table

    unknown = [name for name in only or () if name not in BENCHMARKS]
    if unknown:
        _fail(
            f"--only {', '.join(map(repr, unknown))}: no such benchmark; choose from "
            f"{', '.join(BENCHMARKS)}.",
            EXIT_USAGE,
        )
    if json_path is not None and not json_path.parent.exists():
        _fail(
            f"--json {str(json_path)!r}: folder {str(json_path.parent)!r} does not exist.",
            EXIT_USAGE,
        )
    settings = Settings(quick=quick, repeats=repeats)
    report = run_benchmarks(settings, only=only, progress=_note)
    console = _out()
    console.print(table(report, width=console.width))
    for line in machine_lines(report):
        console.print(line, markup=False, soft_wrap=True)
    if json_path is not None:
        report.write_json(json_path)
        console.print(f"wrote {json_path}", markup=False, soft_wrap=True)
    if report.errors:
        raise typer.Exit(EXIT_FAILURE)


# --------------------------------------------------------------------- cache
cache_app = typer.Typer(
    help="The on-disk compilation cache (a second run of a model skips XLA compilation).",
    no_args_is_help=True,
)
app.add_typer(cache_app, name="cache")


@cache_app.command("info")
def cache_info() -> None:
    """Where compiled programs are kept, and how many and how large they are.

    The location is the user cache directory, or DIRACVI_CACHE_DIR if set (an empty value
    switches the cache off).
    """
    from . import _cache

    info = _cache.info()
    table = Table(show_header=False)
    table.add_row("enabled", "yes" if info["enabled"] else "no")
    table.add_row("chosen by", info["source"])
    table.add_row("entries", f"{info['entries']:,}")
    table.add_row("of which executables", f"{info['programs']:,} (loaded untraced)")
    table.add_row("size", f"{info['bytes'] / 1e6:.1f} MB")
    out = _out()
    out.print(table)
    # the path on a line of its own, never wrapped or cropped: it is meant to be copied
    out.print(f"path: {info['path'] or '-'}", markup=False, soft_wrap=True)


@cache_app.command("clear")
def cache_clear() -> None:
    """Delete every cached compiled program (the next run of each model compiles again)."""
    from . import _cache

    if _cache.active_dir() is None:
        _out().print("the compilation cache is off: nothing to clear", markup=False)
        return
    removed = _cache.clear()
    _out().print(f"removed {removed:,} files from {_cache.active_dir()}", markup=False)


if __name__ == "__main__":
    app()
