"""The work–precision curves of ``diracvi bench --only work-precision`` as one Markdown table.

``python benchmarks/work_precision.py [--quick] [--repeats N]``: every point (problem,
method, step size or tolerance, error at T, warm time) of the spherical pendulum, the
double pendulum and the four-bar linkage, measured side by side in this one run
(``diracvi.bench.work_precision``). The table in ``docs/discretizations.md`` is its output.
"""

import argparse

from diracvi.bench._core import load_average, machine_info
from diracvi.bench.work_precision import curves, table

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--quick", action="store_true", help="T = 1, one step size per rule")
parser.add_argument("--repeats", type=int, default=5, help="warm calls per point (min taken)")
args = parser.parse_args()
data = curves(args.quick, repeats=args.repeats)
print(table(data))
info = machine_info()
print(f"\n{info.get('cpu', '')}, load average {load_average()}")
