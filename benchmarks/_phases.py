"""Phases of one process timed: wall and CPU seconds, and the XLA compilations in each.

A benchmark's child process (``python -c`` source made by :func:`child_source`) creates
:class:`Phases` first thing, calls :meth:`Phases.count_compiles` before importing
diracvi, and :meth:`Phases.mark` at the end of each phase (a netlist's first phases:
:func:`netlist_start`). The CPU time is the process's
user + system time (all its threads): on a shared machine the wall clock moves with the
others' load, the CPU time much less. Compilations are counted from JAX's
``jax_log_compiles`` messages ("Finished XLA compilation"), one per compiled program.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path


def cpu() -> float:
    """This process's CPU seconds so far (user + system)."""
    t = os.times()
    return t.user + t.system


class Phases:
    """``marks``: ``{phase: (wall, cpu, compiles)}``, each since the previous mark (the
    first since the object was made)."""

    def __init__(self):
        self.marks: dict[str, tuple[float, float, int]] = {}
        self.compiled = 0
        self._last = (time.perf_counter(), cpu(), 0)

    def count_compiles(self) -> None:
        """Count JAX's compilations from here on (imports jax: call it first)."""
        import jax

        phases = self

        class Count(logging.Handler):
            def emit(self, record):
                phases.compiled += "Finished XLA compilation" in record.getMessage()

        jax.config.update("jax_log_compiles", True)
        log = logging.getLogger("jax")
        log.addHandler(Count())
        log.setLevel(logging.WARNING)
        log.propagate = False

    def mark(self, name: str) -> None:
        """End the phase ``name`` now."""
        now = (time.perf_counter(), cpu(), self.compiled)
        self.marks[name] = tuple(b - a for a, b in zip(self._last, now, strict=True))
        self._last = now


def jax_split() -> dict[str, float]:
    """JAX's trace/lower/compile seconds from here on (``diracvi.bench``'s, imported only
    when called: a child times ``import diracvi`` as its own phase)."""
    from diracvi.bench._core import jax_split as split

    return split()


def netlist_start(phases: Phases, deck: str):
    """A netlist run's first phases, marked: ``import`` (diracvi), ``read`` (the deck and
    its system), ``operating point`` (the DC start). Returns ``(netlist, settings,
    breakpoints)`` for its variable-step march (``diracvi.spice._run._march``)."""
    from diracvi import spice
    from diracvi.spice import _run

    phases.mark("import")
    netlist = spice.read(deck)
    netlist.system  # noqa: B018  (built here: its own phase)
    phases.mark("read")
    netlist.initial_state()
    phases.mark("operating point")
    settings = _run.tran_settings(netlist)
    return netlist, settings, _run.breakpoints(netlist.system, 0.0, settings.stop)


def table_head(*columns: str) -> None:
    """Print the machine's load average, then a Markdown table's header row and rule."""
    print(f"load average at start: {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")
    print("| " + " | ".join(columns) + " |")
    print("|" + "---|" * len(columns))


def child_source(body: str) -> str:
    """``python -c`` source: ``body`` after making ``phases`` (a :class:`Phases`, counting
    compilations), this module importable from the child (its folder last on the path)."""
    here = str(Path(__file__).resolve().parent)
    return (
        f"import sys\nsys.path.append({here!r})\n"
        "from _phases import Phases, jax_split, netlist_start\n"
        f"phases = Phases()\nphases.count_compiles()\n{body}"
    )
