"""The sparse path's two error controls side by side: step doubling (three solves a try)
against the local truncation error (one solve a step, :mod:`diracvi.driver.sparse_truncation`).

    PYTHONPATH=src OPENBLAS_NUM_THREADS=1 python benchmarks/sparse_errors.py [STAGES ...]

For each RLC ladder of STAGES stages (default 1000; :func:`diracvi.bench.ladders.ladder`,
``.tran 1u 2m uic``): a fine ngspice reference (reltol 1e-7, TMAX = TSTEP/50) of the
probes of :mod:`diracvi.bench.ladder_scaling` (kept in the temporary directory for
reruns), ``ngspice -b`` at the deck's own settings (CPU seconds of the whole process),
then ``spice.run`` in this process under each control, each once to load its programs
and then timed warm: tries, sparse solves, recorded steps, CPU seconds of the
variable-step loop and of the whole call, and the max error / peak against the fine
reference on the TSTEP grid. CPU seconds are the figure to compare on a loaded machine;
the rows of one run are measured side by side.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402

from diracvi import spice  # noqa: E402
from diracvi.bench import ladder_scaling as bench  # noqa: E402
from diracvi.bench.ladders import ladder  # noqa: E402
from diracvi.driver import adaptive_sparse as A  # noqa: E402
from diracvi.spice import _ngspice as ng  # noqa: E402
from diracvi.spice import _run  # noqa: E402

FINE = ".options reltol=1e-7 abstol=1e-15 vntol=1e-12 chgtol=1e-18 trtol=1"


def _counted(text: str, error: str) -> dict:
    """One ``spice.run`` under ``error``: its counts, CPU seconds, and the result."""
    solves, loop = [0], [0.0]
    step, march = A._Map.step, _run._march

    def counting(self, z, u):
        solves[0] += 1
        return step(self, z, u)

    def timed(*args, **kwargs):
        c = time.process_time()
        try:
            return march(*args, **kwargs)
        finally:
            loop[0] += time.process_time() - c

    A._Map.step, _run._march = counting, timed
    try:
        c = time.process_time()
        result = spice.run(text, step_error=error)
        call = time.process_time() - c
    finally:
        A._Map.step, _run._march = step, march
    traj = result.trajectory
    return dict(
        tries=traj.tries, solves=solves[0], steps=len(traj.h), loop=loop[0], call=call,
        result=result, solver=traj.solver,
    )  # fmt: skip


def _fine(text: str):
    """The fine ngspice reference of the probes, kept in the temporary directory by the
    deck's hash (minutes for a large ladder: computed once for reruns)."""
    import hashlib

    key = hashlib.sha256((text + FINE).encode()).hexdigest()[:16]
    path = Path(tempfile.gettempdir()) / f"diracvi-sparse-errors-{key}.npz"
    if path.exists():
        data = np.load(path)
        return data["t"], {p: data[p] for p in bench.PROBES}
    t_ref, ref = ng.ngspice(text, bench.PROBES, tmax=1e-6 / 50, options=FINE)
    np.savez(path, t=t_ref, **ref)
    return t_ref, ref


def main(sizes: list[int]) -> None:
    print("| stages | control | tries | solves | steps | loop CPU s | call CPU s | "
          "max error / peak vs fine ngspice |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for stages in sizes:
        text = ladder(stages)
        t_ref, ref = _fine(text)
        with tempfile.TemporaryDirectory() as name:
            bench._ngspice(text, Path(name))
        print(f"| {stages} | ngspice -b (own settings, whole process) | | | | | "
              f"{bench._NGSPICE_CPU[0]:.2f} | |", flush=True)  # fmt: skip
        for error in A.ERRORS:
            _counted(text, error)  # (programs loaded or compiled: not timed)
            row = _counted(text, error)
            result, worst = row["result"], 0.0
            keep = result.time > t_ref[0]
            for probe in bench.PROBES:
                want = np.interp(result.time[keep], t_ref, ref[probe])
                peak = float(np.max(np.abs(ref[probe])))
                got = result[probe][keep]
                worst = max(worst, float(np.max(np.abs(got - want))) / peak)
            assert row["solver"] == A.DESCRIBE, row["solver"]
            print(f"| {stages} | {error} | {row['tries']} | {row['solves']} | {row['steps']} | "
                  f"{row['loop']:.2f} | {row['call']:.2f} | {worst:.2e} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(description="the sparse path's two error controls")
    ap.add_argument("sizes", type=int, nargs="*", help="stage counts (default 1000)")
    main(ap.parse_args().sizes or [1000])
