"""Reproduce the numerical examples of Parks & Leok §5: figures, ``summary.json``, report.

    from diracvi.reproduce import reproduce
    outcome = reproduce("out", quick=True)
    outcome.summary["examples"]["spring_chain"]["max_position_difference"]

Modules: :mod:`.paper` (the paper's numbers), :mod:`.experiments` (the runs),
:mod:`.metrics` (the comparisons), :mod:`.timing` (the paper's timing protocol),
:mod:`.figures`, :mod:`.report` and :mod:`.document` (the outputs), :mod:`.progress`.
"""

from __future__ import annotations

import json
import os
import platform
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import jax

from ..runtime.dispatch import mode as dispatch_mode
from . import convergence
from .experiments import EXAMPLES, Settings, run_example
from .figures import FIGURES, render_all
from .progress import Progress
from .report import deviations
from .report import write as write_report


@dataclass(frozen=True)
class Outcome:
    """What ``reproduce`` wrote, and the summary it wrote into ``summary.json``."""

    out: Path
    summary: dict
    figures: tuple[Path, ...]
    summary_path: Path
    report_md: Path
    report_html: Path


def _load() -> list[float] | None:
    """The 1-, 5- and 15-minute load averages (None where the OS has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def _json_default(value):
    # NumPy scalars and tuples that slipped into the summary
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


def reproduce(
    out, *, quick: bool = False, repeats: int | None = None, progress: Progress | None = None
) -> Outcome:
    """Run every §5 experiment and write the figures, ``summary.json`` and the report.

    Args:
        out: output folder (created if missing; existing files are overwritten).
        quick: a short smoke run — fewer timing repeats and a shorter long run — that
            still writes every file.
        repeats: timing repeats (default 1000, or 20 with ``quick``).
        progress: a :class:`~diracvi.reproduce.progress.Progress` to report to.
    """
    from .. import __version__

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    settings = Settings.make(quick=quick, repeats=repeats)
    progress = progress if progress is not None else Progress()
    load_before = _load()
    results = {ex.key: run_example(ex, settings, progress) for ex in EXAMPLES}

    progress.step("convergence table: order 2 and order 4 on a forced oscillator")
    orders = convergence.convergence_table(
        convergence.STEPS_PER_PERIOD[:3] if settings.quick else convergence.STEPS_PER_PERIOD
    )
    progress.step(f"writing {len(FIGURES)} figures")
    figures = (*render_all(results, out), convergence.render(orders, out))
    summary = {
        "diracvi_version": __version__,
        "created": datetime.now(UTC).isoformat(timespec="seconds"),
        "quick": settings.quick,
        "settings": {"repeats": settings.repeats, "long_steps": settings.long_steps},
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "jax": jax.__version__,
            "cpu_dispatch": dispatch_mode(),
            "cpus": os.cpu_count(),
            # other work on the machine inflates timings; record it beside them
            "load_average_before": load_before,
            "load_average_after": _load(),
        },
        "figures": {p.name: FIGURES[p.name][0] for p in figures},
        "examples": {key: r.summary for key, r in results.items()},
        "convergence": orders,
    }
    summary["deviations"] = deviations(summary)
    progress.step("writing summary.json and the report")
    summary_path = out / "summary.json"
    summary_path.write_text(
        json.dumps(summary, indent=2, ensure_ascii=False, default=_json_default) + "\n",
        encoding="utf-8",
    )
    md, page = write_report(summary, out)
    progress.close()
    return Outcome(out, summary, figures, summary_path, md, page)


__all__ = ["EXAMPLES", "FIGURES", "Outcome", "Settings", "reproduce"]
