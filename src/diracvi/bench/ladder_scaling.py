r"""RLC ladders of 10²…10⁴ stages against ngspice ``-b`` (issue 30): end to end and warm.

For each ladder (:func:`diracvi.bench.ladders.ladder`: R, L, C per stage, a 1 kHz sine,
2000 steps of 1 µs, ``uic``), side by side in one run:

- **ngspice**: ``ngspice -b`` on the netlist with a ``.control`` block that runs the
  ``.tran`` (maximum step = the netlist's step, default tolerances) and writes three
  probes with ``wrdata``: the whole process's wall time and peak RSS;
- **diracvi end to end**: ``diracvi run ladder.cir --dt 1e-06`` as a subprocess (Python
  start, ``import diracvi``, reading, the plan, stepping, the summary) at the netlist's
  step, fixed as ngspice's maximum step is, with the disk cache cold (a fresh
  ``DIRACVI_CACHE_DIR``) and then warm (the same directory again): wall time and peak
  RSS; up to ``MAX_OUT`` stages also with ``--out x.nc`` (the saved vectors written);
- **warm in-process** ``simulate``: after a first call in this process, the min of a few;
- **agreement**: ``max |v_diracvi − v_ngspice| / peak`` over the probes, ngspice
  interpolated onto diracvi's time nodes (t > 0);
- **without** ``--dt``: ``diracvi run ladder.cir`` as a circuit engineer types it
  (SPICE's variable steps; a linear circuit takes :mod:`diracvi.driver.adaptive_sparse`),
  cold then warm, wall and CPU seconds and peak RSS, its agreement from an in-process
  ``spice.run`` on the TSTEP grid.

``DIRACVI_BENCH_LADDERS`` (comma-separated stage counts) overrides the sizes: default
100, 1000 and 10⁴ (100 with ``--quick``); 10⁵ on request (see ``benchmarks/README.md``
for what limits it).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .. import spice
from ._core import Row, Settings
from .ladders import ladder

NAME = "circuits"
PROBES = ("v(n1)", "v(n10)", "i(L1)")
SIZES_ENV = "DIRACVI_BENCH_LADDERS"
#: the ladders' step (the netlist's TSTEP, fixed for diracvi, ngspice's maximum step)
DT = 1e-6
#: the largest ladder also run with ``--out`` (the NetCDF holds every variable)
MAX_OUT = 1000


def sizes(settings: Settings) -> tuple[int, ...]:
    raw = os.environ.get(SIZES_ENV, "").strip()
    if raw:
        return tuple(int(x) for x in raw.split(",") if x.strip())
    return (100,) if settings.quick else (100, 1000, 10_000)


#: runs a command and prints its wall time, exit code and peak RSS (KB): a child of this
#: small process, so the RSS is the command's own (a child forked from this benchmark's
#: process would report at least the benchmark's RSS: Linux keeps the high-water mark
#: of the forked memory across exec)
_WRAPPER = (
    "import os, sys, time\n"
    "t = time.perf_counter()\n"
    "pid = os.fork()\n"
    "if pid == 0:\n"
    "    os.execvp(sys.argv[1], sys.argv[1:])\n"
    "_, status, usage = os.wait4(pid, 0)\n"
    "wall = time.perf_counter() - t\n"
    "cpu = usage.ru_utime + usage.ru_stime\n"
    "print(f'\\n@@ {wall!r} {os.waitstatus_to_exitcode(status)} {usage.ru_maxrss} {cpu!r}')\n"
)


def _timed(cmd, cwd, env=None, check=True, cpu=None) -> tuple[float, float, str]:
    """Wall time (s), peak RSS (MB) and stdout+stderr of a command (``check``: a nonzero
    exit is an error; ngspice -b exits 1 after a .control run that worked); ``cpu``: a
    list the command's CPU seconds (user + system) are appended to."""
    proc = subprocess.run(
        [sys.executable, "-c", _WRAPPER, *cmd], cwd=cwd, env=env, capture_output=True, text=True
    )
    out = proc.stdout + proc.stderr
    tail = [line for line in proc.stdout.splitlines() if line.startswith("@@ ")]
    if not tail:
        raise RuntimeError(f"{cmd[0]} did not run:\n{out[-2000:]}")
    wall, code, kb, seconds = tail[-1].split()[1:]
    if cpu is not None:
        cpu.append(float(seconds))
    if check and int(code) != 0:
        raise RuntimeError(f"{cmd[0]} failed ({code}):\n{out[-2000:]}")
    return float(wall), int(kb) / 1024.0, out


#: the CPU seconds of the last ngspice run (for the notes)
_NGSPICE_CPU: list[float] = []


def _ngspice(text: str, tmp: Path):
    """``ngspice -b`` of the ladder writing the probes: (wall, MB, t, values)."""
    body = text.rpartition(".end")[0].rstrip()
    deck = "\n".join(
        [body, ".control", "set wr_singlescale", "set wr_vecnames", "option numdgt=15", "run",
         f"wrdata out.txt {' '.join(PROBES)}", ".endc", ".end", ""]
    )  # fmt: skip
    lines = deck.splitlines()
    tran = next(k for k, line in enumerate(lines) if line.lower().startswith(".tran"))
    step, stop = lines[tran].split()[1:3]
    lines[tran] = f".tran {step} {stop} 0 {step} uic"  # maximum step: the netlist's step
    (tmp / "deck.cir").write_text("\n".join(lines))
    cpu: list[float] = []
    wall, mb, log = _timed(["ngspice", "-b", "deck.cir"], tmp, check=False, cpu=cpu)
    _NGSPICE_CPU[:] = cpu
    if not (tmp / "out.txt").exists():
        raise RuntimeError(f"ngspice failed:\n{log[-2000:]}")
    data = np.loadtxt(tmp / "out.txt", skiprows=1, ndmin=2)
    return wall, mb, data[:, 0], {p: data[:, 1 + j] for j, p in enumerate(PROBES)}


def _diracvi_run(path: Path, dt, cache: Path, tmp: Path, out: bool = False, cpu=None):
    """``diracvi run path [--dt dt] [--out x.nc]``: wall (s) and peak RSS (MB);
    ``dt=None``: SPICE's variable steps."""
    env = dict(os.environ, DIRACVI_CACHE_DIR=str(cache))
    src = Path(__file__).resolve().parents[2]  # the package's own tree first
    env["PYTHONPATH"] = os.pathsep.join([str(src), env.get("PYTHONPATH", "")])
    code = "from diracvi.cli import app; app()"
    cmd = [sys.executable, "-c", code, "run", str(path)]
    if dt is not None:
        cmd += ["--dt", repr(dt)]
    if out:
        cmd += ["--out", str(tmp / "x.nc")]
    wall, mb, _ = _timed(cmd, tmp, env, cpu=cpu)
    return wall, mb


def _variable_agreement(text: str, t_ref, ref) -> tuple[float, str]:
    """``spice.run`` without ``dt`` (SPICE's variable steps, output on the TSTEP grid):
    max error / peak vs ngspice over the probes, and the path that ran."""
    result = spice.run(text)
    worst = 0.0
    mask = result.time > 0
    for p in PROBES:
        peak = float(np.max(np.abs(ref[p])))
        expect = np.interp(result.time[mask], t_ref, ref[p])
        worst = max(worst, float(np.max(np.abs(result[p][mask] - expect))) / peak)
    return worst, result.trajectory.solver


def _warm(text: str, repeats: int):
    import diracvi as dv

    netlist = spice.read(text)
    kw = dict(dt=netlist.dt, steps=netlist.steps, discretization="midpoint")
    dv.simulate(netlist.system, netlist.q0, netlist.p0, **kw)
    best, traj = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        traj = dv.simulate(netlist.system, netlist.q0, netlist.p0, **kw)
        best = min(best, time.perf_counter() - t0)
    return best, netlist, traj


def _agreement(netlist, traj, t_ref, ref) -> float:
    from ..spice import waveforms

    got = waveforms(netlist, traj)
    worst = 0.0
    mask = traj.t > 0
    for p in PROBES:
        key = next(k for k in got if k.lower() == p.lower())
        peak = float(np.max(np.abs(ref[p])))
        expect = np.interp(traj.t[mask], t_ref, ref[p])
        worst = max(worst, float(np.max(np.abs(got[key][mask] - expect))) / peak)
    return worst


def rows(settings: Settings) -> list[Row]:
    out = []
    repeats = 3
    for stages in sizes(settings):
        dt = DT
        text = ladder(stages, dt=dt)
        with tempfile.TemporaryDirectory() as tmp_name:
            tmp = Path(tmp_name)
            path = tmp / f"ladder{stages}.cir"
            path.write_text(text)
            ng_wall, ng_mb, t_ref, ref = _ngspice(text, tmp)
            ng_cpu = _NGSPICE_CPU[0]
            cache = tmp / "cache"
            cold, cold_mb = _diracvi_run(path, dt, cache, tmp)
            warm_e2e, warm_mb = _diracvi_run(path, dt, cache, tmp)
            with_out = size_mb = None
            if stages <= MAX_OUT:
                with_out, _ = _diracvi_run(path, dt, cache, tmp, out=True)
                size_mb = (tmp / "x.nc").stat().st_size / 1e6
            var_cpu: list[float] = []
            var_cold, _ = _diracvi_run(path, None, cache, tmp, cpu=var_cpu)
            var_warm, var_mb = _diracvi_run(path, None, cache, tmp, cpu=var_cpu)
            var_err, var_solver = _variable_agreement(text, t_ref, ref)
            warm, netlist, traj = _warm(text, repeats)
            err = _agreement(netlist, traj, t_ref, ref)
        label = f"ladder {stages} stages ({3 * stages + 1} elements, 2000 steps)"
        notes = (
            f"max error / peak vs ngspice {err:.1e}; peak RSS diracvi {warm_mb:.0f} MB (cold "
            f"{cold_mb:.0f}), ngspice {ng_mb:.0f} MB"
        )
        if with_out is not None:
            notes += f"; with --out (saved vectors, {size_mb:.0f} MB NetCDF) {with_out:.1f} s"
        solver = traj.solver
        out += [
            Row(NAME, f"{label}: `diracvi run` end to end, cache cold ÷ ngspice -b", cold,
                ng_wall, cold / ng_wall, solver=solver, notes=notes),
            Row(NAME, f"{label}: `diracvi run` end to end, cache warm ÷ ngspice -b", warm_e2e,
                ng_wall, warm_e2e / ng_wall, solver=solver, notes=notes),
            Row(NAME, f"{label}: warm in-process simulate ÷ ngspice -b", warm, ng_wall,
                warm / ng_wall, solver=solver, notes=f"min of {repeats}; error {err:.1e}"),
            Row(NAME, f"{label}: `diracvi run` without --dt (variable steps), cache warm "
                "÷ ngspice -b", var_warm, ng_wall, var_warm / ng_wall, solver=var_solver,
                notes=f"max error / peak vs ngspice {var_err:.1e}; CPU {var_cpu[1]:.1f} s "
                f"(cold: {var_cold:.1f} s wall, {var_cpu[0]:.1f} s CPU); peak RSS "
                f"{var_mb:.0f} MB; ngspice CPU {ng_cpu:.2f} s"),
        ]  # fmt: skip
    return out
