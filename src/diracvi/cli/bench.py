"""``diracvi bench``: the benchmarks, one table of measured ratios."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from .common import (
    EXIT_FAILURE,
    EXIT_USAGE,
    _fail,
    _note,
    _out,
    _positive_int,
)


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
            "pendulum, ensemble, gradients, sweep, compile, first-call, cache, "
            "closure-chain, driven, work-precision, circuits.",
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
    from ..bench import BENCHMARKS, Settings
    from ..bench import run as run_benchmarks
    from ..bench.report import machine_lines, table

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
