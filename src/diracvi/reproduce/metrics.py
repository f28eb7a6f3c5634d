"""Numbers that compare trajectories: position differences, constraint deviations, energy.

Pure NumPy on :class:`~diracvi.Trajectory` arrays, so each number in ``summary.json``
has one definition, here.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from ..driver.trajectory import Trajectory


def max_abs(values) -> float:
    """``max |x|`` over every entry (0.0 for an empty array)."""
    arr = np.asarray(values, dtype=np.float64)
    return float(np.max(np.abs(arr), initial=0.0))


def position_difference(a: Trajectory, b: Trajectory, pairs: Mapping[str, str]) -> float:
    """``max_k max_(x, y) |q_k[x] − q_k[y]|`` over the coordinate pairs ``{a-name: b-name}``.

    The two trajectories must have taken the same number of steps with the same ``dt``
    (anything else would compare different instants).
    """
    if a.q.shape[0] != b.q.shape[0] or a.dt != b.dt:
        raise ValueError(
            f"cannot compare {a!r} with {b!r}: they differ in length or step; compare "
            "runs with the same dt and steps."
        )
    return max((max_abs(a[x] - b[y]) for x, y in pairs.items()), default=0.0)


def identity_pairs(coords: Iterable[str]) -> dict[str, str]:
    """``{c: c}``: compare every coordinate with its namesake."""
    return {c: c for c in coords}


def port_deviation(traj: Trajectory, ports) -> dict[str, np.ndarray]:
    """``q[a] − q[b]`` over time for each port pair ``(a, b)`` the interconnection ties."""
    return {f"{a} − {b}": traj[a] - traj[b] for a, b in ports}


def constraint_rows(traj: Trajectory, names: Iterable[str]) -> np.ndarray:
    """The columns of ``traj.constraint_residual`` for the constraint rows ``names``."""
    index = [traj.constraint_names.index(n) for n in names]
    return traj.constraint_residual[:, index]


def energy_stats(energy) -> dict[str, float]:
    """Summary of an energy history ``E_k``.

    ``relative_oscillation`` is ``(max − min)/|E_0|``; ``relative_drift`` is the mean over
    the last tenth of the run minus the mean over the first tenth, divided by ``|E_0|``
    (a bounded oscillation gives ≈ 0 here, a drift does not); ``nonincreasing`` says
    whether no step gains more than round-off (``1e-12 |E_0|``).
    """
    e = np.asarray(energy, dtype=np.float64)
    e0 = float(e[0])
    scale = abs(e0) if e0 != 0.0 else 1.0
    tenth = max(e.size // 10, 1)
    return {
        "initial": e0,
        "final": float(e[-1]),
        "min": float(e.min()),
        "max": float(e.max()),
        "relative_oscillation": float((e.max() - e.min()) / scale),
        "relative_drift": float((e[-tenth:].mean() - e[:tenth].mean()) / scale),
        # a dissipative system must never gain energy (up to round-off)
        "nonincreasing": bool(np.all(np.diff(e) <= 1e-12 * scale)),
    }


def fitted_order(errors, steps) -> float:
    """Slope of ``log(error)`` against ``log(dt)``: the observed order of accuracy."""
    slope, _ = np.polyfit(np.log(np.asarray(steps)), np.log(np.asarray(errors)), 1)
    return float(slope)
