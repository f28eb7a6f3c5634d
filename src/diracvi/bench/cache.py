r"""The on-disk compilation cache: a second process's first call against a cold one.

For the paper's torn double pendulum (``--quick``: the torn RLC circuit) two fresh
processes run one after the other with the same new, empty ``DIRACVI_CACHE_DIR``: the
first compiles everything and writes the cache, the second reads it. Each times its
first ``dv.simulate`` call (tracing, compilation or cache reads, every check and the run)
exactly as :mod:`.compile_latency` does. The second process loads diracvi's stored
executables (:mod:`diracvi.runtime.store`) without tracing or lowering them; what is left is
reading them, the Python side of the plan's analysis and the run itself.

A first call is one sample of a few seconds, which a busy machine stretches at random;
so the pair (cold, second) is repeated with a new cache each time, the pairs one after
the other (each second process right after its cold one), and the ratio is of the
minima, as every other timing of ``diracvi bench`` is.
"""

from __future__ import annotations

import shutil
import tempfile

from ._core import Result, Row, Settings, Target
from ._worker import WorkerFailed, run_child
from .compile_latency import TIMEOUT, WORKER

NAME = "cache"
DESCRIPTION = "first call in a second process (compilation cache) ÷ in a cold one"

PROBLEM = {False: "double-pendulum-torn", True: "rlc-torn"}
TARGET = Target("<=", 0.3)

#: (cold, second) pairs of fresh processes; with ``--quick`` one pair
PAIRS = 3


def _pair(name: str) -> tuple[dict, dict]:
    """A cold process and a second one sharing a new, empty cache directory."""
    cache = tempfile.mkdtemp(prefix="diracvi-bench-cache-")
    try:
        cold = run_child(["-c", WORKER, name], timeout=TIMEOUT, cache_dir=cache)
        second = run_child(["-c", WORKER, name], timeout=TIMEOUT, cache_dir=cache)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return cold, second


def run(settings: Settings) -> Result:
    name = PROBLEM[settings.quick]
    try:
        pairs = [_pair(name) for _ in range(1 if settings.quick else PAIRS)]
    except WorkerFailed as exc:
        row = Row(NAME, f"second process: {name}", None, None, None, TARGET, notes=str(exc))
        return Result([row], {})
    cold = min(c["first_call_s"] for c, _ in pairs)
    second = min(s["first_call_s"] for _, s in pairs)
    row = Row(
        NAME,
        f"first call of {name}: second process ÷ cold process (min of {len(pairs)} each)",
        second,
        cold,
        second / cold,
        TARGET,
        solver=pairs[0][1]["solver"],
        notes=(
            f"fresh processes, a new cache dir per (cold, second) pair; "
            f"import {min(c['import_s'] for c, _ in pairs):.2f} s"
        ),
    )
    details = {"pairs": [{"cold": c, "second": s} for c, s in pairs]}
    return Result([row], details)
