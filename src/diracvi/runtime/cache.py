"""The on-disk compilation cache: a second process reuses the first one's programs.

XLA compilation is most of a first ``simulate`` call (seconds for a small torn model) and
is the same in every process that runs the same model, so JAX's persistent compilation
cache is switched on when diracvi is imported, in the user's cache directory
(``platformdirs.user_cache_dir("diracvi")``, e.g. ``~/.cache/diracvi/jax`` on Linux).
``DIRACVI_CACHE_DIR`` overrides the location; set to the empty string it switches the
cache off. A cache directory the user gave JAX themselves
(``jax_compilation_cache_dir``) is left alone.

diracvi's own program store (:mod:`diracvi.runtime.store`) keeps whole executables in the
:data:`PROGRAMS` folder of the same directory, keyed before tracing, so a later process
skips tracing and lowering as well; ``diracvi cache info|clear`` cover both.

Programs are keyed by JAX on their lowered form, so they are reusable across processes
only if no value that changes between processes is baked into them: diracvi passes the
model's parameters, the state, ``dt`` and the clock as arguments (see
:mod:`diracvi.driver.stepping`), and the user functions' captured arrays are lifted to
arguments (:mod:`diracvi.runtime.program`).
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import jax

ENV = "DIRACVI_CACHE_DIR"
_SOURCE = ["off"]  # what chose the location (set by enable)
#: programs that compile faster than this are not written (reading one costs about as much)
MIN_COMPILE_SECONDS = 0.05
#: the folder of the cache directory where diracvi's program store (diracvi.runtime.store)
#: keeps compiled executables, beside JAX's own entries
PROGRAMS = "programs"


def cache_dir() -> Path | None:
    """Where compiled programs are kept, or ``None`` when the cache is switched off."""
    value = os.environ.get(ENV)
    if value is not None:
        return Path(value).expanduser() if value.strip() else None
    import platformdirs  # only here: an explicit DIRACVI_CACHE_DIR needs no lookup

    return Path(platformdirs.user_cache_dir("diracvi", appauthor=False)) / "jax"


def enable() -> Path | None:
    """Point JAX's persistent compilation cache at :func:`cache_dir` (import time)."""
    if jax.config.jax_compilation_cache_dir:  # the user configured JAX: theirs wins
        _SOURCE[0] = "jax_compilation_cache_dir (set by the user)"
        return Path(jax.config.jax_compilation_cache_dir)
    path = cache_dir()
    if path is None:
        _SOURCE[0] = f"off (${ENV} is empty)"
        return None
    _SOURCE[0] = f"${ENV}" if os.environ.get(ENV) else "the user cache directory (platformdirs)"
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path


def info() -> dict:
    """The cache's location, whether it is on, the number and size of its entries, and
    how many of them are stored executables (:mod:`diracvi.runtime.store`)."""
    path = active_dir()
    entries, size, programs = 0, 0, 0
    if path is not None and path.is_dir():
        for item in path.rglob("*"):
            if item.is_file():
                entries += 1
                size += item.stat().st_size
                programs += item.parent.name == PROGRAMS and item.suffix == ".exe"
    return {
        "enabled": path is not None,
        "path": None if path is None else str(path),
        "entries": entries,
        "programs": programs,
        "bytes": size,
        "source": _SOURCE[0],
    }


def clear() -> int:
    """Delete every cached program; return how many files were removed."""
    path = active_dir()
    if path is None or not path.is_dir():
        return 0
    removed = sum(1 for item in path.rglob("*") if item.is_file())
    shutil.rmtree(path)
    return removed


def active_dir() -> Path | None:
    configured = jax.config.jax_compilation_cache_dir
    return Path(configured) if configured else None
