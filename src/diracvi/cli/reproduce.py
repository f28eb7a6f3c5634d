"""``diracvi reproduce``: the paper's §5 — figures, summary.json and a report."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from .common import (
    EXIT_USAGE,
    _err,
    _fail,
    _library_errors,
    _out,
    _positive_int,
)


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
    from ..reproduce import reproduce as run_reproduce
    from ..reproduce.progress import RichProgress
    from ..reproduce.report import fmt

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
