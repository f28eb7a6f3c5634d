"""A quick look at one trajectory: positions, energy and constraint residuals.

Used by ``diracvi plot`` and ``diracvi run --plot``. Matplotlib's object API with the Agg
canvas: no display is needed and the caller's pyplot backend is left alone.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .driver.trajectory import Trajectory

#: more coordinates than this and the legend is left out (it would cover the plot)
LEGEND_LIMIT = 12


def plot_trajectory(
    traj: Trajectory, path, title: str | None = None, name: str | None = None
) -> Path:
    """Write a three-panel PNG of ``traj`` to ``path``: q(t), E_k, |ω_d(k)| (log scale).

    The heading is ``title`` if given, else ``NAME: steps, h, rule, scheme`` where NAME is
    ``name`` (e.g. the problem or model file name) or the trajectory's system name.
    """
    path = Path(path)
    fig = Figure(figsize=(8.0, 9.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_q, ax_e, ax_c = fig.subplots(3, 1, sharex=True)
    heading = title or (
        f"{name or traj.system_name}: {traj.steps} steps, h = {traj.dt:g}, "
        f"{traj.discretization}, scheme {traj.scheme}"
    )
    if not traj.success:
        heading += f"\n(stopped early: {traj.message.splitlines()[0][:90]})"
    ax_q.set_title(heading, fontsize=10)

    for j, name in enumerate(traj.coords):
        ax_q.plot(traj.t, traj.q[:, j], lw=1.0, label=name)
    ax_q.set_ylabel("position q")
    if traj.q.shape[1] <= LEGEND_LIMIT:
        ax_q.legend(fontsize=8, ncols=2)

    t_step = traj.t[:-1]
    ax_e.plot(t_step, traj.energy, lw=1.0)
    ax_e.set_ylabel("energy E(q_k, v_k)")

    residual = np.abs(traj.constraint_residual)
    if residual.shape[1] == 0:
        ax_c.text(0.5, 0.5, "no constraints", ha="center", va="center", transform=ax_c.transAxes)
    elif not np.any(residual > 0):
        ax_c.text(
            0.5,
            0.5,
            "every constraint residual is exactly 0",
            ha="center",
            va="center",
            transform=ax_c.transAxes,
        )
    else:
        for j, name in enumerate(traj.constraint_names):
            # exact zeros cannot be drawn on a log axis; they are below the plotted floor
            # (the legend says so of a constraint that is 0 throughout: it has no line)
            label = name if np.any(residual[:, j] > 0) else f"{name} (exactly 0)"
            ax_c.semilogy(
                t_step, np.where(residual[:, j] > 0, residual[:, j], np.nan), lw=1.0, label=label
            )
        if residual.shape[1] <= LEGEND_LIMIT:
            ax_c.legend(fontsize=8, ncols=2)
    ax_c.set_ylabel("|discrete constraint|")
    ax_c.set_xlabel("time t")
    for ax in (ax_q, ax_e, ax_c):
        ax.grid(alpha=0.3)
    fig.savefig(path, dpi=100)
    return path


def plot_waveforms(t, waves: dict, path, title: str = "") -> Path:
    """Write a PNG of circuit waveforms: node voltages ``v(…)`` above, currents ``i(…)``
    below (``diracvi run circuit.cir --plot``)."""
    path = Path(path)
    fig = Figure(figsize=(8.0, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax_v, ax_i = fig.subplots(2, 1, sharex=True)
    for ax, prefix, unit in ((ax_v, "v(", "V"), (ax_i, "i(", "A")):
        names = [k for k in waves if k.startswith(prefix)]
        for key in names:
            ax.plot(t, waves[key], label=key, lw=1.2)
        ax.set_ylabel(unit)
        if 0 < len(names) <= LEGEND_LIMIT:
            ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
    ax_v.set_title(title, fontsize=10)
    ax_i.set_xlabel("time")
    fig.savefig(path, dpi=110)
    return path


def plot_joints(t, joints: dict, kinds: dict, path, title: str = "") -> Path:
    """Write a PNG of a robot's joint coordinates against time: revolute angles (rad)
    above, prismatic and cylindrical slides (m) below (``diracvi run robot.urdf --plot``)."""
    path = Path(path)
    panels = [
        (label, [j for j in joints if (kinds[j] == "revolute") == turn])
        for label, turn in (("joint angle (rad)", True), ("joint slide (m)", False))
    ]
    panels = [(label, names) for label, names in panels if names] or [("joint", [])]
    fig = Figure(figsize=(8.0, 3.2 * len(panels)), layout="constrained")
    FigureCanvasAgg(fig)
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    for ax, (label, names) in zip(axes, panels, strict=True):
        for name in names:
            ax.plot(t, joints[name], label=name, lw=1.2)
        if not names:
            ax.text(
                0.5,
                0.5,
                "no joint with a coordinate",
                ha="center",
                va="center",
                transform=ax.transAxes,
            )
        elif len(names) <= LEGEND_LIMIT:
            ax.legend(fontsize=8, ncols=2)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_title(title, fontsize=10)
    axes[-1].set_xlabel("time (s)")
    fig.savefig(path, dpi=110)
    return path
