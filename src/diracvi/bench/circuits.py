r"""Netlists against ngspice: time at matched accuracy, and a lossless LC tank's energy.

1. **Matched accuracy.** For each validation netlist (:mod:`diracvi.spice._ngspice`:
   RC charge, the paper's RLC, a 3-stage ladder, coupled inductors, a half-wave diode
   rectifier, a full-wave bridge rectifier) a fine ngspice run (maximum step
   ``TSTOP/40000``, tight tolerances) is the reference.
   diracvi runs midpoint at the netlist's test step ``h``; its error ``e`` is the max over
   ``t > 0`` and over the probes of ``|x − x_ref| / peak``. ngspice (trapezoidal, default
   tolerances) is run with maximum steps ``h·2^j``, j = 3, 2, …, −3, and the first
   (cheapest) one whose error is ≤ ``e`` is timed. Times: a warm ``spice.run`` call
   (min of repeats) against the ngspice batch run's wall time minus that of an empty
   deck (process start-up and file output; min of repeats). Ratio: diracvi ÷ ngspice.
   The bridge (:data:`VARIABLE`) is also timed as a user runs it, ``spice.run(deck)``
   on SPICE's variable steps at the deck's own tolerances: ``e`` at the run's own nodes,
   ngspice's maximum steps ``TSTEP·2^−j``, j = 0 … 7.
2. **Energy drift.** An LC tank, ``L = C = 1`` (period 2π), started at ``v = 1``, 10⁶
   steps of ``h = 2π/100``; the drift is ``max_k |E_k − E_0| / E_0`` of each method's own
   energy. diracvi midpoint: the half-step energy ``½ L i_{k+½}² + q̄_{k+½}²/(2C)`` from
   the branch charges (``i_{k+½} = (q_{k+1} − q_k)/h``, ``q̄`` the average), which the
   midpoint rule conserves exactly on a linear circuit, so what remains is round-off.
   ngspice (trapezoidal and Gear, default tolerances, maximum step ``h``): the node energy
   ``½ C v² + ½ L i²`` of its output (trapezoidal conserves it for a fixed step; its step
   and error control do not keep the step fixed). (The node-sampled energy of diracvi's
   reported ``v(n)``, ``i(L1)`` oscillates by O(h²), 2e-3 here, without drift.)

3. **Ladders** of 10²… stages end to end and warm against ``ngspice -b``
   (:mod:`diracvi.bench.ladder_scaling`).

Without ngspice the rows are reported as not run.
"""

from __future__ import annotations

import math
import time

import numpy as np

from .. import spice
from ..spice._ngspice import CIRCUITS, available, ngspice
from . import ladder_scaling
from ._core import BenchmarkError, Result, Row, Settings

NAME = "circuits"
#: the validation circuits also timed on SPICE's variable steps (``spice.run(deck)``)
VARIABLE = ("bridge",)
DESCRIPTION = "SPICE netlists vs ngspice at matched accuracy; LC tank energy drift (10⁶ steps)"

EMPTY = "empty\nR1 a 0 1\nV1 a 0 1\n.tran 1 1\n.end\n"
LC = """LC tank, L = C = 1
L1 n 0 1 IC=0
C1 n 0 1 IC=1
.tran {h!r} {stop!r} uic
.end
"""


def _wall(fn, repeats):
    best = math.inf
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def _error(t, values, ref_t, ref, probes):
    worst = 0.0
    for p in probes:
        peak = np.max(np.abs(ref[p]))
        mask = t > 0
        got = np.interp(t[mask], ref_t, ref[p])
        worst = max(worst, float(np.max(np.abs(values[p][mask] - got)) / peak))
    return worst


def _cheapest(netlist, probes, err, steps, ref_t, ref, repeats):
    """The first of ngspice's runs at maximum steps ``steps`` (trapezoidal, default
    tolerances) whose error is at most ``err``, timed: ``(tmax, seconds, its error)``
    (seconds: min of ``repeats``, minus an empty deck's run), or ``None``."""
    t_empty, _ = _wall(lambda: ngspice(EMPTY, ("v(a)",), tmax=1.0, options=".options"), repeats)
    for tmax in steps:
        t_ng, (ts, vs) = _wall(
            lambda tmax=tmax: ngspice(netlist, probes, tmax, options=".options"), 1
        )
        if _error(ts, vs, ref_t, ref, probes) <= err:
            t_ng, (ts, vs) = _wall(
                lambda tmax=tmax: ngspice(netlist, probes, tmax, options=".options"), repeats
            )
            return tmax, max(t_ng - t_empty, 1e-6), _error(ts, vs, ref_t, ref, probes), t_empty
    return None


def _matched(name, settings: Settings) -> Row:
    netlist, probes, h = CIRCUITS[name]
    parsed = spice.read(netlist)
    stop = parsed.stop
    ref_t, ref = ngspice(netlist, probes, tmax=stop / 40000)
    result = spice.run(parsed, dt=h, steps=round(stop / h))
    err = _error(result.time, {p: result[p] for p in probes}, ref_t, ref, probes)
    repeats = settings.long_repeats
    t_dv, _ = _wall(lambda: spice.run(parsed, dt=h, steps=round(stop / h)), repeats)
    steps = [h * 2.0**j for j in range(3, -4, -1)]
    chosen = _cheapest(netlist, probes, err, steps, ref_t, ref, repeats)
    if chosen is None:
        return Row(
            NAME, f"{name}: diracvi vs ngspice at matched accuracy", t_dv, None, None,
            solver=result.trajectory.solver, status="not run",
            notes=f"ngspice did not reach diracvi's error {err:.1e} with tmax ≥ h/8",
        )  # fmt: skip
    tmax, t_ng, err_ng, t_empty = chosen
    return Row(
        NAME,
        f"{name}: diracvi midpoint (h = {h:g}) ÷ ngspice trap at matched accuracy",
        t_dv,
        t_ng,
        t_dv / t_ng,
        solver=result.trajectory.solver,
        notes=f"error {err:.1e} vs ngspice {err_ng:.1e} (tmax = {tmax:g}); ngspice "
        f"minus start-up {t_empty * 1e3:.0f} ms; min of {repeats}",
    )


def _matched_variable(name, settings: Settings) -> Row:
    """The deck as a user runs it: ``spice.run(deck)``, SPICE's variable steps at the
    deck's own tolerances, its error taken at the run's own nodes (``internal=True``,
    as ngspice's at its own time points); ngspice's maximum step ``TSTEP·2^−j``."""
    netlist, probes, _ = CIRCUITS[name]
    parsed = spice.read(netlist)
    ref_t, ref = ngspice(netlist, probes, tmax=parsed.stop / 40000)
    result = spice.run(parsed, internal=True)
    err = _error(result.time, {p: result[p] for p in probes}, ref_t, ref, probes)
    repeats = settings.long_repeats
    t_dv, _ = _wall(lambda: spice.run(parsed), repeats)
    march = result.trajectory
    steps = [parsed.dt * 2.0**-j for j in range(0, 8)]
    chosen = _cheapest(netlist, probes, err, steps, ref_t, ref, repeats)
    if chosen is None:
        return Row(
            NAME, f"{name}: diracvi variable steps vs ngspice at matched accuracy", t_dv,
            None, None, solver=march.solver, status="not run",
            notes=f"ngspice did not reach diracvi's error {err:.1e} with tmax ≥ TSTEP/128",
        )  # fmt: skip
    tmax, t_ng, err_ng, t_empty = chosen
    return Row(
        NAME,
        f"{name}: diracvi variable steps (deck's tolerances) ÷ ngspice trap at matched accuracy",
        t_dv,
        t_ng,
        t_dv / t_ng,
        solver=march.solver,
        notes=f"error {err:.1e} ({len(march.h)} steps, {march.tries} tries, "
        f"{march.iterations} Newton iterations) vs ngspice {err_ng:.1e} (tmax = {tmax:g}); "
        f"ngspice minus start-up {t_empty * 1e3:.0f} ms; min of {repeats}",
    )


def _energy_drift(steps: int) -> list[Row]:
    h = 2.0 * math.pi / 100.0
    netlist = LC.format(h=h, stop=h * steps)
    parsed = spice.read(netlist)
    t0 = time.perf_counter()
    result = spice.run(parsed, dt=h, steps=steps)
    t_dv = time.perf_counter() - t0
    traj = result.trajectory
    q_l, q_c = traj["L1.q"], traj["C1.q"]
    half = 0.5 * (np.diff(q_l) / h) ** 2 + 0.5 * (0.5 * (q_c[1:] + q_c[:-1])) ** 2
    drift_dv = float(np.max(np.abs(half - half[0])) / half[0])
    node = 0.5 * result["v(n)"] ** 2 + 0.5 * result["i(L1)"] ** 2
    wobble_dv = float(np.max(np.abs(node - 0.5)) / 0.5)
    rows = []
    for method in ("trap", "gear"):
        t0 = time.perf_counter()
        _, vs = ngspice(netlist, ("v(n)", "i(L1)"), tmax=h, method=method, options=".options")
        t_ng = time.perf_counter() - t0
        e = 0.5 * vs["v(n)"] ** 2 + 0.5 * vs["i(L1)"] ** 2
        drift = float(np.max(np.abs(e - e[0])) / e[0])
        rows.append(
            Row(
                NAME,
                f"LC tank {steps:.0e} steps: max relative energy drift, diracvi midpoint "
                f"÷ ngspice {method}",
                drift_dv,
                drift,
                drift_dv / drift if drift > 0 else None,
                unit="",
                solver=result.trajectory.solver,
                notes=f"wall: diracvi {t_dv:.2f} s (incl. compile), ngspice {t_ng:.2f} s; "
                f"diracvi: half-step energy (its node-sampled v, i energy oscillates by "
                f"{wobble_dv:.1e}); ngspice: node energy, default tolerances, tmax = h",
            )
        )
    return rows


def run(settings: Settings) -> Result:
    if not available():
        return Result(
            [Row(NAME, "netlists vs ngspice", None, None, None, status="not run",
                 notes="ngspice is not installed (apt-get install ngspice)")],
            {"ngspice": False},
        )  # fmt: skip
    names = ("rc", "rlc", "bridge") if settings.quick else tuple(CIRCUITS)
    rows = [_matched(n, settings) for n in names]
    # the bridge rectifier as a user runs it (issue 30: ≤ 1× ngspice at matched accuracy)
    rows += [_matched_variable(n, settings) for n in VARIABLE if n in names]
    rows += _energy_drift(10_000 if settings.quick else 1_000_000)
    rows += ladder_scaling.rows(settings)  # RLC ladders of 10²… stages, end to end
    if any(r.status for r in rows if r.diracvi is None):
        raise BenchmarkError("a circuit row could not be measured")
    return Result(rows, {"circuits": list(names)})
