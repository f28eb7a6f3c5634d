"""A small netlist's ``diracvi run`` as a circuit user first meets it, beside ngspice.

python benchmarks/netlist_first_call.py [--decks ng_rc es_rc …] [--repeats N] [--phases]

Each deck runs as a fresh ``diracvi run DECK --out FILE.nc`` process (the command a user
types), twice: **cold** with an empty ``DIRACVI_CACHE_DIR`` (nothing compiled yet) and
**warm** right after, with the cache the cold run filled; beside it ``ngspice -b`` on the
same deck. Each side is timed by wall clock and by the CPU time of the child (user +
system, from ``os.wait4``): on a shared machine the wall clock moves with the others'
load, the CPU time much less. ``--repeats N`` takes the minimum of N rounds (each round:
cold, warm, ngspice).

``--phases`` adds, per deck, a breakdown of one process, cold then warm (a fresh process
each, in this order): import of the command line (typer, rich and the pydantic typer
validates with), import of what the run needs (JAX, Equinox, diracvi's netlist modules),
reading the deck, the DC operating point, the variable-step march (loading or compiling
its program and running it), resampling onto the TSTEP grid, writing the NetCDF file,
and the XLA compilations in each phase (``jax_log_compiles``: a warm run that compiles
nothing shows 0).

``--bytecode``: the children may write and read Python's compiled bytecode (``.pyc``, in
a folder of the run's own, ``PYTHONPYCACHEPREFIX``, filled by one untimed import first),
as an installed diracvi has it. Without it they inherit the environment: where
``PYTHONDONTWRITEBYTECODE`` is set and the source tree has no ``__pycache__`` (this
project's sandbox), every process compiles diracvi's ~120 modules from source, ≈ 0.25
CPU s that a user's second run does not pay.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from _phases import child_source

HERE = Path(__file__).resolve().parent
NETLISTS = HERE.parent / "tests" / "data" / "netlists"
DECKS = ("ng_rc", "liec_cap_charging", "liec_halfwave", "es_rc", "xy_rlc")


def deck_path(name: str) -> Path:
    """The corpus deck ``name``: its ``file`` in ``EXPECTED.toml`` (a deck in a folder
    with its includes, as ``es_bjt_amp``), else ``NAME.cir`` beside it."""
    with open(NETLISTS / "EXPECTED.toml", "rb") as f:
        entry = tomllib.load(f).get(name)
    path = NETLISTS / (entry["file"] if entry else f"{name}.cir")
    if not path.is_file():
        raise SystemExit(f"deck {name!r}: {path} does not exist; name a deck of {NETLISTS}.")
    return path


def runnable(deck: Path, work: Path) -> Path:
    """``deck``, or where ``diracvi run`` takes it as a netlist: a deck named otherwise
    (``BJT_amplifier.cir.out``) is copied with its folder (its includes) into ``work``
    and given the suffix ``.cir``, unedited."""
    if deck.suffix.lower() in (".cir", ".sp", ".spice", ".net", ".ckt"):
        return deck
    folder = work / "deck"
    shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(deck.parent, folder)
    copy = folder / f"{deck.name}.cir"
    shutil.copy(deck, copy)
    return copy


def timed(command: list[str], env: dict, cwd: Path, check: bool = True) -> tuple[float, float]:
    """``(wall, cpu)`` seconds of ``command`` as a child process (its CPU: user + system
    of the child and its own children, from ``os.wait4``). ``check=False``: a failing
    exit status is accepted (ngspice -b on a deck with text after ``.end`` runs the
    deck, then fails on the rest as a second circuit)."""
    start = time.perf_counter()
    child = subprocess.Popen(
        command, env=env, cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    err = child.stderr.read().decode(errors="replace")
    child.stderr.close()
    if check and os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{err}")
    return wall, usage.ru_utime + usage.ru_stime


def diracvi_command(deck: Path, out: Path) -> list[str]:
    return [sys.executable, "-m", "diracvi.cli.main", "run", str(deck), "--out", str(out)]


def child_env(work: Path, bytecode: bool) -> dict:
    """The children's environment: the cache in ``work``, and with ``bytecode`` Python's
    compiled modules kept in ``work/pyc`` (see the module docstring)."""
    env = {**os.environ, "DIRACVI_CACHE_DIR": str(work / "cache")}
    if bytecode:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(work / "pyc")
    return env


def prime_bytecode(env: dict, work: Path) -> None:
    """Write the run's modules' bytecode once (an untimed import of what a run imports)."""
    subprocess.run(
        [sys.executable, "-c", "import diracvi.cli.main, diracvi.spice._run, h5netcdf"],
        env=env,
        cwd=work,
        check=True,
    )


def measure(deck: Path, work: Path, bytecode: bool = False) -> dict:
    """One round on ``deck``: cold, warm, ngspice."""
    cache = work / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    env = child_env(work, bytecode)
    row = {}
    row["cold"] = timed(diracvi_command(deck, work / "cold.nc"), env, work)
    row["warm"] = timed(diracvi_command(deck, work / "warm.nc"), env, work)
    row["ngspice"] = timed(["ngspice", "-b", str(deck)], env, work, check=False)
    return row


PHASES = child_source(r"""
import diracvi.cli.main  # noqa: F401  (the command line, as `diracvi run` imports it)
import pydantic  # noqa: F401  (what typer checks the options with when it parses them)
phases.mark("import CLI")
netlist, settings, breaks = netlist_start(phases, sys.argv[1])
from diracvi import spice
from diracvi.spice import _run
mark = phases.mark
march = _run._march(netlist, settings, breaks)
mark("march")
result = spice.run(netlist)  # the march again (its program is in memory) and resampling
mark("resample (+march)")
result.save(sys.argv[2])
mark("write NetCDF")
for name, (wall, cpu, n) in phases.marks.items():
    print(f"{name}\t{wall:.2f}\t{cpu:.2f}\t{n}")
wall, cpu, _ = (sum(x) for x in zip(*phases.marks.values()))
print(f"total\t{wall:.2f}\t{cpu:.2f}\t{phases.compiled}")
""")


def phases(deck: Path, work: Path, bytecode: bool = False) -> list[tuple[str, list]]:
    """Per phase ``(name, [cold wall, cold cpu, cold compiles, warm wall, warm cpu,
    warm compiles])`` of one cold and one warm process on ``deck``."""
    cache = work / "cache"
    shutil.rmtree(cache, ignore_errors=True)
    env = child_env(work, bytecode)
    runs = []
    for label in ("cold", "warm"):
        out = subprocess.run(
            [sys.executable, "-c", PHASES, str(deck), str(work / f"{label}.nc")],
            env=env,
            cwd=work,
            capture_output=True,
            text=True,
            check=True,
        )
        runs.append([line.split("\t") for line in out.stdout.strip().splitlines()])
    return [(cold[0], [*cold[1:], *warm[1:]]) for cold, warm in zip(runs[0], runs[1], strict=True)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decks", nargs="+", default=list(DECKS))
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--phases", action="store_true")
    parser.add_argument(
        "--bytecode", action="store_true", help="children keep .pyc files (module docstring)"
    )
    args = parser.parse_args()
    if shutil.which("ngspice") is None:
        raise SystemExit("ngspice is not on PATH: it is the baseline of this benchmark.")
    print(f"load average at start: {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")
    print("| deck | diracvi cold | diracvi warm | ngspice -b | cold/ngspice | warm/ngspice |")
    print("|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="diracvi-first-call-") as tmp:
        work = Path(tmp)
        if args.bytecode:
            prime_bytecode(child_env(work, True), work)
        for name in args.decks:
            deck = runnable(deck_path(name), work)
            rounds = [measure(deck, work, args.bytecode) for _ in range(args.repeats)]
            best = {k: min(r[k][0] for r in rounds) for k in rounds[0]}
            cpu = {k: min(r[k][1] for r in rounds) for k in rounds[0]}
            print(
                f"| {name} | {best['cold']:.2f} s ({cpu['cold']:.2f} CPU) "
                f"| {best['warm']:.2f} s ({cpu['warm']:.2f} CPU) "
                f"| {best['ngspice']:.3f} s | {best['cold'] / best['ngspice']:.0f}× "
                f"| {best['warm'] / best['ngspice']:.0f}× |",
                flush=True,
            )
        if args.phases:
            for name in args.decks:
                print(f"\n{name}: seconds per phase, wall (CPU), XLA compilations")
                print("| phase | cold | cold compiles | warm | warm compiles |")
                print("|---|---|---|---|---|")
                deck = runnable(deck_path(name), work)
                for phase, (cw, cc, cn, ww, wc, wn) in phases(deck, work, args.bytecode):
                    print(f"| {phase} | {cw} ({cc}) | {cn} | {ww} ({wc}) | {wn} |", flush=True)
    print(f"load average at end: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
