"""The outputs of ``diracvi bench``: one rich table, the machine it ran on, and JSON."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from rich.table import Table

from ._core import Row, Settings, fmt_ratio, fmt_value


@dataclass
class Report:
    """Every row of one run, the numbers behind them, and where and how it ran."""

    settings: Settings
    machine: dict
    rows: list[Row] = field(default_factory=list)
    details: dict = field(default_factory=dict)
    durations: dict = field(default_factory=dict)  # benchmark → wall seconds
    errors: dict = field(default_factory=dict)  # benchmark → message

    def to_json(self) -> dict:
        return {
            "settings": {
                "quick": self.settings.quick,
                "paper_repeats": self.settings.paper_repeats,
                "numpy_repeats": self.settings.numpy_repeats,
                "long_repeats": self.settings.long_repeats,
            },
            "machine": self.machine,
            "rows": [row.to_json() for row in self.rows],
            "details": self.details,
            "durations_s": self.durations,
            "errors": self.errors,
        }

    def write_json(self, path: Path) -> None:
        text = json.dumps(self.to_json(), indent=2, default=_json_default)
        Path(path).write_text(text + "\n", encoding="utf-8")


def _json_default(value):
    if hasattr(value, "item"):  # NumPy scalars
        return value.item()
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


def _verdict(row: Row) -> str:
    if row.status == "failed":
        return "[red]error[/red]"
    met = row.met
    if met is None:
        return "—"
    return "[green]yes[/green]" if met else "[red]no[/red]"


#: below this many columns the eight-column table would break words; rows are stacked
WIDE_TABLE_COLUMNS = 140


def table(report: Report, width: int | None = None) -> Table:
    """The one table: benchmark | diracvi | baseline | ratio | target | met? | solver | notes.

    On a console narrower than :data:`WIDE_TABLE_COLUMNS` (``width``), each benchmark is a
    block of ``field  value`` lines instead, so no word is broken across lines.
    """
    mode = "quick" if report.settings.quick else "full"
    if width is not None and width < WIDE_TABLE_COLUMNS:
        return _stacked(report, mode)
    result = Table(title=f"diracvi bench ({mode})", title_justify="left", show_lines=True)
    result.add_column("benchmark", overflow="fold", ratio=3)
    result.add_column("diracvi", justify="right", no_wrap=True)
    result.add_column("baseline", justify="right", no_wrap=True)
    result.add_column("ratio", justify="right", no_wrap=True)
    result.add_column("target", no_wrap=True)
    result.add_column("met?", no_wrap=True)
    result.add_column("solver", overflow="fold", ratio=1)
    result.add_column("notes", overflow="fold", ratio=2)
    for row in report.rows:
        result.add_row(
            row.label,
            fmt_value(row.diracvi, row.unit),
            fmt_value(row.baseline, row.unit),
            fmt_ratio(row.ratio),
            "—" if row.target is None else str(row.target),
            _verdict(row),
            row.solver or "—",
            row.notes,
        )
    return result


def _stacked(report: Report, mode: str) -> Table:
    result = Table(title=f"diracvi bench ({mode})", title_justify="left", show_header=False)
    result.add_column("field", style="bold", no_wrap=True)
    result.add_column("value", overflow="fold")  # only a word wider than the column folds
    for row in report.rows:
        fields = [
            ("benchmark", row.label),
            ("diracvi", fmt_value(row.diracvi, row.unit)),
            ("baseline", fmt_value(row.baseline, row.unit)),
            ("ratio", fmt_ratio(row.ratio)),
            ("target", "—" if row.target is None else str(row.target)),
            ("met?", _verdict(row)),
            ("solver", row.solver or "—"),
            ("notes", row.notes),
        ]
        for i, (key, value) in enumerate(fields):
            result.add_row(key, str(value), end_section=i == len(fields) - 1)
    return result


def machine_lines(report: Report) -> list[str]:
    """Where and when it ran, in a few lines under the table."""
    m = report.machine
    load = m.get("load_average")
    lines = [
        f"machine: {m['cpu']}, {m['cores']} cores, {m['platform']}",
        f"versions: python {m['python']}, jax {m['jax']} ({m['jax_backend']}, "
        f"{m.get('cpu_dispatch', 'unknown')} CPU dispatch), "
        f"numpy {m['numpy']}, scipy {m['scipy']}, diracvi {m['diracvi']}"
        + (f" (commit {m['commit']})" if m.get("commit") else ""),
        f"date: {m['date']}; load average at start: {load}; at end: {m.get('load_average_end')}",
        "timings: warm calls, min over repeats, sides of each ratio interleaved; "
        + ", ".join(f"{name} {sec:.0f} s" for name, sec in report.durations.items()),
    ]
    for name, message in report.errors.items():
        lines.append(f"error in {name}: {message}")
    return lines


def markdown(data: dict) -> str:
    """The table and machine lines of a ``--json`` file as Markdown (for the README)."""
    from . import BENCHMARKS  # the package imports this module: import at call time

    head = "| benchmark | diracvi | baseline | ratio | target | met? | solver | notes |"
    lines = [head, "|---|---:|---:|---:|---|---|---|---|"]
    for row in data["rows"]:
        met = {True: "yes", False: "no", None: "—"}[row["met"]]
        if row["status"] == "failed":
            met = "error"
        cells = [
            row["label"],
            fmt_value(row["diracvi"], row["unit"]),
            fmt_value(row["baseline"], row["unit"]),
            fmt_ratio(row["ratio"]),
            row["target"] or "—",
            met,
            row["solver"] or "—",
            row["notes"],
        ]
        lines.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    m = data["machine"]
    command = "diracvi bench" + (" --quick" if data["settings"]["quick"] else "")
    ran = list(data["durations_s"])
    if ran != list(BENCHMARKS):
        command += "".join(f" --only {name}" for name in ran)
    commit = f" at commit {m['commit']}" if m.get("commit") else ""
    lines += [
        "",
        f"Run: `{command}`{commit} on {m['date']}; "
        f"{m['cpu']}, {m['cores']} cores; python {m['python']}, jax {m['jax']}, "
        f"numpy {m['numpy']}, scipy {m['scipy']}, diracvi {m['diracvi']}; load average "
        f"{m['load_average']} at start, {m.get('load_average_end')} at end.",
    ]
    return "\n".join(lines)
