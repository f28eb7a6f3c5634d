r"""Work–precision: error against run time, diracvi's rules beside DOP853 on the reduced ODE.

Three constrained mechanisms, each as diracvi steps it and as a reduced ODE written out
by hand in NumPy (no diracvi) for ``scipy.integrate.solve_ivp``:

- **spherical pendulum** (``problems.spherical_pendulum``): Cartesian ``(x, y, z)`` with
  the holonomic rod; reduced ``(θ, θ̇, φ)`` with ``L_z`` conserved
  (:func:`diracvi.problems.spherical_pendulum.reduced_rhs`);
- **double pendulum** (``problems.double_pendulum_torn().reduced``): its two angles;
  reduced ``M(θ) ω̇ = b`` (:func:`diracvi.bench.pendulum.reduced_rhs`);
- **four-bar linkage** (``problems.four_bar``, a closed kinematic loop, driven): three link
  angles with two loop-closure rows; reduced: the crank angle's equation
  (:class:`diracvi.problems.FourBar`), the other angles from the closure.

Each is run to ``T = HORIZON`` by ``dv.simulate`` with ``"midpoint"`` (order 2) and
``"lobatto"`` (order 4) at a few step sizes (the double pendulum also with
``"retraction"``, order 1), and by DOP853 at a grid of tolerances. Error: the largest
coordinate error of the model's ``q(T)`` against DOP853 at rtol = atol = 1e-13. Time: the
minimum of interleaved warm calls (:func:`~diracvi.bench._core.interleaved`), every
point of one problem in the same rounds.

One row per problem and rule: its most accurate point against DOP853 at the loosest
tolerance on the grid that is at least as accurate (DOP853 ÷ diracvi time). The curves
are in the details (and drawn by the gallery example ``work_precision.py``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.integrate import solve_ivp

import diracvi as dv

from .. import problems
from ..problems.spherical_pendulum import positions
from ._core import BenchmarkError, Result, Row, Settings, interleaved
from .pendulum import reduced_rhs

NAME = "work-precision"
DESCRIPTION = (
    "spherical pendulum, double pendulum, four-bar: error vs run time, "
    "midpoint / lobatto / DOP853 on the reduced ODE"
)

HORIZON = {False: 10.0, True: 1.0}
RTOLS = tuple(10.0 ** (-k) for k in range(4, 13))
REFERENCE_RTOL = 1e-13


class Case(NamedTuple):
    """A problem as diracvi steps it and as its reduced ODE: ``to_q(y)`` maps a reduced
    state to the model's coordinates, the space in which errors are measured."""

    system: object
    q0: np.ndarray
    p0: np.ndarray
    rhs: object
    y0: np.ndarray
    to_q: object
    steps: dict  # rule → step sizes (the quick run takes the first of each)


def _spherical() -> Case:
    problem = problems.get("spherical-pendulum")
    prm = problem.parameters
    ell = prm["l"]
    return Case(
        problem.system,
        problem.q0,
        problem.p0,
        prm["reduced_rhs"],
        prm["reduced_y0"],
        lambda y: positions(ell, y),
        {"midpoint": (0.01, 0.005, 0.0025), "lobatto": (0.05, 0.025, 0.0125)},
    )


def _double() -> Case:
    problem = problems.get("double-pendulum-torn")
    reduced, prm = problem.reduced, problem.parameters
    rhs = reduced_rhs(prm["m1"], prm["m2"], prm["l1"], prm["l2"], prm["g"])
    y0 = np.array([*prm["theta0"], *prm["omega0"]], dtype=np.float64)
    return Case(
        reduced.system,
        reduced.q0,
        reduced.p0,
        rhs,
        y0,
        lambda y: np.asarray(y)[:2],
        {
            "retraction": (0.005, 0.0025, 0.00125),
            "midpoint": (0.02, 0.01, 0.005),
            "lobatto": (0.05, 0.025, 0.0125),
        },
    )


def _four_bar() -> Case:
    problem = problems.get("four-bar")
    prm = problem.parameters
    linkage = problems.FourBar(
        prm["a"], prm["b"], prm["c"], prm["d"], *prm["masses"], prm["g"], prm["tau0"], prm["Omega"]
    )
    q0 = problem.q0

    def to_q(y):
        angles = linkage.angles(float(np.asarray(y)[0]))
        # the branch nearest q0, as problems.four_bar's reference takes it
        angles[1:] = q0[1:] + np.angle(np.exp(1j * (angles[1:] - q0[1:])))
        return angles

    return Case(
        problem.system,
        q0,
        problem.p0,
        linkage.rhs,
        np.array([prm["theta0"], prm["omega0"]]),
        to_q,
        {"midpoint": (0.005, 0.0025, 0.00125), "lobatto": (0.02, 0.01, 0.005)},
    )


#: name → the case's builder
CASES = {
    "spherical pendulum": _spherical,
    "double pendulum": _double,
    "four-bar": _four_bar,
}


def curves(
    quick: bool = False, repeats: int = 3, points: int | None = None, cases=tuple(CASES)
) -> dict:
    """``{case: {"horizon", "reference_rtol", rule: [(h, error, seconds)], "dop853":
    [(rtol, error, seconds)]}}``: the work–precision points (seconds: min of ``repeats``
    warm calls, interleaved within a case); ``points`` step sizes per rule (default: 1 when
    ``quick``, else all)."""
    return {name: _case_curves(CASES[name](), quick, repeats, points) for name in cases}


def _case_curves(case: Case, quick: bool, repeats: int, points: int | None) -> dict:
    horizon = HORIZON[quick]

    def dop853(rtol):
        sol = solve_ivp(case.rhs, (0.0, horizon), case.y0, method="DOP853", rtol=rtol, atol=rtol)
        if sol.status != 0:
            raise BenchmarkError(f"DOP853 at rtol={rtol:.0e} failed: {sol.message}")
        return case.to_q(sol.y[:, -1])

    reference = dop853(REFERENCE_RTOL)
    out: dict = {"horizon": horizon, "reference_rtol": REFERENCE_RTOL}
    calls = {}
    for rule, hs in case.steps.items():
        count = (1 if quick else len(hs)) if points is None else points
        for h in hs[:count]:

            def call(h=h, rule=rule):
                return dv.simulate(
                    case.system,
                    case.q0,
                    case.p0,
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
    for name, curve in data.items():
        for rule in (k for k in curve if k not in ("horizon", "reference_rtol", "dop853")):
            h, error, seconds = min(curve[rule], key=lambda p: p[1])
            match = _matched(curve["dop853"], error)
            rows.append(
                Row(
                    NAME,
                    f"{name} T = {curve['horizon']:g}, {rule} h = {h:g} (error "
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


def table(data: dict) -> str:
    """The curves of :func:`curves` as one Markdown table (what ``docs/discretizations.md``
    shows): per problem, every point with its error and warm time."""
    lines = ["| problem | method | h or rtol | error at T | time (ms) |", "|---|---|---|---|---|"]
    for name, curve in data.items():
        for kind in (k for k in curve if k not in ("horizon", "reference_rtol")):
            for value, error, seconds in curve[kind]:
                label = f"{name}, T = {curve['horizon']:g}"
                lines.append(
                    f"| {label} | {kind} | {value:g} | {error:.1e} | {seconds * 1e3:.2f} |"
                )
    return "\n".join(lines)
