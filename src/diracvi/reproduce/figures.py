"""The paper's seven §5 figures, remade from our runs, plus three it lacks.

Matplotlib's object API with the Agg canvas: no display and no global backend switch.
Style follows the captions: the monolithic model as lines, the interconnected one as
hollow markers (every few steps, so the line underneath stays visible).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from . import metrics
from .experiments import ExampleResult, sample_steps

#: file name → (what it shows, which paper figure it remakes or None)
FIGURES = {
    "spring_positions.png": ("Spring positions, monolithic vs interconnected", "Fig. 3"),
    "spring_energy.png": ("Spring system energy, monolithic vs interconnected", "Fig. 4"),
    "spring_constraint_deviation.png": ("Deviation q2 − q̄2 of the interconnection", "Fig. 5"),
    "spring_long_energy.png": ("Interconnected energy over the long run", "Fig. 6"),
    "rlc_capacitor_charge.png": ("Capacitor charge, monolithic vs interconnected", "Fig. 9"),
    "rlc_energy.png": ("Circuit energy, monolithic vs interconnected", "Fig. 10"),
    "rlc_constraint_deviation.png": ("Deviation qS1 − qS2 of the interconnection", "Fig. 11"),
    "spring_discretizations.png": ("Energy error: retraction (paper) vs midpoint", None),
    "rlc_discretizations.png": ("Capacitor charge vs exact: retraction vs midpoint", None),
    "rlc_resistor_sign.png": ("RLC energy: physical vs the paper's printed resistor sign", None),
    "convergence_orders.png": (
        "Forced oscillator: error vs steps per period, order 2 and order 4",
        "arXiv:1703.03045, convergence table",
    ),
}

_MARKERS = ("o", "s", "^", "D", "v", "P")


def _figure(rows: int = 1, height: float = 4.0):
    fig = Figure(figsize=(7.5, height * rows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    return fig, axes


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=110)
    return path


def _every(n: int) -> int:
    return max(n // 40, 1)


def _colors(result: ExampleResult) -> dict[str, str]:
    """One colour per reduced coordinate; a port variable takes its partner's colour."""
    reduced = result.reduced.coords
    color = {r: f"C{i}" for i, r in enumerate(reduced)}
    for torn, red in result.shared.items():
        color[torn] = color[red]
    for a, b in result.ports:
        if a in color and b not in color:
            color[b] = color[a]
        elif b in color and a not in color:
            color[a] = color[b]
    return color


def positions(result: ExampleResult, coords=None, ylabel="position q"):
    """Reduced model as lines, interconnected model as hollow markers (caption of Fig. 3)."""
    red, inter = result.reduced, result.interconnected
    color = _colors(result)
    fig, (ax,) = _figure()
    shown_red = coords or red.coords
    for r in shown_red:
        ax.plot(red.t, red[r], "-", color=color[r], lw=1.3, label=f"{r} (monolithic)")
    torn_coords = (
        [result.torn_name(r) for r in coords] if coords is not None else list(inter.coords)
    )
    every = _every(inter.steps)
    for i, c in enumerate(torn_coords):
        ax.plot(
            inter.t,
            inter[c],
            _MARKERS[i % len(_MARKERS)],
            color=color.get(c, "k"),
            mfc="none",
            ms=6,
            markevery=(i * every // len(torn_coords), every),
            label=f"{c} (interconnected)",
        )
    ax.set_xlabel("time t")
    ax.set_ylabel(ylabel)
    ax.legend(ncols=2, fontsize=8)
    ax.grid(alpha=0.3)
    return fig, ax


def _energy_axes(result: ExampleResult, title: str):
    red, inter = result.reduced, result.interconnected
    fig, (ax,) = _figure()
    ax.plot(red.t[:-1], red.energy, "-", lw=1.3, label="variational (monolithic, hand-built)")
    ax.plot(
        inter.t[:-1],
        inter.energy,
        "o",
        mfc="none",
        ms=6,
        markevery=_every(inter.steps),
        label="interconnected",
    )
    ax.set_xlabel("time t")
    ax.set_ylabel("energy E(q_k, v_k)")
    ax.set_title(title)
    ax.legend()
    ax.grid(alpha=0.3)
    return fig, ax


def _deviation(result: ExampleResult, path: Path, title: str) -> Path:
    """Position-level port deviation and the discrete interaction residual α_{d+}."""
    from .experiments import interaction_names

    inter = result.interconnected
    fig, (top, bottom) = _figure(rows=2, height=3.0)
    for name, dev in metrics.port_deviation(inter, result.ports).items():
        top.plot(inter.t, dev, "-", label=f"{name}  (max |·| = {metrics.max_abs(dev):.1e})")
    top.set_ylabel("position deviation")
    top.set_title(title)
    top.legend(fontsize=8)
    top.grid(alpha=0.3)
    names = interaction_names(result.problem.system)
    rows = metrics.constraint_rows(inter, names)
    for j, name in enumerate(names):
        bottom.plot(
            inter.t[:-1],
            rows[:, j],
            "-",
            label=f"α_d+ [{name}]  (max |·| = {metrics.max_abs(rows[:, j]):.1e})",
        )
    bottom.set_xlabel("time t")
    bottom.set_ylabel("discrete constraint α_d+")
    bottom.legend(fontsize=8)
    bottom.grid(alpha=0.3)
    return _save(fig, path)


def envelope(t, values, windows: int = 400):
    """``(t_mid, low, high)`` of ``values`` over about ``windows`` equal windows of steps."""
    t, values = np.asarray(t), np.asarray(values)
    size = max(len(values) // windows, 1)
    count = len(values) // size
    blocks = values[: count * size].reshape(count, size)
    mids = t[: count * size].reshape(count, size).mean(axis=1)
    return mids, blocks.min(axis=1), blocks.max(axis=1)


def _long_energy(long, path: Path) -> Path:
    """The long run's energy as an envelope (min/max per window) over the whole run, and a
    zoom on its last few oscillations: a plain line of 10^5 oscillating points is a band."""
    fig = Figure(figsize=(7.5, 6.4), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1)  # not sharing x: the lower panel is a zoom
    t, energy = long.t[:-1], long.energy
    mids, low, high = envelope(t, energy)
    top.fill_between(
        mids,
        low,
        high,
        color="C0",
        alpha=0.35,
        lw=0,
        label=f"min–max per window ({len(mids)} windows)",
    )
    top.plot(mids, 0.5 * (low + high), "-", color="C0", lw=1.0, label="window midpoint")
    top.set_ylabel("energy E(q_k, v_k)")
    # short enough for the full run's 100,000 steps at this width (a longer title is cut)
    top.set_title(f"Spring chain, interconnected: {long.steps:,} steps, h = {long.dt}")
    # headroom above the band for the legend, which would otherwise cover the data
    span = float(high.max() - low.min()) or 1.0
    top.set_ylim(float(low.min()) - 0.05 * span, float(high.max()) + 0.35 * span)
    top.legend(fontsize=8, loc="upper left", ncol=2)
    top.grid(alpha=0.3)
    zoom = slice(max(len(energy) - 1000, 0), len(energy))
    bottom.plot(t[zoom], energy[zoom], "-", color="C0", lw=1.0)
    bottom.set_xlim(t[zoom][0], t[zoom][-1])
    bottom.set_xlabel("time t")
    bottom.set_ylabel("energy (last 1,000 steps)")
    bottom.grid(alpha=0.3)
    return _save(fig, path)


def spring_figures(result: ExampleResult, out: Path) -> list[Path]:
    paths = []
    fig, ax = positions(result)
    ax.set_title("Spring chain: monolithic (lines) vs interconnected (hollow markers)")
    paths.append(_save(fig, out / "spring_positions.png"))
    fig, ax = _energy_axes(result, "Spring chain energy: monolithic vs interconnected")
    ax.ticklabel_format(axis="y", useOffset=True)
    paths.append(_save(fig, out / "spring_energy.png"))
    paths.append(
        _deviation(result, out / "spring_constraint_deviation.png", "Spring chain: q2 − q̄2")
    )
    paths.append(_long_energy(result.long_run, out / "spring_long_energy.png"))
    paths.append(_rules_energy(result, out / "spring_discretizations.png"))
    return paths


def _rules_energy(result: ExampleResult, path: Path) -> Path:
    """Energy error of both rules (top) and of the midpoint rule alone (bottom: its error
    is ~h² and would be a flat line on the retraction rule's ~h scale)."""
    fig, (top, bottom) = _figure(rows=2, height=3.2)
    orders = result.summary["discretizations"]
    for i, rule in enumerate(result.rules):
        t, err = result.energy_errors[rule]
        label = f"{rule} (fitted order {orders[rule]['fitted_order']:.2f})"
        top.plot(t, err, "-", color=f"C{i}", lw=1.0, label=label)
        if rule == "midpoint":
            bottom.plot(t, err, "-", color=f"C{i}", lw=1.0, label=label)
    top.set_title(f"Spring chain (interconnected), h = {result.problem.dt}: energy error")
    bottom.set_xlabel("time t")
    for ax in (top, bottom):
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel("E(q_k, v_k) − E_exact")
        ax.legend()
        ax.grid(alpha=0.3)
    return _save(fig, path)


def rlc_figures(result: ExampleResult, out: Path) -> list[Path]:
    paths = []
    head = result.example.headline
    fig, ax = positions(result, coords=[head], ylabel=f"capacitor charge {head}")
    ax.set_title("RLC circuit: capacitor charge, monolithic (line) vs interconnected (markers)")
    paths.append(_save(fig, out / "rlc_capacitor_charge.png"))
    fig, _ = _energy_axes(result, "RLC circuit energy: monolithic vs interconnected")
    paths.append(_save(fig, out / "rlc_energy.png"))
    paths.append(_deviation(result, out / "rlc_constraint_deviation.png", "RLC circuit: qS1 − qS2"))
    paths.append(_rules_charge(result, out / "rlc_discretizations.png"))
    paths.append(_resistor_sign(result, out / "rlc_resistor_sign.png"))
    return paths


def _rules_charge(result: ExampleResult, path: Path) -> Path:
    head = result.example.headline
    reduced_coords = result.reduced.coords
    fig, (top, bottom) = _figure(rows=2, height=3.2)
    t, exact = result.exact_samples
    exact = exact[:, reduced_coords.index(head)]
    k = sample_steps(result.interconnected.steps)
    top.plot(t, exact, "k-", lw=1.0, label="exact")
    orders = result.summary["discretizations"]
    for rule, traj in result.rules.items():
        name = result.torn_name(head) if head not in traj.coords else head
        top.plot(traj.t, traj[name], "--", lw=1.0, label=rule)
        bottom.plot(
            t,
            traj[name][k] - exact,
            "-",
            lw=1.0,
            label=f"{rule} (fitted order {orders[rule]['fitted_order']:.2f})",
        )
    top.set_ylabel(f"capacitor charge {head}")
    top.set_title(f"RLC circuit, h = {result.problem.dt}: retraction (paper) vs midpoint")
    top.legend()
    top.grid(alpha=0.3)
    bottom.set_xlabel("time t")
    bottom.set_ylabel("error vs exact")
    bottom.legend()
    bottom.grid(alpha=0.3)
    return _save(fig, path)


def _resistor_sign(result: ExampleResult, path: Path) -> Path:
    fig, (ax,) = _figure()
    physical, printed = result.sign["physical"], result.sign["paper"]
    ax.semilogy(physical.t[:-1], physical.energy, "-", label="physical sign: f_d⁻ = +hF")
    ax.semilogy(printed.t[:-1], printed.energy, "-", label="paper's printed sign: f_d⁻ = −hF")
    ax.set_xlabel("time t")
    ax.set_ylabel("energy E(q_k, v_k)  (log scale)")
    ax.set_title("RLC circuit energy: physical vs the paper's printed resistor sign")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    return _save(fig, path)


def render_all(results: dict[str, ExampleResult], out: Path) -> list[Path]:
    """Write every figure of :data:`FIGURES` into ``out``; returns their paths."""
    return spring_figures(results["spring_chain"], out) + rlc_figures(results["rlc"], out)
