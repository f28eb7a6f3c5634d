"""Work–precision on the double pendulum: error at T = 1 against run time for the three
discretizations (retraction, order 1; midpoint, order 2; lobatto, order 4) and scipy's
DOP853 at a range of tolerances.

The points are those of the ``work-precision`` entry of ``diracvi bench`` (over its quick
horizon, two step sizes per rule); ``diracvi bench --only work-precision`` runs the full
curves over T = 10. Times are warm calls (compilation excluded), minimum of 3.

Run: python examples/work_precision.py [figure.png]
"""

# gallery: Work–precision: three rules and DOP853

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path
from matplotlib.ticker import LogLocator

from diracvi.bench.work_precision import STEPS, curves

data = curves(quick=True, repeats=3, points=2)
fig, ax = plt.subplots(figsize=(6.5, 4.2), layout="constrained")
for rule, marker in zip([*STEPS, "dop853"], "osD^", strict=True):
    points = np.asarray(data[rule])
    ax.loglog(points[:, 2], points[:, 1], marker=marker, label=rule)
    for value, error, seconds in data[rule]:
        print(f"{rule:10s} {value:9.3g}  error {error:.1e}  time {seconds * 1e3:7.2f} ms")
ax.set(
    xlabel="run time (s, warm)",
    ylabel=f"max |Δθ| at T = {data['horizon']:g} s (rad)",
    title="double pendulum: error against run time",
)
# the run times span little more than a decade, so matplotlib labels the minor ticks:
# at each of 2…9 × 10ⁿ the labels run into each other, at 2 and 5 × 10ⁿ they do not
ax.xaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
ax.grid(alpha=0.3, which="both")
ax.legend(loc="lower left")  # "best" put it over the slowest points; this corner stays empty
fig.savefig(figure_path("work_precision.png"), dpi=110)
