"""``import diracvi`` stays light: the heavy libraries that only some entry points need
(plots, NetCDF, the command line, Dask, SciPy) are imported by those entry points."""

import subprocess
import sys

LAZY = ("matplotlib", "xarray", "typer", "rich", "dask", "distributed", "scipy")


def test_importing_diracvi_leaves_the_optional_stacks_unimported():
    probe = (
        "import sys, diracvi, diracvi.problems\n"
        f"print(' '.join(m for m in {LAZY!r} if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.strip() == "", f"imported with diracvi: {out.stdout.strip()}"
