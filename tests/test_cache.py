"""The on-disk compilation cache: where it is, switching it off, and a second process
really reading the first one's programs (JAX's own cache log says hit or miss).

White-box: reads internals of ``diracvi.runtime``."""

import os
import re
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from diracvi.cli import app
from diracvi.runtime import cache as _cache

# A small model in a fresh process that logs JAX's cache decisions. Its Lagrangian is a
# callable Module of the user's, which diracvi keeps whole (not lifted to a program), so
# the program store (diracvi.runtime.store, tested in test_stored.py) cannot key its programs:
# they are traced in every process, and JAX's cache saves their compilation.
CHILD = """
import logging, sys
logging.basicConfig(level=logging.WARNING, stream=sys.stdout, format="%(message)s")
logging.getLogger("jax._src.compiler").setLevel(logging.DEBUG)
import equinox as eqx
import numpy as np
import diracvi as dv

class Springs(eqx.Module):
    k: float
    def __call__(self, q, v):
        return 0.5 * v @ v - 0.5 * self.k * (q @ q + (q[0] - q[1]) ** 2)

system = dv.LagrangeDiracSystem(("x", "y"), Springs(2.0))
dv.simulate(system, np.array([1.0, 0.0]), np.zeros(2), dt=0.01, steps=20)
"""


def _child(cache: str) -> str:
    env = {**os.environ, "DIRACVI_CACHE_DIR": cache}
    out = subprocess.run(
        [sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, timeout=300
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def _written(log: str) -> set[str]:
    """Keys of the programs a process compiled and wrote to the cache (JAX logs a miss
    with its key, then "took at least … seconds to compile" when it writes it)."""
    keys, last = set(), None
    for line in log.splitlines():
        miss = re.search(r"CACHE MISS for '[^']+' with key '([^']+)'", line)
        if miss:
            last = miss.group(1)
        elif "took at least" in line and last is not None:
            keys.add(last)
    return keys


def test_location_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("DIRACVI_CACHE_DIR", str(tmp_path / "c"))
    assert _cache.cache_dir() == tmp_path / "c"
    monkeypatch.setenv("DIRACVI_CACHE_DIR", "")
    assert _cache.cache_dir() is None  # empty: switched off
    monkeypatch.delenv("DIRACVI_CACHE_DIR")
    default = _cache.cache_dir()
    assert default is not None and default.name == "jax" and "diracvi" in str(default)


def test_second_process_reads_the_first_ones_programs(tmp_path):
    cache = str(tmp_path / "cache")
    first = _child(cache)
    written = _written(first)
    assert written and any(p.is_file() for p in Path(cache).rglob("*"))
    second = _child(cache)
    # every program the first process wrote is read back, none compiled again (a tiny
    # program below the write threshold in one process may cross it in the other)
    hits = set(re.findall(r"cache hit for '[^']+' with key '([^']+)'", second))
    assert written <= hits, written - hits
    assert not written & set(re.findall(r"CACHE MISS for '[^']+' with key '([^']+)'", second))


def test_empty_value_switches_the_cache_off():
    log = _child("")
    assert "Persistent compilation cache hit" not in log
    assert f"< {_cache.MIN_COMPILE_SECONDS:.2f} seconds" not in log  # JAX's defaults rule


def test_cli_info_and_clear(tmp_path, monkeypatch):
    path = tmp_path / "cache"
    (path / "sub").mkdir(parents=True)
    (path / _cache.PROGRAMS).mkdir()
    (path / "a").write_bytes(b"x" * 10)
    (path / "sub" / "b").write_bytes(b"y" * 5)
    (path / _cache.PROGRAMS / "k.exe").write_bytes(b"z" * 5)  # a stored executable
    monkeypatch.setattr(_cache, "active_dir", lambda: path)
    runner = CliRunner()
    info = runner.invoke(app, ["cache", "info"])
    assert info.exit_code == 0, info.output
    assert str(path) in info.output
    assert re.search(r"entries\s*│\s*3\b", info.output), info.output
    assert re.search(r"executables\s*│\s*1\b", info.output), info.output
    cleared = runner.invoke(app, ["cache", "clear"])
    assert cleared.exit_code == 0, cleared.output
    assert "removed 3 files" in cleared.output
    assert not path.exists()
    monkeypatch.setattr(_cache, "active_dir", lambda: None)
    off = runner.invoke(app, ["cache", "clear"])
    assert off.exit_code == 0 and "off" in off.output
