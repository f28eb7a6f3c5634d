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


def test_importing_diracvi_leaves_what_a_call_may_not_need_unimported():
    """The public names are imported at their first use: ``import diracvi`` alone loads
    no Dirac structures, sweeps, ensembles or step solvers, and a name brings its module."""
    probe = (
        "import sys, diracvi as dv\n"
        "before = sorted(m for m in sys.modules if m.startswith(("
        "'diracvi.dirac', 'diracvi.sweeps', 'diracvi.driver', 'diracvi.solvers')))\n"
        "dv.sweep, dv.dirac\n"
        "print(' '.join(before), '|', 'diracvi.sweeps.run' in sys.modules, "
        "'diracvi.dirac' in sys.modules, sorted(set(dv.__all__) - set(dir(dv))))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True
    )
    assert out.stdout.split() == ["|", "True", "True", "[]"], out.stdout


def test_a_netlist_run_writes_its_file_without_xarray(tmp_path):
    """A variable-step netlist result is written with h5netcdf alone (``spice/_netcdf.py``):
    a ``diracvi run deck.cir --out`` does not pay for importing xarray and pandas."""
    deck = tmp_path / "rc.cir"
    deck.write_text("RC\nV1 in 0 DC 1\nR1 in out 1k\nC1 out 0 1u\n.tran 0.5m 5m uic\n.end\n")
    probe = (
        "import sys\nfrom diracvi import spice\n"
        f"spice.run({str(deck)!r}).save({str(tmp_path / 'rc.nc')!r})\n"
        "print(' '.join(m for m in ('xarray', 'pandas') if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=300, check=True
    )
    assert out.stdout.strip() == "", f"imported by the run: {out.stdout.strip()}"
    assert (tmp_path / "rc.nc").exists()


def test_a_netlist_run_from_the_command_line_imports_only_what_it_runs(tmp_path):
    """``diracvi run deck.cir`` imports neither the built-in problems nor the model-file
    loader, nor the parts a linear deck does not build (rigid bodies, multibody systems,
    URDF robots, the level-2 MOSFET), nor the partitioned solver, nor SciPy's sparse
    matrices and graph algorithms (the band-plus-border plan's, from 200 unknowns on;
    jaxlib's LAPACK binding imports ``scipy.linalg`` alone); ``diracvi --help`` imports
    neither the rules nor the variable-step loops (issue 30)."""
    deck = tmp_path / "rc.cir"
    deck.write_text("RC\nV1 in 0 DC 1\nR1 in out 1k\nC1 out 0 1u\n.tran 0.5m 5m uic\n.end\n")
    unneeded = (
        "diracvi.problems",
        "diracvi.model.modelfile",
        "diracvi.components.multibody",
        "diracvi.components.urdf",
        "diracvi.components.mosfet2",
        "diracvi.solvers.partitioned",
        "scipy.sparse",
    )
    probe = (
        "import sys\nfrom diracvi.cli import app\n"
        "sys.argv = ['diracvi', *sys.argv[1:]]\n"
        "try:\n    app()\nexcept SystemExit:\n    pass\n"
        "print('@@', ' '.join(m for m in {names!r} if m in sys.modules))"
    )
    for argv, names in (
        (["run", str(deck)], unneeded),
        (["--help"], ("diracvi.discretization.rules", "diracvi.driver.adaptive_sparse")),
    ):
        out = subprocess.run(
            [sys.executable, "-c", probe.format(names=names), *argv],
            capture_output=True, text=True, timeout=300, check=True,
        )  # fmt: skip
        assert "@@" in out.stdout, out.stdout + out.stderr
        imported = out.stdout.rpartition("@@")[2].strip()
        assert imported == "", f"imported by diracvi {' '.join(argv)}: {imported}"


def test_the_help_names_the_registered_rules():
    """The command line lists the built-in rules without importing them
    (``discretization/names.py``): the same names, in order, as the registry's."""
    from diracvi.discretization.names import BUILT_IN
    from diracvi.discretization.rules import RULES, rule_names

    assert rule_names()[: len(BUILT_IN)] == BUILT_IN
    assert all(RULES[name]().name == name for name in BUILT_IN)
