"""RLC ladders run as a circuit engineer runs them: ``diracvi run ladder.cir`` without
``--dt`` (SPICE's variable steps; a linear circuit takes the sparse maps of
:mod:`diracvi.driver.adaptive_sparse`), beside ``ngspice -b`` (issues 30, 28).

    PYTHONPATH=src python benchmarks/ladder_variable.py 100 1000
    PYTHONPATH=src python benchmarks/ladder_variable.py --probes --single 10000 100000
    PYTHONPATH=src python benchmarks/ladder_variable.py --phases 1000

For each ladder of N stages (:func:`diracvi.bench.ladders.ladder`): ngspice's wall and CPU
seconds and peak RSS; ``diracvi run`` with the disk cache cold, then warm (a fresh
``DIRACVI_CACHE_DIR``, then the same again): wall and CPU seconds and peak RSS; then an
in-process ``spice.run`` and its max error / peak against ngspice over the probes of
:mod:`diracvi.bench.ladder_scaling` on the TSTEP grid, and the path that ran. CPU seconds
are the figure to compare on a loaded machine.

``--phases``: instead, where a fresh ``diracvi run ladder.cir`` process spends its wall
and CPU seconds, cache cold then warm (a new ``DIRACVI_CACHE_DIR``, then the same): the
imports, reading the deck (the model built and packed), the sparse maps' structural
pattern, the four probe builds (of them: the programs' keys, loading or compiling them),
and the loop's parts — the steps, the offsets, the error estimates, recording, the maps
of new step sizes, the verification; ngspice ``-b`` beside it.

Options for the large ladders (minutes each, so not in the default run; at 10⁵ stages
``--probes --single`` took ngspice 385 CPU s and diracvi 366 CPU s at a peak RSS of
4.2 GB, ``benchmarks/README.md``):

- ``--probes``: a ``.save`` line of the probes in the deck, for both programs: each keeps
  only those on its output (without it, every node voltage and inductor current on the
  2001-point grid: 4.8 GB at 10⁵ stages, in ngspice as in diracvi);
- ``--single``: one ``diracvi run`` (the disk cache of the environment's
  ``DIRACVI_CACHE_DIR``, else a fresh one: cold) with ``--out``, and the agreement read
  from its file instead of a second, in-process run.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from diracvi.bench import ladder_scaling as bench
from diracvi.bench.ladders import ladder


def _deck(stages: int, probes: bool) -> str:
    text = ladder(stages)
    if probes:
        body, _, tail = text.rpartition(".end")
        text = body + f".save {' '.join(bench.PROBES)}\n.end" + tail
    return text


def _file_agreement(path: Path, t_ref, ref) -> float:
    """Max error / peak vs ngspice over the probes, from ``diracvi run --out``'s file."""
    import h5netcdf

    worst = 0.0
    with h5netcdf.File(path, "r") as f:
        t = np.asarray(f.variables["time"][...])
        names = {k.lower(): k for k in f.variables}
        mask = t > 0
        for p in bench.PROBES:
            got = np.asarray(f.variables[names[p.lower()]][...])
            peak = float(np.max(np.abs(ref[p])))
            expect = np.interp(t[mask], t_ref, ref[p])
            worst = max(worst, float(np.max(np.abs(got[mask] - expect))) / peak)
    return worst


#: a fresh ``diracvi run`` with its phases timed by wrapping the functions named (nested
#: phases are included in their parents; the wrappers cost ≈ 1 µs a call)
_PHASES_CHILD = """
import os, sys, time
def clock():
    t = os.times()
    return time.perf_counter(), t.user + t.system
spent = {}
def wrap(owner, attr, label):
    original = getattr(owner, attr)
    def timed(*a, **k):
        wa, ca = clock()
        try:
            return original(*a, **k)
        finally:
            wb, cb = clock()
            s = spent.setdefault(label, [0.0, 0.0, 0])
            s[0] += wb - wa; s[1] += cb - ca; s[2] += 1
    setattr(owner, attr, timed)
w0, c0 = clock()
from diracvi.cli import app
from diracvi import spice
from diracvi.cli import common
from diracvi.driver import adaptive_sparse as A
from diracvi.runtime import store
from diracvi.spice import _run, _stream
w1, c1 = clock()
spent["import diracvi (the CLI)"] = [w1 - w0, c1 - c0, 1]
wrap(spice, "read", "read (parse, build, pack)")
wrap(A, "structural_pattern", "  structural pattern")
wrap(A._Maps, "_try_fit", "  4 probe builds")
wrap(store, "canonical", "    program keys")
wrap(store, "load", "    executables loaded")
wrap(store, "compile_fresh", "    compiled")
wrap(A._Map, "step", "  steps (3 a try)")
wrap(A._Offsets, "_rows", "  offsets")
wrap(A, "estimate", "  error estimates")
wrap(_stream.StreamRecord, "add", "  recording (grid streamed)")
wrap(A, "_verify", "  verification")
wrap(_run, "_march", "run (variable steps)")
sys.argv = ["diracvi", "run", sys.argv[1]]
try:
    app()
except SystemExit:
    pass
w2, c2 = clock()
spent["process (after Python's start)"] = [w2 - w0, c2 - c0, 1]
for label, (wall, cpu, calls) in spent.items():
    print(f"@@{label}|{wall!r}|{cpu!r}|{calls}")
"""


def phases(sizes: list[int]) -> None:
    """The per-phase table of a fresh ``diracvi run``, cold and warm (module doc)."""
    import subprocess

    for stages in sizes:
        with tempfile.TemporaryDirectory() as name:
            tmp = Path(name)
            path = tmp / f"ladder{stages}.cir"
            path.write_text(ladder(stages))
            wall = bench._ngspice(ladder(stages), tmp)[0]
            print(f"{stages} stages: ngspice -b wall {wall:.2f} s, CPU "
                  f"{bench._NGSPICE_CPU[0]:.2f} s; load {os.getloadavg()[0]:.1f}")  # fmt: skip
            env = dict(os.environ, DIRACVI_CACHE_DIR=str(tmp / "cache"))
            src = Path(bench.__file__).resolve().parents[2]  # this checkout's package
            env["PYTHONPATH"] = os.pathsep.join([str(src), env.get("PYTHONPATH", "")])
            table: dict[str, list] = {}
            for _ in ("cold", "warm"):  # (one cache directory: the second run is warm)
                out = subprocess.run(
                    [sys.executable, "-c", _PHASES_CHILD, str(path)], env=env, cwd=tmp,
                    capture_output=True, text=True, check=True,
                ).stdout  # fmt: skip
                for line in out.splitlines():
                    if line.startswith("@@"):
                        phase, wall, cpu, calls = line[2:].split("|")
                        table.setdefault(phase, []).append((float(wall), float(cpu), calls))
            print("| phase | calls | cold: wall, CPU s | warm: wall, CPU s |")
            print("|---|---|---|---|")
            for phase, cells in table.items():
                given = " | ".join(f"{w:.2f}, {c:.2f}" for w, c, _ in cells)
                print(f"| {phase} | {cells[-1][2]} | {given} |", flush=True)


def main(sizes: list[int], probes: bool = False, single: bool = False) -> None:
    for stages in sizes:
        text = _deck(stages, probes)
        with tempfile.TemporaryDirectory() as name:
            tmp = Path(name)
            path = tmp / f"ladder{stages}.cir"
            path.write_text(text)
            wall, mb, t_ref, ref = bench._ngspice(text, tmp)
            print(f"{stages} stages: ngspice -b wall {wall:.2f} s, CPU "
                  f"{bench._NGSPICE_CPU[0]:.2f} s, RSS {mb:.0f} MB", flush=True)  # fmt: skip
            if single:
                cache = Path(os.environ.get("DIRACVI_CACHE_DIR", tmp / "cache"))
                cpu: list[float] = []
                wall, mb = bench._diracvi_run(path, None, cache, tmp, out=True, cpu=cpu)
                err = _file_agreement(tmp / "x.nc", t_ref, ref)
                print(f"{stages} stages: diracvi run --out (no --dt): wall {wall:.1f} s, CPU "
                      f"{cpu[-1]:.1f} s, RSS {mb:.0f} MB; max error / peak vs ngspice "
                      f"{err:.2e}", flush=True)  # fmt: skip
                continue
            cache, cpu = tmp / "cache", []
            for label in ("cold", "warm"):
                wall, mb = bench._diracvi_run(path, None, cache, tmp, cpu=cpu)
                print(f"{stages} stages: diracvi run (no --dt), cache {label}: wall {wall:.1f} "
                      f"s, CPU {cpu[-1]:.1f} s, RSS {mb:.0f} MB", flush=True)  # fmt: skip
            t, c = time.perf_counter(), time.process_time()
            err, solver = bench._variable_agreement(text, t_ref, ref)
            print(f"{stages} stages: in-process spice.run wall {time.perf_counter() - t:.1f} s, "
                  f"CPU {time.process_time() - c:.1f} s; max error / peak vs ngspice "
                  f"{err:.2e}; path: {solver}", flush=True)  # fmt: skip


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="RLC ladders: diracvi run beside ngspice")
    ap.add_argument("sizes", type=int, nargs="*", help="stage counts (default 100 1000)")
    ap.add_argument("--probes", action="store_true", help="a .save line of the probes")
    ap.add_argument("--single", action="store_true", help="one diracvi run --out")
    ap.add_argument("--phases", action="store_true", help="a fresh run's phases instead")
    args = ap.parse_args()
    if args.phases:
        phases(args.sizes or [1000])
    else:
        main(args.sizes or [100, 1000], probes=args.probes, single=args.single)
