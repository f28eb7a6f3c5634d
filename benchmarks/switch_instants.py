"""Switching instants against exact ones.

    python benchmarks/switch_instants.py [ring|switches|relaxation|all]

* ``ring``: the 7-stage switch ring of ``tests/test_switches.py`` (RING7) at reltol 1e-3,
  1e-4 and 1e-5, its 60 switchings against the exact event-by-event solution
  (``tests/_switch_ring.py``): the mean and rms of the instants' errors, and the located
  crossing's own part — the discrete control at each flip against its level, signed along
  the crossing (positive: past the level), in event tolerances — with the tries, the
  rejected tries and the retries aimed at an instant.
* ``switches``: the corpus deck ``ng_switches`` at its own settings, its flips against
  the PWL controls' exact crossings (0.54545, 1.2, 3.2 and 3.5 ms).
* ``relaxation``: ``tests/data/switches/relaxation.cir`` (C charged through R, discharged
  by an S it controls at 7 V and 3 V), its flips against the closed form and the
  capacitor's voltage at each flip against the level crossed.

Prints CPU seconds (``time.process_time``) per run; run with one BLAS thread. The step
sequences, and so these figures, move with the compiler's options
(``DIRACVI_FAST_COMPILE=1``, as the tests run, or not).
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from diracvi import spice  # noqa: E402
from diracvi.driver import events  # noqa: E402


def ring(reltol):
    import test_switches
    from _switch_ring import ring_switchings

    cpu = time.process_time()
    run = spice.run(test_switches.RING7, reltol=reltol, internal=True)
    cpu = time.process_time() - cpu
    march, system = run.trajectory, run.netlist.system
    t, q, modes = march.t, march.q, march.modes
    found = events.relays(system)
    column = {}
    for j, (i, _) in enumerate(found):
        _, stage, switch = system.coords[i].split(":")
        column[(int(stage[2:]), switch[:2])] = j
    n, vdd = 7, 3.0
    v = [q[:, system.coords.index(f"c:xs{k}:cl.q")] / 1e-13 for k in range(n)]
    flips = {key: list(np.flatnonzero(np.diff(modes[:, j])) + 1) for key, j in column.items()}
    exact = ring_switchings(t[-1], stages=n)
    tol = events.tolerances(system, reltol, 1e-6)[0]
    seen, err, past = {}, [], []
    for te, k, switch, closed in sorted(exact, key=lambda e: e[0]):
        nth = seen.get((k, switch), 0)
        seen[(k, switch)] = nth + 1
        i = flips[(k, switch)][nth]
        err.append(t[i] - te)
        j = (k - 1) % n
        u = v[j][i] if switch == "sn" else vdd - v[j][i]
        level = 1.1 if closed else 0.9
        past.append((u - level) * (1.0 if closed else -1.0) / tol)
    err, past = np.array(err), np.array(past)
    print(
        f"ring reltol {reltol:g}: {len(err)} switchings, error mean {np.mean(err):.3e} s "
        f"rms {np.sqrt(np.mean(err**2)):.3e} s max {np.max(np.abs(err)):.3e} s; "
        f"control past its level at the flip (tolerances): mean {np.mean(past):+.3f} "
        f"min {np.min(past):+.3f} max {np.max(past):+.3f}; tries {march.tries} rejected "
        f"{march.rejected} aimed {march.aimed} steps {len(march.h)} hmin {np.min(march.h):.2e}; "
        f"status {march.status}; CPU {cpu:.1f} s",
        flush=True,
    )


def switches():
    deck = ROOT / "tests" / "data" / "netlists" / "ng_switches.cir"
    cpu = time.process_time()
    run = spice.run(deck, internal=True)
    cpu = time.process_time() - cpu
    march, system = run.trajectory, run.netlist.system
    found = events.relays(system)
    tol = events.tolerances(system, 1e-3, [1e-6 if r.impulse else 1e-12 for _, r in found])
    # v(1) 1 V/ms up to 2 ms then down, v(2) 0.55 V/ms up from 0.9 V then 0.8 V/ms down,
    # i(vm3) 1 mA/ms: closes at 1.2 (V, mA), opens at 0.8
    exact = {"s1": (1.2e-3, 3.2e-3), "s2": (0.3e-3 / 0.55, 3.5e-3), "s3": (3.5e-3,)}
    exact["w1"] = exact["s1"]
    slope = {"s1": (1e3, 1e3), "s2": (550.0, 800.0), "s3": (800.0,), "w1": (1.0, 1.0)}
    late = []
    for j, (i, _) in enumerate(found):
        name = system.coords[i].split(".")[0].split(":")[-1].lower()
        k = np.flatnonzero(np.diff(march.modes[:, j])) + 1
        d = march.t[k] - np.asarray(exact[name])
        w = tol[j] / np.asarray(slope[name])
        late += list(d)
        print(
            f"  {name}: flips late by {', '.join(f'{x * 1e9:+.2f}' for x in d)} ns "
            f"(tol/slope {', '.join(f'{x * 1e9:.1f}' for x in w)} ns)"
        )
    print(
        f"ng_switches: mean {np.mean(late) * 1e9:+.2f} ns; tries {march.tries} rejected "
        f"{march.rejected} aimed {march.aimed} steps {len(march.h)}; CPU {cpu:.1f} s",
        flush=True,
    )


def relaxation():
    import math

    deck = ROOT / "tests" / "data" / "switches" / "relaxation.cir"
    cpu = time.process_time()
    result = spice.run(deck, internal=True)
    cpu = time.process_time() - cpu
    march, system = result.trajectory, result.netlist.system
    k = np.flatnonzero(np.diff(march.modes[:, 0])) + 1
    times, states = march.t[k], march.modes[k, 0]
    rc, r_par, v_low = 1e-4, 10e3 * 100 / 10.1e3, 10 * 100 / 10.1e3
    exact = [rc * math.log(10 / 3)]
    discharge = r_par * 10e-9 * math.log((7 - v_low) / (3 - v_low))
    while len(exact) < len(times):
        exact.append(exact[-1] + (discharge if len(exact) % 2 else rc * math.log(7 / 3)))
    late = times - np.asarray(exact)
    tol = events.tolerances(system, 1e-3, 1e-6)[0]
    offset = march.q[k, system.coords.index("C1.q")] / 10e-9 - np.where(states > 0, 7.0, 3.0)
    past = np.where(states > 0, offset, -offset) / tol
    print(
        f"relaxation: {len(times)} flips; control past its level (tolerances): closing "
        f"{np.mean(past[states > 0]):+.3f}, opening {np.mean(past[states == 0]):+.3f}, all "
        f"{np.mean(past):+.3f}; instants late by {late[0] * 1e9:+.3f} ns first, "
        f"{late[-1] * 1e9:+.3f} ns last, at most {np.max(np.abs(late)) * 1e9:.3f} ns; tries "
        f"{march.tries} rejected {march.rejected} aimed {march.aimed}; CPU {cpu:.1f} s",
        flush=True,
    )


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "all"
    if what in ("switches", "all"):
        switches()
    if what in ("relaxation", "all"):
        relaxation()
    if what in ("ring", "all"):
        for reltol in (1e-3, 1e-4, 1e-5):
            ring(reltol)
