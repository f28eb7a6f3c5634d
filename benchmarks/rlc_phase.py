"""Where `es_rlc`'s error comes from: ``python benchmarks/rlc_phase.py [--table]``.

The deck (R 1k, L 2 H, C 0.5 µF in series from a 0 → 5 V ramp over 0.5 ms, ``.tran 10m
100m``, reltol 1e-3) has a closed form, so its run's error splits without a reference:

* the run's global error at its step centres (each step's mean current against the
  exact current at the centre, its charge against the exact one at its end);
* what the output's resampling (``spice/_resample.py``) adds on top, on a fine grid;
* each try's true local error (from the exact state at the try's start, the try's two
  recorded midpoint steps against the exact end), of the charge and of the inductor's
  nodal current, in the step control's tolerances ``s·rtol·peak`` (``s`` =
  :data:`diracvi.driver.step_error.SAFETY`, peaks over the run).

``--table`` prints every try through the first 14 ms of the ringing. Measured in the
docs ("`es_rlc`: the ringing's phase", ``docs/circuits.md``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

import numpy as np  # noqa: E402
from scipy.linalg import expm  # noqa: E402

from diracvi import spice  # noqa: E402
from diracvi.driver.step_error import SAFETY  # noqa: E402

DECK = ROOT / "tests" / "data" / "netlists" / "es_rlc.cir"
R, L, C, RAMP, VOLTS = 1e3, 2.0, 0.5e-6, 0.5e-3, 5.0
# (q, i, source, its slope): the source is the ramp's line, then constant
A = np.array([[0, 1, 0, 0], [-1 / (L * C), -R / L, 1 / L, 0], [0, 0, 0, 1], [0, 0, 0, 0.0]])


def exact(t: float) -> np.ndarray:
    """The closed form ``(q, i)`` at ``t`` (at rest at t = 0)."""
    start = np.array([0.0, 0.0, 0.0, VOLTS / RAMP])
    if t <= RAMP:
        return (expm(A * t) @ start)[:2]
    corner = expm(A * RAMP) @ start
    corner[3] = 0.0
    return (expm(A * (t - RAMP)) @ corner)[:2]


def source(t: float) -> float:
    return VOLTS * min(t, RAMP) / RAMP


def midpoint(x: np.ndarray, t: float, h: float) -> np.ndarray:
    """One implicit-midpoint step of the series loop (the (+) Dirac step's charge and
    nodal current: ``tests/test_nodal_momentum_error.py``)."""
    a, b, eye = A[:2, :2], np.array([0.0, 1.0 / L]), np.eye(2)
    return np.linalg.solve(eye - 0.5 * h * a, (eye + 0.5 * h * a) @ x + h * b * source(t + h / 2))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--table", action="store_true", help="every try of 2-14 ms")
    args = parser.parse_args()
    cpu = time.process_time()
    result = spice.run(DECK)
    cpu = time.process_time() - cpu
    run = result.trajectory
    t, h = run.t, run.h
    q = run.q[:, list(result.netlist.system.coords).index("c1.q")]
    fine = np.linspace(0.0, 0.1, 20001)[1:]
    states = np.array([exact(s) for s in fine])
    q_peak, i_peak = np.max(np.abs(states[:, 0])), np.max(np.abs(states[:, 1]))
    centres = t[:-1] + 0.5 * h
    at_centres = np.array([exact(s) for s in centres])
    current = np.diff(q) / h
    i_centre = np.abs(current - at_centres[:, 1]) / i_peak
    q_nodes = np.abs(q[1:] - np.array([exact(s)[0] for s in t[1:]])) / q_peak
    waves = result.at(fine)
    i_out = np.abs(waves["i(l1)"] - states[:, 1]) / i_peak
    v_out = np.abs(waves["v(out)"] - states[:, 0] / C) / (q_peak / C)
    print(f"es_rlc at its own settings: {len(h)} steps, {run.tries} tries, {cpu:.2f} s CPU")
    print(f"  i(l1):  at the step centres {i_centre.max():.3e} of peak (at "
          f"{centres[i_centre.argmax()] * 1e3:.2f} ms), resampled {i_out.max():.3e}")  # fmt: skip
    print(f"  charge: at the nodes {q_nodes.max():.3e} of peak; v(out) resampled {v_out.max():.3e}")
    print(f"  before the ramp's corner (0.5 ms): i(l1) {i_centre[centres < RAMP].max():.1e}")
    # the tries: two recorded steps each (the run's steps come in equal pairs)
    tol_q, tol_i = SAFETY * 1e-3 * q_peak, SAFETY * 1e-3 * i_peak
    rows = []
    for k in range(0, len(h) - 1, 2):
        start, size = t[k], h[k] + h[k + 1]
        x0 = exact(start)
        end = midpoint(midpoint(x0, start, h[k]), start + h[k], h[k + 1])
        local = (end - exact(start + size)) / np.array([tol_q, tol_i])
        rows.append((start, size, *local))
    rows = np.array(rows)
    ring = (rows[:, 0] > 2e-3) & (rows[:, 0] < 14e-3)
    print(f"  tries of 2-14 ms: local error of the charge up to {np.abs(rows[ring, 2]).max():.2f}, "
          f"of the nodal current up to {np.abs(rows[ring, 3]).max():.2f} tolerances")  # fmt: skip
    if args.table:
        print("   t ms     H µs   charge   current  (local error / s·rtol·peak)")
        for start, size, lq, li in rows[ring]:
            print(f"{start * 1e3:8.3f} {size * 1e6:8.1f} {lq:8.2f} {li:8.2f}")


if __name__ == "__main__":
    main()
