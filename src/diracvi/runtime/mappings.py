r"""The process's memory mappings, which compiled programs use up before memory.

Linux gives a process at most ``vm.max_map_count`` memory mappings (65 530 by default).
An XLA CPU executable keeps its machine code in mappings of its own — one or more per
kernel: measured with jaxlib 0.10, a one-solve program ≈ 46, a netlist's stepping program
≈ 100 — for as long as the executable lives, and executables live as long as something
holds them: this process's program store (:mod:`diracvi.runtime.store`), and JAX's own
in-memory caches, which keep up to 2048 compilations per cache for every function that
stays alive (a module-level function such as an analysis program: all of them). So a
long process that builds many different models — a notebook, a sweep over netlists, a
test session — reaches the limit with a few hundred to a thousand programs alive, not
with its memory (24 GiB free at the time). Past it ``mmap`` fails inside LLVM's or XLA's
code, which does not check: the process dies (measured: SIGSEGV in
``serialize_executable`` at the 193rd slow test of one session, its core holding 65 433
mappings, vm.max_map_count 65 530; earlier the same run died by SIGABRT), losing
whatever it had not written.

So before a program is compiled or loaded, :func:`relieve` counts the mappings and, past
:data:`BUDGET_SHARE` of the limit, drops every executable the process holds in memory
(the store's and JAX's caches, :func:`jax.clear_caches`): each is loaded again from the
on-disk store, or compiled again, when next called. Nothing is lost but that time, and
the count falls back to what the live models need.
"""

from __future__ import annotations

import gc
import logging
from collections.abc import Callable
from pathlib import Path

log = logging.getLogger(__name__)

#: past this share of vm.max_map_count the executables held in memory are dropped
BUDGET_SHARE = 0.5
_LIMIT_FILE = Path("/proc/sys/vm/max_map_count")
_MAPS_FILE = Path("/proc/self/maps")


def limit() -> int | None:
    """``vm.max_map_count``, or ``None`` where there is no such limit to read (not Linux)."""
    try:
        return int(_LIMIT_FILE.read_text())
    except (OSError, ValueError):
        return None


def count() -> int | None:
    """How many memory mappings this process has (one line of ``/proc/self/maps`` each),
    or ``None`` where that cannot be read. About 3 ms at 30 000 mappings."""
    try:
        with open(_MAPS_FILE, "rb") as maps:
            return sum(block.count(b"\n") for block in iter(lambda: maps.read(1 << 20), b""))
    except OSError:
        return None


#: the mapping count past which :func:`relieve` drops executables (``None``: never);
#: read once, a test may set it
BUDGET: int | None = None if limit() is None else int(BUDGET_SHARE * limit())


def relieve(drop_own: Callable[[], None]) -> bool:
    """Past :data:`BUDGET` mappings, drop every executable this process holds in memory:
    ``drop_own()`` (the store's), then JAX's caches; ``True`` if it did."""
    global BUDGET
    if BUDGET is None:
        return False
    before = count()
    if before is None or before <= BUDGET:
        return False
    import jax

    drop_own()
    jax.clear_caches()
    gc.collect()
    after = count()
    log.info("%s memory mappings past %s: programs dropped, %s now", before, BUDGET, after)
    hard = limit()
    if after is not None and hard is not None and after > BUDGET:
        # what holds them is not a program: the next relief halfway to the limit, not at
        # every compile (each would drop what was just compiled)
        BUDGET = after + (hard - after) // 2
        log.warning(
            "this process holds %s memory mappings (vm.max_map_count %s) after dropping every "
            "compiled program: it may run out of them",
            after,
            hard,
        )
    return True
