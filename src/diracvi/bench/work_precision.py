r"""Work–precision on the double pendulum: error against run time for the three rules and DOP853.

The (reduced, hand-built) double pendulum ``problems.double_pendulum_torn().reduced`` is
run to ``T = HORIZON`` by ``dv.simulate`` with ``"retraction"`` (order 1), ``"midpoint"``
(order 2) and ``"lobatto"`` (order 4) at a few step sizes each, and by
``scipy.integrate.solve_ivp`` (DOP853) at a grid of tolerances. Error: ``max(|Δθ₁|,
|Δθ₂|)`` at ``t = T`` against DOP853 at rtol = atol = 1e-13 (the textbook ODE written out
in :func:`diracvi.bench.pendulum.reduced_rhs`, not diracvi's model). Time: the minimum of
interleaved warm calls (:func:`~diracvi.bench._core.interleaved`).

One row per rule: its most accurate point against DOP853 at the loosest tolerance on
the grid that is at least as accurate (DOP853 ÷ diracvi time). The curves are in the
details (and drawn by the gallery example ``work_precision.py``).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

import diracvi as dv

from .. import problems
from ._core import BenchmarkError, Result, Row, Settings, interleaved
from .pendulum import reduced_rhs

NAME = "work-precision"
DESCRIPTION = "double pendulum: error vs run time, retraction / midpoint / lobatto / DOP853"

HORIZON = {False: 10.0, True: 1.0}
#: step sizes per rule (the quick run takes the first of each)
STEPS = {
    "retraction": (0.005, 0.0025, 0.00125),
    "midpoint": (0.02, 0.01, 0.005),
    "lobatto": (0.05, 0.025, 0.0125),
}
RTOLS = tuple(10.0 ** (-k) for k in range(4, 13))
REFERENCE_RTOL = 1e-13


def curves(quick: bool = False, repeats: int = 3, points: int | None = None) -> dict:
    """``{"horizon", "reference", rule: [(h, error, seconds)], "dop853": [(rtol, error,
    seconds)]}``: the work–precision points (seconds: min of ``repeats`` warm calls);
    ``points`` step sizes per rule (default: 1 when ``quick``, else all)."""
    points = (1 if quick else len(STEPS["lobatto"])) if points is None else points
    horizon = HORIZON[quick]
    problem = problems.get("double-pendulum-torn")
    reduced, prm = problem.reduced, problem.parameters
    rhs = reduced_rhs(prm["m1"], prm["m2"], prm["l1"], prm["l2"], prm["g"])
    y0 = np.array([*prm["theta0"], *prm["omega0"]], dtype=np.float64)

    def dop853(rtol):
        sol = solve_ivp(rhs, (0.0, horizon), y0, method="DOP853", rtol=rtol, atol=rtol)
        if sol.status != 0:
            raise BenchmarkError(f"DOP853 at rtol={rtol:.0e} failed: {sol.message}")
        return sol.y[:2, -1]

    reference = dop853(REFERENCE_RTOL)
    out: dict = {"horizon": horizon, "reference_rtol": REFERENCE_RTOL}
    calls = {}
    for rule, hs in STEPS.items():
        for h in hs[:points]:

            def call(h=h, rule=rule):
                return dv.simulate(
                    reduced.system,
                    reduced.q0,
                    reduced.p0,
                    dt=h,
                    steps=round(horizon / h),
                    discretization=rule,
                    save_states=False,
                ).final_state[0]

            calls[(rule, h)] = call
    for rtol in RTOLS[::2] if quick else RTOLS:
        calls[("dop853", rtol)] = lambda rtol=rtol: dop853(rtol)
    names = {f"{kind}@{value:g}": (kind, value) for kind, value in calls}
    times = interleaved({name: calls[key] for name, key in names.items()}, repeats)
    for name, (kind, value) in names.items():
        error = float(np.max(np.abs(np.asarray(calls[(kind, value)]()) - reference)))
        out.setdefault(kind, []).append((value, error, float(times[name].min())))
    return out


def _matched(dop: list, error: float):
    """The loosest DOP853 point at least as accurate as ``error`` (or None)."""
    good = [p for p in dop if p[1] <= error]
    return max(good, key=lambda p: p[0]) if good else None


def run(settings: Settings) -> Result:
    data = curves(settings.quick, repeats=3 if settings.quick else 10)
    rows = []
    for rule in STEPS:
        h, error, seconds = min(data[rule], key=lambda p: p[1])
        match = _matched(data["dop853"], error)
        rows.append(
            Row(
                NAME,
                f"double pendulum T = {data['horizon']:g}, {rule} h = {h:g} (error "
                f"{error:.1e}): DOP853 ÷ diracvi at matched error",
                seconds,
                None if match is None else match[2],
                None if match is None else match[2] / seconds,
                notes="no DOP853 tolerance on the grid is as loose"
                if match is None
                else f"DOP853 rtol = atol = {match[0]:.0e} (error {match[1]:.1e})",
            )
        )
    return Result(rows, data)
