r"""The on-disk compilation cache: a second process's first call against a cold one.

For the paper's torn double pendulum (``--quick``: the torn RLC circuit) two fresh
processes run one after the other with the same new, empty ``DIRACVI_CACHE_DIR``: the
first compiles everything and writes the cache, the second reads it. Each times its
first ``dv.simulate`` call (tracing, compilation or cache reads, every check and the run)
exactly as :mod:`.compile_latency` does. What the cache cannot save is tracing and
lowering to XLA's input, which every process repeats.
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


def run(settings: Settings) -> Result:
    name = PROBLEM[settings.quick]
    cache = tempfile.mkdtemp(prefix="diracvi-bench-cache-")
    try:
        cold = run_child(["-c", WORKER, name], timeout=TIMEOUT, cache_dir=cache)
        warm = run_child(["-c", WORKER, name], timeout=TIMEOUT, cache_dir=cache)
    except WorkerFailed as exc:
        row = Row(NAME, f"second process: {name}", None, None, None, TARGET, notes=str(exc))
        return Result([row], {})
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    row = Row(
        NAME,
        f"first call of {name}: second process ÷ cold process",
        warm["first_call_s"],
        cold["first_call_s"],
        warm["first_call_s"] / cold["first_call_s"],
        TARGET,
        solver=warm["solver"],
        notes=f"fresh processes sharing one new cache dir; import {cold['import_s']:.2f} s",
    )
    return Result([row], {"cold": cold, "second": warm})
