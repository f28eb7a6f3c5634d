r"""The convergence table of Parks & Leok's follow-up paper, for order 2 and order 4.

*Constructing equivalence-preserving Dirac variational integrators with forces*
(Parks & Leok, arXiv:1703.03045) shows, for a forced oscillator, the error at the end of
a run against the number of steps per period (20, 40, 80, 160) with the ratio of
consecutive errors: ≈ 4 for a second-order and ≈ 16 for a fourth-order integrator. This
module produces the same *form* of table with diracvi's ``"midpoint"`` (order 2) and
``"lobatto"`` (order 4) rules on :func:`~diracvi.problems.forced_oscillator`
(``m ẍ + c ẋ + k x = F₀ cos ωt``, closed-form solution), periods of the forcing
``2π/ω``.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .. import problems
from ..driver.simulate import simulate

CITATION = (
    "Parks & Leok, *Constructing equivalence-preserving Dirac variational integrators "
    "with forces*, arXiv:1703.03045"
)
STEPS_PER_PERIOD = (20, 40, 80, 160)
RULES = {"midpoint": 2, "lobatto": 4}
PERIODS = 4
FIGURE = "convergence_orders.png"


def convergence_table(steps_per_period=STEPS_PER_PERIOD, periods: int = PERIODS) -> dict:
    """``{rule: {"order", "steps_per_period", "error", "ratio", "observed_order"}}``: the
    absolute position error at ``t = periods · 2π/ω`` against the closed form."""
    problem = problems.get("forced-oscillator")
    period = 2.0 * np.pi / problem.parameters["omega"]
    horizon = periods * period
    exact = float(problem.exact(np.array([problem.t0 + horizon]))[0, 0])
    table = {"problem": problem.name, "periods": periods, "horizon": horizon}
    for rule, order in RULES.items():
        errors = []
        for count in steps_per_period:
            traj = simulate(
                problem.system,
                problem.q0,
                problem.p0,
                dt=period / count,
                steps=periods * count,
                t0=problem.t0,
                discretization=rule,
                save_states=False,
            )
            errors.append(abs(float(traj.final_state[0][0]) - exact))
        ratios = [None] + [a / b for a, b in itertools.pairwise(errors)]
        slope = -np.polyfit(np.log(steps_per_period), np.log(errors), 1)[0]
        table[rule] = {
            "order": order,
            "steps_per_period": list(steps_per_period),
            "error": errors,
            "ratio": ratios,
            "observed_order": float(slope),
        }
    return table


def render(table: dict, out: Path) -> Path:
    """Error against steps per period, log–log, with the slopes −2 and −4 for reference."""
    fig = Figure(figsize=(7.5, 4.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    for rule, marker in zip(RULES, ("o", "s"), strict=True):
        row = table[rule]
        n = np.asarray(row["steps_per_period"], dtype=float)
        ax.loglog(n, row["error"], marker=marker, label=f"{rule} (order {row['order']})")
        # the guide starts a factor 3 below the first error so that it runs beside the
        # data instead of under it (a slope drawn through the data point hides behind it)
        guide = row["error"][0] / 3.0 * (n / n[0]) ** -row["order"]
        ax.loglog(n, guide, ls=":", lw=1.5, color="black")
    ax.set_xlabel("steps per period")
    ax.set_ylabel(f"|x − x_exact| after {table['periods']} periods")
    ax.set_title("Forced oscillator: order 2 and order 4 (dotted, black: slopes −2, −4)")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    path = out / FIGURE
    fig.savefig(path, dpi=110)
    return path


def add_to_report(doc, table: dict, out: Path, fmt) -> None:
    """The section of the report: the table in the follow-up paper's form and the figure."""
    doc.heading("Order 2 and order 4: the follow-up paper's convergence table", level=3)
    doc.paragraph(
        f"After {CITATION}: the forced oscillator `{table['problem']}` run for "
        f"{table['periods']} forcing periods; the error of x at the end of the run against "
        "the closed form, and the ratio to the error at half as many steps per period "
        "(≈ 4 for order 2, ≈ 16 for order 4)."
    )
    header = ["steps per period"]
    for rule in RULES:
        header += [f"{rule} error", f"{rule} ratio"]
    rows = []
    for j, count in enumerate(STEPS_PER_PERIOD[: len(table["midpoint"]["error"])]):
        row = [str(count)]
        for rule in RULES:
            ratio = table[rule]["ratio"][j]
            row += [fmt(table[rule]["error"][j]), "—" if ratio is None else f"{ratio:.2f}"]
        rows.append(row)
    rows.append(
        ["observed order"]
        + [x for rule in RULES for x in (f"{table[rule]['observed_order']:.2f}", "")]
    )
    doc.table(header, rows)
    doc.figure(out / FIGURE, "Error at the end of the run against steps per period.")
