"""The ``diracvi`` command line through typer's CliRunner: every command and error path."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from typer.testing import CliRunner

import diracvi as dv
from diracvi.cli import EXIT_FAILURE, EXIT_USAGE, app

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def write_model(folder, name, body):
    path = folder / name
    path.write_text(textwrap.dedent(body))
    return path


OSCILLATOR = """
    import diracvi as dv

    def build():
        system = dv.LagrangeDiracSystem(
            ("x",), lambda q, v: 0.5 * v @ v - 0.5 * q @ q, name="osc"
        )
        return {RETURN}
"""


def oscillator_model(folder, returned, name="osc.py"):
    return write_model(folder, name, OSCILLATOR.replace("{RETURN}", returned))


# ----------------------------------------------------------------------- list
def test_list_names_every_builtin_problem_with_its_description():
    result = invoke("list")
    assert result.exit_code == 0
    for name, description in dv.problems.available().items():
        assert name in result.output
        assert description.split()[0] in result.output


def test_version_and_help():
    assert dv.__version__ in invoke("--version").output
    result = invoke("--help")
    assert result.exit_code == 0
    for command in ("list", "run", "plot", "reproduce"):
        assert command in result.output


# ------------------------------------------------------------------------ run
def test_run_builtin_saves_netcdf_and_plot(tmp_path):
    out = tmp_path / "chain.nc"
    result = invoke("run", "spring-chain-torn", "--steps", 50, "--out", out, "--plot")
    assert result.exit_code == 0, result.output
    assert "Newton iterations" in result.output
    assert "max |constraint residual|" in result.output
    traj = dv.load(out)
    assert traj.steps == 50
    assert traj.dt == 0.01  # the problem's default step
    assert traj.coords == ("left.q1", "left.q2", "right.q2bar", "right.q3")
    png = out.with_suffix(".png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_run_summary_reports_the_trajectory_it_computed(tmp_path):
    out = tmp_path / "rlc.nc"
    result = invoke("run", "rlc", "--steps", 20, "--out", out)
    assert result.exit_code == 0, result.output
    traj = dv.load(out)
    assert f"final {traj.energy[-1]:.10g}" in result.output
    assert f"{traj.newton_iterations.sum()} total" in result.output
    assert "dt = 0.1" in result.output


def test_run_options_reach_simulate(tmp_path):
    out = tmp_path / "m.nc"
    result = invoke(
        "run",
        "damped-oscillator",
        "--dt",
        "0.02",
        "--steps",
        30,
        "--scheme",
        "minus",
        "--discretization",
        "midpoint",
        "--out",
        out,
    )
    assert result.exit_code == 0, result.output
    traj = dv.load(out)
    assert (traj.scheme, traj.discretization, traj.steps, traj.dt) == (
        "minus",
        "midpoint",
        30,
        0.02,
    )
    assert traj.t[-1] == pytest.approx(-0.6)


RLC_SWEEP = """
    from diracvi import problems

    def build(R=1.0, C=3.0):
        return problems.build_rlc(R=R, C=C)
"""


def test_sweep_solver_option_reaches_sweep(tmp_path):
    # --solver is run's option, with run's names: automatic (the affine maps of a linear
    # circuit) or a solver for every member; the dataset and the summary say which ran
    import xarray as xr

    model = write_model(tmp_path, "rlc.py", RLC_SWEEP)
    base = ["sweep", model, "--param", "R=0.5,2", "--param", "C=1,3", "--dt", "0.1"]
    base += ["--steps", 60, "--batch-size", 4]
    q = {}
    for option, solver in (((), "affine step map"), (("--solver", "newton"), "NewtonSolver()")):
        out = tmp_path / f"{solver.split()[0]}.nc"
        result = invoke(*base, *option, "--out", out)
        assert result.exit_code == 0, result.output
        assert solver in result.output
        with xr.open_dataset(out, engine="h5netcdf") as ds:
            assert set(ds.solver.values.ravel()) == {solver} and (ds.status == 0).all()
            q[solver] = ds["qC"].values
    np.testing.assert_allclose(q["NewtonSolver()"], q["affine step map"], rtol=0, atol=1e-11)
    bad = invoke(*base, "--solver", "lu")
    assert bad.exit_code == EXIT_USAGE
    flat = " ".join(bad.output.replace("│", " ").split())  # (rich boxes and wraps it)
    assert "--solver" in flat and "'lu' is not one of newton, newton-full, affine," in flat
    refused = invoke(*base, "--solver", "partitioned")  # the library's reason, plainly
    assert refused.exit_code == EXIT_FAILURE
    assert "needs an interconnected system" in " ".join(refused.output.split())
    assert "Traceback" not in refused.output


def test_run_plot_without_out_writes_next_to_cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke("run", "damped-oscillator", "--steps", 10, "--plot")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "damped-oscillator.png").stat().st_size > 0


def test_unknown_problem_is_named_and_the_available_ones_listed():
    result = invoke("run", "spring-chian")
    assert result.exit_code == EXIT_USAGE
    assert "'spring-chian'" in result.output
    for name in dv.problems.REGISTRY:
        assert name in result.output


def test_missing_model_file_is_named(tmp_path):
    path = tmp_path / "nowhere" / "model.py"
    result = invoke("run", path)
    assert result.exit_code == EXIT_USAGE
    assert str(path) in result.output
    assert "does not exist" in result.output


RC_DECK = "rc\nv1 1 0 pulse(0 1 0 1u 1u 1m 2m)\nr1 1 2 1k\nc1 2 0 1u\n.tran 10u 100u\n.end\n"


@pytest.mark.parametrize("name", ["RC.cir.out", "rc.spi"])
def test_netlists_named_as_esim_and_ngspice_name_them_run(tmp_path, name):
    # eSim hands ngspice <project>.cir.out (the field test's eSim decks); .spi is ngspice's
    deck = tmp_path / name
    deck.write_text(RC_DECK)
    result = invoke("run", deck, "--out", tmp_path / "rc.nc")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "rc.nc").is_file()


def test_a_file_neither_python_nor_a_netlist_by_name_is_refused_naming_both(tmp_path):
    deck = tmp_path / "rc.txt"
    deck.write_text(RC_DECK)
    result = invoke("run", deck)
    assert result.exit_code == EXIT_USAGE
    assert "neither a model file (.py) nor a netlist" in result.output
    assert ".cir.out" in result.output and "cannot be imported as Python" not in result.output


@pytest.mark.parametrize(
    ("args", "option", "value"),
    [
        (["--dt", "-1"], "--dt", "-1"),
        (["--dt", "0"], "--dt", "0"),
        (["--dt", "abc"], "--dt", "abc"),
        (["--dt", "nan"], "--dt", "nan"),
        (["--steps", "0"], "--steps", "0"),
        (["--steps", "2.5"], "--steps", "2.5"),
        (["--scheme", "sideways"], "--scheme", "sideways"),
        (["--discretization", "rk4"], "--discretization", "rk4"),
    ],
)
def test_bad_option_values_name_the_option(args, option, value):
    result = invoke("run", "rlc", *args)
    assert result.exit_code == EXIT_USAGE
    assert option in result.output
    assert value in result.output


def test_out_folder_must_exist(tmp_path):
    out = tmp_path / "missing" / "x.nc"
    result = invoke("run", "rlc", "--steps", 5, "--out", out)
    assert result.exit_code == EXIT_USAGE
    assert str(out.parent) in result.output


def test_unsolvable_step_prints_the_message_without_traceback():
    result = invoke("run", "lc", "--discretization", "retraction", "--steps", 5)
    assert result.exit_code == EXIT_FAILURE
    assert "not solvable" in result.output
    assert "midpoint" in result.output  # the fix it suggests
    assert "Traceback" not in result.output


# ---------------------------------------------------------------- model files
def test_model_file_returning_a_tuple(tmp_path):
    path = oscillator_model(tmp_path, "system, [1.0], [0.0]")
    out = tmp_path / "osc.nc"
    result = invoke("run", path, "--dt", "0.1", "--steps", 20, "--out", out)
    assert result.exit_code == 0, result.output
    traj = dv.load(out)
    # the (+) retraction step of the harmonic oscillator stays near x = cos t
    assert np.max(np.abs(traj.q[:, 0] - np.cos(traj.t))) < 0.1


def test_model_file_dict_supplies_dt_and_steps_defaults(tmp_path):
    path = oscillator_model(
        tmp_path, '{"system": system, "q0": [1.0], "p0": [0.0], "dt": 0.05, "steps": 7}'
    )
    out = tmp_path / "osc.nc"
    assert invoke("run", path, "--out", out).exit_code == 0
    traj = dv.load(out)
    assert (traj.steps, traj.dt) == (7, 0.05)
    # command-line options override the file's defaults
    assert invoke("run", path, "--steps", 3, "--out", out).exit_code == 0
    assert dv.load(out).steps == 3


def test_model_file_object_with_attributes(tmp_path):
    path = write_model(
        tmp_path,
        "prob.py",
        """
        from diracvi import problems

        def build():
            return problems.get("damped-oscillator")
    """,
    )
    result = invoke("run", path, "--steps", 5)
    assert result.exit_code == 0, result.output
    assert "5 of 5" in result.output


def test_model_file_without_dt_asks_for_it(tmp_path):
    path = oscillator_model(tmp_path, "system, [1.0], [0.0]")
    result = invoke("run", path)
    assert result.exit_code == EXIT_USAGE
    assert "--dt" in result.output and "--steps" in result.output


@pytest.mark.parametrize(
    ("body", "expected"),
    [
        ("x = 1\n", "no build() function"),
        ("def build():\n    return 1 / 0\n", "ZeroDivisionError"),
        ("import no_such_module_anywhere\n", "ModuleNotFoundError"),
        ("def build():\n    return {'q0': [0.0]}\n", "lacks ['system', 'p0']"),
        ("def build():\n    return 'sys', [0.0], [0.0]\n", "not a diracvi system"),
    ],
)
def test_broken_model_files_explain_themselves(tmp_path, body, expected):
    path = write_model(tmp_path, "broken.py", body)
    result = invoke("run", path, "--dt", "0.1", "--steps", 3)
    assert result.exit_code == EXIT_FAILURE
    assert expected in result.output
    assert str(path) in result.output
    assert "Traceback" not in result.output


def test_model_error_from_the_library_is_printed_plainly(tmp_path):
    path = oscillator_model(tmp_path, "system, [1.0, 2.0], [0.0]")
    result = invoke("run", path, "--dt", "0.1", "--steps", 3)
    assert result.exit_code == EXIT_FAILURE
    assert "q0 has shape (2,)" in result.output
    assert "Traceback" not in result.output


def test_step_failure_saves_the_partial_trajectory(tmp_path):
    # sqrt(1 − x) is NaN once the oscillator swings past x = 1 (amplitude 2)
    path = write_model(
        tmp_path,
        "wall.py",
        """
        import jax.numpy as jnp
        import diracvi as dv

        def build():
            system = dv.LagrangeDiracSystem(
                ("x",), lambda q, v: 0.5 * v @ v - 0.5 * q @ q + jnp.sqrt(1.0 - q[0]),
                name="wall",
            )
            return {"system": system, "q0": [0.0], "p0": [2.0], "dt": 0.01, "steps": 500}
    """,
    )
    out = tmp_path / "partial.nc"
    result = invoke("run", path, "--out", out)
    assert result.exit_code == EXIT_FAILURE
    assert "NaN or Inf appeared" in result.output
    assert "saved to" in result.output and str(out) in result.output
    assert "Traceback" not in result.output
    traj = dv.load(out)
    assert 0 < traj.steps < 500
    assert traj.status != 0
    # every saved state is finite; the failing step is the first from beyond x = 1
    assert np.all(np.isfinite(traj.q))
    assert np.all(traj.q[:-1, 0] < 1.0) and traj.q[-1, 0] > 1.0


def test_step_failure_without_out_saves_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = write_model(
        tmp_path,
        "wall.py",
        """
        import jax.numpy as jnp
        import diracvi as dv

        def build():
            system = dv.LagrangeDiracSystem(
                ("x",), lambda q, v: 0.5 * v @ v + jnp.sqrt(1.0 - q[0]), name="wall"
            )
            return system, [0.0], [2.0]
    """,
    )
    result = invoke("run", path, "--dt", "0.01", "--steps", 200)
    assert result.exit_code == EXIT_FAILURE
    assert "saved" not in result.output
    assert list(tmp_path.glob("*.nc")) == []


# ----------------------------------------------------------------------- plot
def test_plot_a_saved_trajectory(tmp_path):
    nc = tmp_path / "t.nc"
    dv.simulate(
        dv.problems.get("rlc-torn").system, np.zeros(5), [0.0, 7.5, 0.0, 0.0, 0.0], dt=0.1, steps=30
    ).save(nc)
    result = invoke("plot", nc)
    assert result.exit_code == 0, result.output
    assert nc.with_suffix(".png").read_bytes()[:4] == b"\x89PNG"
    other = tmp_path / "other.png"
    assert invoke("plot", nc, "--out", other).exit_code == 0
    assert other.stat().st_size > 0


def test_plot_does_not_overwrite_an_existing_png_without_force(tmp_path):
    nc = tmp_path / "t.nc"
    dv.simulate(dv.problems.get("damped-oscillator").system, [1.0], [0.0], dt=0.1, steps=5).save(nc)
    png = nc.with_suffix(".png")
    png.write_bytes(b"mine")
    result = invoke("plot", nc)
    assert result.exit_code == EXIT_USAGE
    assert "already exists" in result.output and "--force" in result.output
    assert png.read_bytes() == b"mine"
    assert invoke("plot", nc, "--force").exit_code == 0
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_run_plot_is_titled_with_the_problem_name(tmp_path, monkeypatch):
    import diracvi.plotting

    seen = {}
    real = diracvi.plotting.plot_trajectory

    def spy(traj, path, title=None, name=None):
        seen["name"] = name
        return real(traj, path, title=title, name=name)

    monkeypatch.setattr(diracvi.plotting, "plot_trajectory", spy)
    out = tmp_path / "d.nc"
    assert invoke("run", "damped-oscillator", "--steps", 5, "--out", out, "--plot").exit_code == 0
    assert seen["name"] == "damped-oscillator"  # not the system's name, "oscillator"


def test_model_file_may_return_dt_and_steps_beside_the_state(tmp_path):
    path = oscillator_model(tmp_path, "system, [1.0], [0.0], {'dt': 0.05, 'steps': 7}")
    out = tmp_path / "o.nc"
    result = invoke("run", path, "--out", out)
    assert result.exit_code == 0, result.output
    traj = dv.load(out)
    assert (traj.dt, traj.steps) == (0.05, 7)
    # the command line still overrides them
    assert invoke("run", path, "--steps", 3, "--out", out).exit_code == 0
    assert dv.load(out).steps == 3


def test_plot_missing_file_is_named(tmp_path):
    path = tmp_path / "absent.nc"
    result = invoke("plot", path)
    assert result.exit_code == EXIT_USAGE
    assert str(path) in result.output


def test_plot_unreadable_file_is_named(tmp_path):
    path = tmp_path / "junk.nc"
    path.write_text("not netcdf")
    result = invoke("plot", path)
    assert result.exit_code == EXIT_FAILURE
    assert str(path) in result.output
    assert "Traceback" not in result.output


def test_warnings_are_printed_as_plain_lines(tmp_path):
    """An inconsistent initial state runs, with a one-line warning (no file:line prefix)."""
    path = write_model(
        tmp_path,
        "loose.py",
        """
        import diracvi as dv

        def build():
            # an LC circuit with two capacitors: p^{C1} = p^{C2} (= −μ) is required
            system = dv.LagrangeDiracSystem(
                ("qL", "qC1", "qC2"),
                lambda q, v: 0.5 * v[0] ** 2 - 0.5 * q[1] ** 2 - 0.5 * q[2] ** 2,
                constraints=[[1.0, -1.0, -1.0]], name="loose",
            )
            return system, [0.0, 0.0, 0.0], [1.0, 0.3, 0.0]
        """,
    )
    result = invoke("run", path, "--dt", "0.1", "--steps", 5, "--discretization", "midpoint")
    assert result.exit_code == 0, result.output
    assert "warning: Inconsistent initial data" in result.output
    assert "InconsistentInitialDataWarning" not in result.output


def test_readme_model_file_runs_without_options(tmp_path):
    """The README's model-file example, copied as written, runs with no --dt/--steps."""
    import re
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")
    block = re.search(r"```python[^\n]*\n(# model\.py\n.*?)```", readme, re.S)
    assert block, "the README shows a model file"
    path = tmp_path / "model.py"
    path.write_text(block.group(1))
    out = tmp_path / "m.nc"
    result = invoke("run", path, "--out", out)
    assert result.exit_code == 0, result.output
    assert dv.load(out).steps == 1000
    # the same file swept: its (system, q0, p0, {dt, steps}) gives the sweep's defaults
    swept = tmp_path / "s.nc"
    result = invoke("sweep", path, "--param", "k=1,4", "--out", swept)
    assert result.exit_code == 0, result.output
    import xarray as xr

    with xr.open_dataset(swept) as ds:
        assert ds.sizes["k"] == 2 and ds.sizes["time"] == 1001 and (ds.status == 0).all()


def test_a_problems_notes_print_as_whole_lines():
    """A problem's ``notes`` is one string: it prints as one line, not one character a
    line (it used to be iterated as a list)."""
    result = invoke("run", "rlc", "--discretization", "midpoint", "--steps", 20)
    assert result.exit_code == 0, result.output
    notes = [line for line in result.output.splitlines() if line.startswith("note:")]
    assert notes and all(len(line) > len("note: x") for line in notes)
    assert any("resistor sign" in line for line in notes)


def test_the_process_exit_skips_the_collectors_walk_and_the_test_runner_does_not(tmp_path):
    """A ``diracvi`` process moves what is left after its command to the collector's
    permanent generation (``gc.freeze``, ``cli/main.py: _Command``: the interpreter's
    exit then does not walk JAX's millions of objects), and a netlist run what exists
    before it runs (``cli/common.py: _settle``); a command run by ``CliRunner`` — many
    in one test process — freezes nothing."""
    import gc
    import subprocess
    import sys

    deck = tmp_path / "rc.cir"
    deck.write_text(RC_DECK)
    probe = (
        "import gc, sys\nfrom diracvi import spice\nfrom diracvi.cli import app\n"
        "run = spice.run\n"
        "def counted(*a, **k):\n    print('@@ before the run', gc.get_freeze_count())\n"
        "    return run(*a, **k)\n"
        "spice.run = counted\n"
        "try:\n    app()\nfinally:\n    print('@@ at the end', gc.get_freeze_count())\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe, "run", str(deck)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    counts = [int(line.split()[-1]) for line in out.stdout.splitlines() if line[:2] == "@@"]
    assert len(counts) == 2, out.stdout + out.stderr
    # the imported modules' objects, at least, then more (the run's)
    assert 10_000 < counts[0] < counts[1], counts
    before = gc.get_freeze_count()
    assert runner.invoke(app, ["--version"]).exit_code == 0
    result = invoke("run", deck, "--out", tmp_path / "rc.nc")
    assert result.exit_code == 0, result.output
    assert gc.get_freeze_count() == before
