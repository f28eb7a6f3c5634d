"""Work–precision on three constrained mechanisms: error at T = 1 against run time for the
midpoint rule (order 2), the lobatto rule (order 4) and scipy's DOP853 on the reduced ODE
at a range of tolerances — a spherical pendulum (holonomic rod), a double pendulum and a
four-bar linkage (a closed kinematic loop, driven).

The points are those of the ``work-precision`` entry of ``diracvi bench`` (over its quick
horizon, two step sizes per rule); ``diracvi bench --only work-precision`` runs the full
curves over T = 10 and ``python benchmarks/work_precision.py`` prints them as a table.
Times are warm calls (compilation excluded), minimum of 3.

Run: python examples/work_precision.py [figure.png]
"""

# gallery: Work–precision: midpoint, lobatto and DOP853 on three mechanisms

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path
from matplotlib.ticker import LogLocator

from diracvi.bench.work_precision import CASES, curves

data = curves(quick=True, repeats=3, points=2)
# one colour and marker per method in every panel (the panels do not all have the same
# methods, so cycling the defaults would draw DOP853 green in one panel and red in another)
STYLE = {
    "retraction": {"marker": "o", "color": "tab:gray"},
    "midpoint": {"marker": "s", "color": "tab:blue"},
    "lobatto": {"marker": "D", "color": "tab:orange"},
    "dop853": {"marker": "^", "color": "tab:green"},
}
fig, axes = plt.subplots(1, len(CASES), figsize=(13, 4.2), layout="constrained")
for ax, (name, curve) in zip(axes, data.items(), strict=True):
    kinds = [k for k in curve if k not in ("horizon", "reference_rtol")]
    for kind in kinds:
        points = np.asarray(curve[kind])
        ax.loglog(points[:, 2], points[:, 1], label=kind, **STYLE[kind])
        for value, error, seconds in curve[kind]:
            print(f"{name:18s} {kind:10s} {value:9.3g}  error {error:.1e}  {seconds * 1e3:7.2f} ms")
    ax.set(
        xlabel="run time (s, warm)",
        ylabel=f"max |Δq| at T = {curve['horizon']:g} s (rad, m)",
        title=name,
    )
    # the run times span little more than a decade, so matplotlib labels the minor ticks:
    # at each of 2…9 × 10ⁿ the labels run into each other, at 2 and 5 × 10ⁿ they do not
    ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="lower left")  # "best" put it over the slowest points; this corner stays empty
fig.savefig(figure_path("work_precision.png"), dpi=110)
