"""``diracvi cache info|clear``: the on-disk compilation cache."""

from __future__ import annotations

import typer
from rich.table import Table

from .common import (
    _out,
)

cache_app = typer.Typer(
    help="The on-disk compilation cache (a second run of a model skips XLA compilation).",
    no_args_is_help=True,
)


@cache_app.command("info")
def cache_info() -> None:
    """Where compiled programs are kept, and how many and how large they are.

    The location is the user cache directory, or DIRACVI_CACHE_DIR if set (an empty value
    switches the cache off).
    """
    from ..runtime import cache as _cache

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
    from ..runtime import cache as _cache

    if _cache.active_dir() is None:
        _out().print("the compilation cache is off: nothing to clear", markup=False)
        return
    removed = _cache.clear()
    _out().print(f"removed {removed:,} files from {_cache.active_dir()}", markup=False)
