"""Progress reporting for ``reproduce``: silent by default, a rich display from the CLI.

The experiments only call :meth:`step` (a new stage, optionally with a number of ticks)
and :meth:`tick`; how that is shown is the caller's business.
"""

from __future__ import annotations


class Progress:
    """Does nothing; subclasses display."""

    def step(self, description: str, total: int | None = None) -> None:
        """A new stage begins (``total`` ticks follow, if given)."""

    def tick(self) -> None:
        """One unit of the current stage is done."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def close(self) -> None:
        pass


class RichProgress(Progress):
    """One rich progress bar per stage; the finished ones stay on screen as a log.

    On a console that is not a terminal (CI, pipes, typer's ``CliRunner``) rich draws
    no live display, so each stage is also printed as one plain line.
    """

    def __init__(self, console=None):
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            TextColumn,
            TimeElapsedColumn,
        )
        from rich.progress import Progress as _RichProgress

        self.console = console if console is not None else Console(stderr=True)
        self._live = self.console.is_terminal
        self._bar = _RichProgress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=self.console,
            disable=not self._live,
        )
        self._task = None
        self._bar.start()

    def _finish_current(self) -> None:
        if self._task is not None:
            task = self._bar.tasks[-1]
            self._bar.update(self._task, completed=task.total)

    def step(self, description: str, total: int | None = None) -> None:
        self._finish_current()
        self._task = self._bar.add_task(description, total=total or 1)
        if not self._live:
            self.console.print(f"• {description}", markup=False, highlight=False, soft_wrap=True)

    def tick(self) -> None:
        if self._task is not None:
            self._bar.advance(self._task)

    def close(self) -> None:
        self._finish_current()
        self._bar.stop()
