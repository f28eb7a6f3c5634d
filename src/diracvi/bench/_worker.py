"""Measurements in a fresh Python process, under a wall-time and a memory limit.

Used where a fresh process is the honest setting (first-call latency: nothing compiled or
cached yet) and where a size might not fit (the largest chains): the parent watches the
child's resident memory and kills it past ``max_rss_bytes``, so a benchmark that does
not fit is reported as such instead of exhausting a shared machine.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time

#: resident memory a benchmark child may use before it is stopped (bytes)
MAX_RSS_BYTES = 12 * 1024**3  # half of the 24 GiB the project machines have


class WorkerFailed(RuntimeError):
    """The child exceeded its limits, crashed, or printed no result."""


def _rss_bytes(pid: int) -> int:
    try:
        with open(f"/proc/{pid}/statm", encoding="ascii") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0  # no /proc (not Linux) or the child just exited: nothing to watch


def run_child(
    args: list[str], *, timeout: float, max_rss_bytes: int = MAX_RSS_BYTES, cache_dir: str = ""
) -> dict:
    """Run ``python ARGS``; return the JSON object it prints on its last stdout line.

    The child's on-disk compilation cache is ``cache_dir`` (``DIRACVI_CACHE_DIR``); the
    default, empty, switches it off, so a first call in the child compiles for real.

    Raises :class:`WorkerFailed` if it runs longer than ``timeout`` seconds, holds more
    than ``max_rss_bytes`` of resident memory, exits non-zero or prints no JSON.
    """
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        env = {**os.environ, "DIRACVI_CACHE_DIR": cache_dir}
        proc = subprocess.Popen([sys.executable, *args], stdout=out, stderr=err, text=True, env=env)
        start, peak, reason = time.perf_counter(), 0, None
        while proc.poll() is None:
            peak = max(peak, _rss_bytes(proc.pid))
            elapsed = time.perf_counter() - start
            if peak > max_rss_bytes:
                reason = f"needed more than {max_rss_bytes / 1024**3:.3g} GB of memory"
            elif elapsed > timeout:
                reason = f"took longer than {timeout:.0f} s"
            if reason is not None:
                proc.kill()
                proc.wait()
                raise WorkerFailed(reason)
            time.sleep(0.05)
        out.seek(0)
        err.seek(0)
        lines = out.read().strip().splitlines()
        if proc.returncode != 0 or not lines:
            tail = err.read().strip().splitlines()[-3:]
            raise WorkerFailed(f"exit code {proc.returncode}: {' | '.join(tail)}")
        try:
            result = json.loads(lines[-1])
        except json.JSONDecodeError as exc:
            raise WorkerFailed(f"no result printed ({exc})") from None
    result["peak_rss_bytes"] = peak
    return result
