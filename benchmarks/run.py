"""Run the benchmark suite: ``python benchmarks/run.py [--quick] [--only NAME]... [--json PATH]``.

The same as ``diracvi bench``; the code lives in the installed package (``diracvi.bench``)
so that the command works after a plain ``pip install .``. Method and results:
``benchmarks/README.md``.
"""

import sys

# the command line is the layer above the benchmarks: it imports them, never the reverse
from diracvi.cli import app

if __name__ == "__main__":
    app(["bench", *sys.argv[1:]], prog_name="diracvi")
