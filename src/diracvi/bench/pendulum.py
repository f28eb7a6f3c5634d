r"""Torn double pendulum, 10⁵ steps: cost and energy error against DOP853 at matched accuracy.

diracvi: ``problems.double_pendulum_torn()`` with the midpoint rule (order 2) at the
problem's step h = 0.01, 10⁵ steps (T = 1000; 500 steps with ``--quick``), states saved
every ``SAVE_EVERY`` steps. Its accuracy is the maximum over the saved times of
``|θ₁ − θ₁^ref|`` and ``|θ₂ − θ₂^ref|``.

Reference: ``scipy.integrate.solve_ivp`` (DOP853, rtol = atol = 1e-13) on the reduced
ODE in ``(θ₁, θ₂, ω₁, ω₂)``, written out by hand below (the textbook double pendulum;
not diracvi's model), evaluated on the same saved times through DOP853's dense output.
Its own error is estimated by a second solve at rtol = atol = 2.5e-14; the comparison is
only made if that estimate is below 1 % of diracvi's error (else
:class:`BenchmarkError`). A perturbation of θ₁ by 1e-9 is also integrated: its growth
over the horizon tells whether the motion is chaotic (exponential growth) or regular.

Matched accuracy: DOP853 (atol = rtol) on a grid of tolerances, two per decade from
1e-12 to 1e-3, tightest first; the match is the loosest tolerance such that it and every
tighter one on the grid have a maximum position error over the horizon not above
diracvi's. (Bisection would do over short horizons; over T = 1000 the error is not
monotone in rtol, and bisection lands on a lucky tolerance.) The two are then timed
interleaved, DOP853 producing output on the same saved times. Energy error of each:
``max |E − E₀| / |E₀|`` over its output, with ``E₀ = E(θ₀, ω₀)`` of the reduced model
(diracvi reports ``E`` at each step's midpoint node, ``Trajectory.energy``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

import diracvi as dv

from .. import problems
from ._core import BenchmarkError, Result, Row, Settings, interleaved
from ._core import summary as time_summary

NAME = "pendulum"
DESCRIPTION = "torn double pendulum, 10⁵ midpoint steps vs DOP853 at matched accuracy"

STEPS = {False: 100_000, True: 500}
SAVE_EVERY = {False: 10, True: 1}
REFERENCE_RTOL = 1e-13
CROSS_CHECK_RTOL = 2.5e-14
#: DOP853 tolerances tried for the match, tightest first: two per decade, 1e-12 … 1e-3
RTOL_GRID = tuple(10.0 ** (-12 + k / 2) for k in range(19))
PERTURBATION = 1e-9
#: the reference's error estimate must be below this fraction of diracvi's error
REFERENCE_MARGIN = 0.01


def reduced_rhs(m1, m2, l1, l2, g):
    """``f(t, y)`` of the double pendulum, ``y = (θ₁, θ₂, ω₁, ω₂)``: ``M(θ) ω̇ = b``."""

    def rhs(t, y):
        t1, t2, w1, w2 = y
        c, s = math.cos(t1 - t2), math.sin(t1 - t2)
        a11, a12, a22 = (m1 + m2) * l1 * l1, m2 * l1 * l2 * c, m2 * l2 * l2
        b1 = -m2 * l1 * l2 * s * w2 * w2 - (m1 + m2) * g * l1 * math.sin(t1)
        b2 = m2 * l1 * l2 * s * w1 * w1 - m2 * g * l2 * math.sin(t2)
        det = a11 * a22 - a12 * a12
        return [w1, w2, (a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det]

    return rhs


def reduced_energy(y, m1, m2, l1, l2, g):
    """``E = T + V`` of the double pendulum for ``y = (θ₁, θ₂, ω₁, ω₂)`` (rows)."""
    t1, t2, w1, w2 = y
    kinetic = (
        0.5 * (m1 + m2) * l1**2 * w1**2
        + 0.5 * m2 * l2**2 * w2**2
        + m2 * l1 * l2 * np.cos(t1 - t2) * w1 * w2
    )
    return kinetic - (m1 + m2) * g * l1 * np.cos(t1) - m2 * g * l2 * np.cos(t2)


def run(settings: Settings) -> Result:
    steps, every = STEPS[settings.quick], SAVE_EVERY[settings.quick]
    problem = problems.double_pendulum_torn(steps=steps)
    prm = problem.parameters
    consts = (prm["m1"], prm["m2"], prm["l1"], prm["l2"], prm["g"])
    rhs = reduced_rhs(*consts)
    y0 = np.array([*prm["theta0"], *prm["omega0"]], dtype=np.float64)
    e0 = float(reduced_energy(y0, *consts))

    def diracvi_run():
        return dv.simulate(
            problem.system,
            problem.q0,
            problem.p0,
            dt=problem.dt,
            steps=steps,
            discretization="midpoint",
            save_every=every,
        )

    traj = diracvi_run()
    grid = np.asarray(traj.t)
    horizon = (0.0, float(grid[-1]))

    def dop853(rtol, start=y0):
        sol = solve_ivp(rhs, horizon, start, method="DOP853", rtol=rtol, atol=rtol, t_eval=grid)
        if sol.status != 0:
            raise BenchmarkError(f"DOP853 at rtol={rtol:.1e} failed: {sol.message}")
        return sol.y

    theta = np.stack([traj["upper.theta1"], traj["lower.theta2"]])
    ref = dop853(REFERENCE_RTOL)
    ref_error = float(np.max(np.abs(dop853(CROSS_CHECK_RTOL)[:2] - ref[:2])))
    perturbed = dop853(REFERENCE_RTOL, y0 + np.array([PERTURBATION, 0.0, 0.0, 0.0]))
    growth = float(np.max(np.abs(perturbed[:2] - ref[:2]))) / PERTURBATION
    dv_error = float(np.max(np.abs(theta - ref[:2])))
    if ref_error > REFERENCE_MARGIN * dv_error:
        raise BenchmarkError(
            f"the DOP853 reference is uncertain by {ref_error:.1e} over t ≤ {horizon[1]:g}, "
            f"not small against diracvi's error {dv_error:.1e} (a 1e-9 perturbation grows "
            f"×{growth:.3g}: chaotic?); shorten the horizon."
        )

    # Over a long horizon DOP853's error is not monotone in rtol (phase errors of order
    # 0.1 rad: a tighter tolerance can land farther off), so bisection would pick a lucky
    # tolerance. Instead: a grid, and the loosest tolerance such that it and every tighter
    # one on the grid are at least as accurate as diracvi.
    tried, rtol = {}, None
    for rt in RTOL_GRID:
        tried[rt] = float(np.max(np.abs(dop853(rt)[:2] - ref[:2])))
        if tried[rt] > dv_error:
            break
        rtol = rt
    if rtol is None:
        raise BenchmarkError(
            f"DOP853 at rtol={RTOL_GRID[0]:.0e} is less accurate ({tried[RTOL_GRID[0]]:.1e}) "
            f"than diracvi ({dv_error:.1e}): no tolerance on the grid matches."
        )
    matched = dop853(rtol)
    dop_error = float(np.max(np.abs(matched[:2] - ref[:2])))

    times = interleaved(
        {"diracvi": diracvi_run, "dop853": lambda: dop853(rtol)}, settings.long_repeats
    )
    t_dv, t_dop = float(times["diracvi"].min()), float(times["dop853"].min())
    dv_drift = np.abs(np.asarray(traj.energy) - e0) / abs(e0)
    dop_drift = np.abs(reduced_energy(matched, *consts) - e0) / abs(e0)
    dv_energy, dop_energy = float(dv_drift.max()), float(dop_drift.max())
    # growth (drift) or not: the largest error in the first and in the last tenth
    tenths = {
        name: (float(e[: e.size // 10].max()), float(e[-(e.size // 10) :].max()))
        for name, e in (("diracvi", dv_drift), ("dop853", dop_drift))
    }
    kind = "chaotic" if growth > 1e6 else "regular"
    span = f"{steps:,} steps, T = {horizon[1]:g}"
    rows = [
        Row(
            NAME,
            f"double pendulum (torn, midpoint), {span}: DOP853 ÷ diracvi at matched max "
            f"|Δθ| ({dv_error:.1e} vs {dop_error:.1e})",
            t_dv,
            t_dop,
            t_dop / t_dv,
            solver=traj.solver,
            notes=f"DOP853 rtol = atol = {rtol:.1e}; reference error ≤ {ref_error:.0e}; "
            f"1e-9 perturbation grows ×{growth:.3g} ({kind}); min of {settings.long_repeats}",
        ),
        Row(
            NAME,
            f"double pendulum, {span}: max |E − E₀|/|E₀|, DOP853 ÷ diracvi",
            dv_energy,
            dop_energy,
            dop_energy / dv_energy,
            solver=traj.solver,
            unit="",
            notes="max in the first → last tenth of the horizon: diracvi "
            f"{tenths['diracvi'][0]:.1e} → {tenths['diracvi'][1]:.1e}, DOP853 "
            f"{tenths['dop853'][0]:.1e} → {tenths['dop853'][1]:.1e}",
        ),
    ]
    details = {
        "steps": steps,
        "dt": problem.dt,
        "save_every": every,
        "horizon": horizon[1],
        "diracvi_position_error": dv_error,
        "reference_error_estimate": ref_error,
        "perturbation_growth": growth,
        "motion": kind,
        "dop853_rtol": rtol,
        "dop853_position_error": dop_error,
        "dop853_errors": {f"{rt:.1e}": e for rt, e in tried.items()},
        "energy_error": {"diracvi": dv_energy, "dop853": dop_energy},
        "energy_error_first_last_tenth": tenths,
        "times": {name: time_summary(t) for name, t in times.items()},
        "solver": traj.solver,
    }
    return Result(rows, details)
