"""Where an error message suggests a value, the suggestion works: each test triggers the
error, reads the suggested value out of the message, applies it, and checks that the call
then succeeds (and, where the message promises more — "the end of the run", "at most half
the horizon" — that too). A message whose suggested value is wrong fails here."""

from __future__ import annotations

import ast
import math
import re

import numpy as np
import pytest
from typer.testing import CliRunner

import diracvi as dv
from diracvi import components as cp
from diracvi.cli import app
from diracvi.errors import ModelError
from diracvi.runtime import compile as compile_switches
from diracvi.runtime import dispatch
from diracvi.spice import waveforms


def _oscillator():
    return dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v - 0.5 * q @ q, name="osc")


def _pendulum():  # nonlinear: stepped by the Newton solver, whose options are under test
    import jax.numpy as jnp

    return dv.LagrangeDiracSystem(
        ("theta",), lambda q, v: 0.5 * v @ v + jnp.cos(q[0]), name="pendulum"
    )


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def suggestion(message: str, pattern: str) -> str:
    """The value the message suggests (``pattern``'s group), failing when it offers none."""
    found = re.search(pattern, message)
    assert found, f"the message suggests no value matching {pattern!r}: {message}"
    return found.group(1)


@pytest.mark.parametrize(("steps", "save_every"), [(10, 3), (7, 4), (1, 2), (100, 7)])
def test_save_every_error_suggests_a_step_count_that_runs(steps, save_every):
    run = dict(dt=0.1, save_every=save_every)
    with pytest.raises(ModelError, match="does not divide") as err:
        dv.simulate(_oscillator(), [1.0], [0.0], steps=steps, **run)
    fixed = int(suggestion(str(err.value), r"choose steps=(\d+)"))
    traj = dv.simulate(_oscillator(), [1.0], [0.0], steps=fixed, **run)
    assert traj.steps == fixed >= steps  # the run is not shortened
    assert fixed - steps < save_every  # the next count that works, not any multiple
    np.testing.assert_allclose(traj.t[-1], fixed * 0.1)  # the last saved state ends the run


@pytest.mark.parametrize(("every", "save_every"), [(4, 3), (5, 2)])
def test_checkpoint_every_error_suggests_a_value_that_runs(tmp_path, every, save_every):
    run = dict(dt=0.1, steps=12 * save_every, save_every=save_every)
    with pytest.raises(ModelError, match="not a multiple") as err:
        dv.simulate(
            _oscillator(), [1.0], [0.0], checkpoint=tmp_path / "a.nc", checkpoint_every=every, **run
        )
    fixed = int(suggestion(str(err.value), r"use checkpoint_every=(\d+)"))
    traj = dv.simulate(
        _oscillator(), [1.0], [0.0], checkpoint=tmp_path / "b.nc", checkpoint_every=fixed, **run
    )
    assert traj.steps == run["steps"] and fixed >= every


@pytest.mark.parametrize(
    ("arg", "bad"),
    [
        ("dt", -1.0),
        ("dt", math.nan),
        ("dt", "0.1"),
        ("steps", 0),
        ("steps", 2.5),
        ("t0", math.inf),
        ("t0", "zero"),
    ],
)
def test_argument_errors_suggest_a_value_that_runs(arg, bad):
    run = {"dt": 0.01, "steps": 20, "t0": 0.0}
    with pytest.raises(ModelError) as err:
        dv.simulate(_oscillator(), [1.0], [0.0], **{**run, arg: bad})
    text = suggestion(str(err.value), rf"e\.g\. {arg}=([-+0-9.e]+?)\.?$")
    value = int(text) if arg == "steps" else float(text)
    traj = dv.simulate(_oscillator(), [1.0], [0.0], **{**run, arg: value})
    assert traj.steps == (value if arg == "steps" else run["steps"])


@pytest.mark.parametrize(
    ("arg", "bad"), [("rtol", 2.0), ("floor", 0.0), ("max_steps", 0), ("contraction", 1.5)]
)
def test_newton_option_errors_suggest_a_value_that_runs(arg, bad):
    with pytest.raises(ModelError) as err:
        dv.NewtonSolver(**{arg: bad})
    text = suggestion(str(err.value), r"e\.g\. ([0-9.e-]+?)\.?$")
    solver = dv.NewtonSolver(**{arg: int(text) if arg == "max_steps" else float(text)})
    traj = dv.simulate(_pendulum(), [1.0], [0.0], dt=0.05, steps=20, solver=solver)
    assert traj.solver.startswith("Newton") and np.all(np.isfinite(traj.q))


@pytest.mark.parametrize(("arg", "label"), [("detect_rtol", "detect"), ("verify_rtol", "verify")])
def test_affine_tolerance_errors_suggest_a_value_that_runs(arg, label):
    with pytest.raises(ModelError) as err:
        dv.AffineSolver(**{arg: 0.5})
    value = float(suggestion(str(err.value), rf"([0-9.e-]+) \({label}\)"))
    traj = dv.simulate(
        _oscillator(), [1.0], [0.0], dt=0.01, steps=20, solver=dv.AffineSolver(**{arg: value})
    )
    assert traj.solver == "affine step map"


@pytest.mark.parametrize(("option", "bad"), [("--dt", "abc"), ("--dt", "-1"), ("--steps", "x")])
def test_cli_number_errors_suggest_values_that_run(option, bad):
    run = {"--dt": "0.01", "--steps": "20"}
    result = invoke("run", "rlc", *[a for k, v in {**run, option: bad}.items() for a in (k, v)])
    assert result.exit_code != 0
    message = " ".join(result.output.split())  # rich wraps the message in a box
    examples = re.findall(r"e\.g\. ([0-9a-z.]+)(?: or ([0-9a-z.]+))?", message)
    assert examples, message
    for value in filter(None, examples[0]):  # "e.g. 0.01 or 5u": each one works
        value = value.rstrip(".")
        ok = invoke("run", "rlc", *[a for k, v in {**run, option: value}.items() for a in (k, v)])
        assert ok.exit_code == 0, (value, ok.output)


@pytest.mark.parametrize("switch", [compile_switches.fast_compile, dispatch.keep_async])
def test_switch_errors_suggest_the_settings_that_work(switch, monkeypatch):
    name = {compile_switches.fast_compile: "DIRACVI_FAST_COMPILE"}.get(switch, dispatch.ASYNC_ENV)
    monkeypatch.setenv(name, "yes")
    with pytest.raises(ValueError, match=name) as err:
        switch()
    on = suggestion(str(err.value), r"set it to (\S+) \(")
    off = suggestion(str(err.value), r"\) or (\S+) / unset")
    monkeypatch.setenv(name, on)
    assert switch() is True
    monkeypatch.setenv(name, off)
    assert switch() is False


def test_sweep_reserved_name_error_suggests_a_name_that_runs():
    def build(**values):
        (k,) = values.values()
        system = dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v - 0.5 * k * q @ q)
        return system, [1.0], [0.0]

    with pytest.raises(ModelError, match="reserved") as err:
        dv.sweep(build, {"energy": [1.0, 2.0]}, dt=0.1, steps=5)
    name = suggestion(str(err.value), r"e\.g\. (\w+)\)")
    ds = dv.sweep(build, {name: [1.0, 2.0]}, dt=0.1, steps=5)
    assert name in ds.coords and ds.sizes[name] == 2 and (ds.status == 0).all()


def test_waveforms_error_suggests_a_step_that_works():
    c = cp.Circuit("rc")
    c.add(cp.VoltageSource(1.0, name="V1"), p="in", n="0")
    c.add(cp.Resistor(1.0, name="R1"), p="in", n="out")
    c.add(cp.Capacitor(1.0, name="C1"), p="out", n="0")
    built = c.build()
    horizon = 0.5
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=horizon, steps=1, discretization="midpoint"
    )
    with pytest.raises(ModelError, match="at most half the horizon"):
        waveforms(built, traj)
    dt = horizon / 2  # the largest step the message allows
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=dt, steps=round(horizon / dt),
        discretization="midpoint",
    )  # fmt: skip
    assert np.all(np.isfinite(waveforms(built, traj)["v(out)"]))


def test_plot_refusal_suggests_options_that_work(tmp_path):
    traj = dv.simulate(_oscillator(), [1.0], [0.0], dt=0.1, steps=10)
    saved = tmp_path / "osc.nc"
    traj.save(saved)
    assert invoke("plot", saved).exit_code == 0
    refused = invoke("plot", saved)
    assert refused.exit_code != 0
    message = " ".join(refused.output.split())
    flag = suggestion(message, r"pass (--\w+) to overwrite")
    out_option, new_png = suggestion(message, r"or (--\w+ \S+\.png)").split()
    assert invoke("plot", saved, flag).exit_code == 0
    new_png = tmp_path / new_png
    assert invoke("plot", saved, out_option, new_png).exit_code == 0 and new_png.is_file()


@pytest.mark.slow  # a gradient through a netlist run: about 7 s of compilation
def test_traced_netlist_parameters_suggest_a_step_that_runs():
    import jax

    from diracvi import spice

    netlist = """RC step
.param rval=1k
V1 in 0 DC 1
R1 in out {rval}
C1 out 0 1u
.tran 0.1m 1m
.end
"""
    with pytest.raises(ModelError, match="need a fixed step") as err:
        jax.grad(lambda r: spice.run(netlist, params={"rval": r})["v(out)"][-1])(1e3)
    message = str(err.value)
    dt = float(suggestion(message, r"TSTEP (\S+?)\)"))
    if "add UIC to the .tran line" in message:
        netlist = netlist.replace(".tran 0.1m 1m", ".tran 0.1m 1m UIC")
    grad = jax.grad(lambda r: spice.run(netlist, dt=dt, params={"rval": r})["v(out)"][-1])(1e3)
    assert np.isfinite(grad) and grad < 0  # a larger R charges the capacitor more slowly


# ------------------------------------------------------------------ models and solvers


def test_names_error_suggests_names_that_run():
    energy = lambda q, v: 0.5 * v @ v - 0.5 * q @ q  # noqa: E731
    with pytest.raises(ModelError, match="sequence of names") as err:
        dv.LagrangeDiracSystem("xy", energy)
    names = ast.literal_eval(suggestion(str(err.value), r"e\.g\. coords=(\(.*?\))\.$"))
    traj = dv.simulate(dv.LagrangeDiracSystem(names, energy), [1.0, 0.0], [0.0, 1.0],
                       dt=0.1, steps=10)  # fmt: skip
    assert traj.status == 0 and traj.q.shape == (11, 2)


def test_holonomic_shape_error_suggests_a_constraint_that_runs():
    import jax.numpy as jnp

    def lagrangian(q, v):  # a point mass in the plane under gravity
        return 0.5 * v @ v - q[1]

    with pytest.raises(ModelError, match="holonomic returned shape") as err:
        dv.LagrangeDiracSystem(("x", "y"), lagrangian, holonomic=lambda q: q @ q - 1.0)
    written = suggestion(str(err.value), r"e\.g\. (lambda q: .*)\.$")
    system = dv.LagrangeDiracSystem(("x", "y"), lagrangian, holonomic=eval(written, {"jnp": jnp}))
    traj = dv.simulate(system, [1.0, 0.0], [0.0, 0.0], dt=0.01, steps=50)
    radius = np.sum(np.asarray(traj.q) ** 2, axis=1)  # the suggested g: a pendulum of length 1
    assert traj.status == 0 and np.abs(radius - 1.0).max() < 1e-10
    assert traj.q[-1, 1] < -0.01  # it swings down


def test_partitioned_solver_errors_suggest_fixes_that_run():
    with pytest.raises(ModelError, match="needs an interconnected system") as err:
        dv.simulate(_pendulum(), [1.0], [0.0], dt=0.05, steps=10, solver=dv.PartitionedSolver())
    written = suggestion(str(err.value), r"use solver=(dv\.\w+\(\))")
    traj = dv.simulate(_pendulum(), [1.0], [0.0], dt=0.05, steps=10,
                       solver=eval(written, {"dv": dv}))  # fmt: skip
    assert traj.status == 0


@pytest.mark.slow  # three compilations of the torn double pendulum: about 6 s
def test_partitioned_midpoint_error_suggests_fixes_that_run():
    from diracvi import problems

    pendulum = problems.get("double-pendulum-torn")
    run = dict(dt=pendulum.dt, steps=10)
    args = (pendulum.system, pendulum.q0, pendulum.p0)
    with pytest.raises(ModelError, match="do not split by subsystem") as err:
        dv.simulate(*args, **run, discretization="midpoint", solver=dv.PartitionedSolver())
    message = str(err.value)
    solver = eval(suggestion(message, r"use solver=(dv\.\w+\(\))"), {"dv": dv})
    rule = suggestion(message, r"or discretization='(\w+)'")
    newton = dv.simulate(*args, **run, discretization="midpoint", solver=solver)
    split = dv.simulate(*args, **run, discretization=rule, solver=dv.PartitionedSolver())
    assert newton.status == 0 and split.status == 0
    assert split.solver.startswith("partitioned") or "artition" in split.solver


def test_affine_fallback_error_suggests_solvers_that_run():
    with pytest.raises(ModelError, match="fallback must be a step solver") as err:
        dv.AffineSolver(fallback="newton")
    written = re.findall(r"(dv\.\w+\(\))", suggestion(str(err.value), r"e\.g\. (.*)\.$"))
    assert len(written) == 2, err.value
    solver = dv.AffineSolver(
        fallback=eval(written[0], {"dv": dv})
    )  # a nonlinear model: it falls back
    traj = dv.simulate(_pendulum(), [1.0], [0.0], dt=0.05, steps=10, solver=solver)
    assert traj.status == 0 and traj.solver.startswith("Newton")
    assert isinstance(dv.AffineSolver(fallback=eval(written[1], {"dv": dv})), dv.AffineSolver)


# ------------------------------------------------------------------ sweeps


def _sweep_build(R=1.0, C=1.0):
    """A damped oscillator: stiffness 1/C, damping R."""
    system = dv.LagrangeDiracSystem(
        ("x",), lambda q, v: 0.5 * v @ v - 0.5 * q @ q / C, force=lambda q, v: -R * v
    )
    return system, [1.0], [0.0]


@pytest.mark.parametrize("which", ["params", "samples"])
def test_sweep_table_error_suggests_a_table_that_runs(which):
    with pytest.raises(ModelError, match="is not a mapping") as err:
        dv.sweep(_sweep_build, **{which: [1.0, 2.0]}, dt=0.1, steps=5)
    written = suggestion(str(err.value), rf"e\.g\. {which}=(\{{.*?\}}) \(")
    table = eval(written, {"np": np})
    ds = dv.sweep(_sweep_build, **{which: table}, dt=0.1, steps=5)
    assert (ds.status == 0).all() and set(table) <= set(ds.coords) | set(ds.data_vars)


def test_sweep_values_error_suggests_values_that_run():
    with pytest.raises(ModelError, match="is not numeric") as err:
        dv.sweep(_sweep_build, {"R": ["low", "high"]}, dt=0.1, steps=5)
    values = eval(suggestion(str(err.value), r"e\.g\. (np\.linspace\(.*?\))\.$"), {"np": np})
    ds = dv.sweep(_sweep_build, {"R": values}, dt=0.1, steps=5)
    assert ds.sizes["R"] == len(values) and (ds.status == 0).all()


@pytest.mark.parametrize("bad", ["R", "R=abc", "R=1:2:x"])
def test_cli_param_errors_suggest_params_that_run(bad, tmp_path):
    model = tmp_path / "damped.py"
    model.write_text(
        "import diracvi as dv\n\n"
        "def build(R=1.0, C=1.0):\n"
        "    system = dv.LagrangeDiracSystem(\n"
        "        ('x',), lambda q, v: 0.5 * v @ v - 0.5 * q @ q / C, force=lambda q, v: -R * v\n"
        "    )\n"
        "    return system, [1.0], [0.0], {'dt': 0.1, 'steps': 5}\n"
    )
    refused = invoke("sweep", model, "--param", bad, "--out", tmp_path / "no.nc")
    assert refused.exit_code != 0
    message = " ".join(refused.output.split())
    examples = re.findall(r"((?:R|C)=[0-9.:,]+[0-9])", suggestion(message, r"e\.g\. (.*)"))
    assert len(examples) == 2, message
    out = tmp_path / "sweep.nc"
    ran = invoke("sweep", model, *[a for e in examples for a in ("--param", e)], "--out", out)
    assert ran.exit_code == 0, ran.output
    import xarray as xr

    with xr.open_dataset(out) as ds:
        assert ds.sizes["R"] == 20 and ds.sizes["C"] == 3 and int(ds.status.max()) == 0


# ------------------------------------------------------------------ netlists

RC = """RC
V1 in 0 DC 1
R1 in out 1
C1 out 0 1
.tran 0.1 1
.end
"""


BSIM3_BIAS = """a BSIM3 transistor biased
VD d 0 1
VG g 0 2
M1 d g 0 0 nb L=1u W=10u
.model nb NMOS LEVEL=8 VERSION=3.3.0
.tran 1n 10n
.end
"""


@pytest.mark.parametrize("line", [".temp 50", ".options temp=50"])
def test_temperature_error_suggests_a_temperature_that_runs(line):
    # a device with no temperature update yet: BSIM3, the one left (the JFET had none
    # when this was written; tests/test_temperature.py has the ones that have one); its
    # refusal names the card's TNOM, and the circuit set to it runs as without the line
    from diracvi import spice

    with pytest.raises(ModelError, match="TNOM 27 °C") as err:
        spice.run(BSIM3_BIAS.replace(".end", f"{line}\n.end"), dt=1e-9)
    value = suggestion(str(err.value), r"the card's TNOM (\d+) °C")
    fixed = spice.run(BSIM3_BIAS.replace(".end", f"{line.replace('50', value)}\n.end"), dt=1e-9)
    removed = spice.run(BSIM3_BIAS, dt=1e-9)
    assert np.array_equal(fixed["i(vd)"], removed["i(vd)"])
    assert np.max(np.abs(removed["i(vd)"])) > 1e-6  # it conducts: 1.13e-5 A, as ngspice


@pytest.mark.parametrize(
    ("options", "match"),
    [({"discretization": "retraction"}, "midpoint"), ({"solver": "newton"}, "fixed-step")],
)
def test_variable_step_refusals_suggest_a_fixed_step_that_runs(options, match):
    from diracvi import spice

    if "solver" in options:
        options = {"solver": dv.NewtonSolver()}
    with pytest.raises(ModelError, match=match) as err:
        spice.run(RC, **options)
    assert "pass dt=" in str(err.value)
    result = spice.run(RC, dt=0.1, **options)  # the netlist's TSTEP
    assert np.all(np.isfinite(result["v(out)"])) and result["v(out)"][-1] > 0.5


def test_cli_netlist_solver_refusal_suggests_an_option_that_runs(tmp_path):
    deck = tmp_path / "rc.cir"
    deck.write_text(RC)
    refused = invoke("run", deck, "--solver", "newton")
    assert refused.exit_code != 0
    option = suggestion(" ".join(refused.output.split()), r"pass (--\w+) STEP")
    ran = invoke("run", deck, "--solver", "newton", option, "0.1")  # the deck's TSTEP
    assert ran.exit_code == 0, ran.output
    assert "10 of 10" in ran.output  # the horizon kept: 1 s in steps of 0.1


def test_thinned_netlist_runs_are_refused_with_a_fix_that_runs():
    from diracvi import spice

    for options in ({"save_every": 2}, {"save_states": False}):
        with pytest.raises(ModelError, match="every state") as err:
            spice.run(RC, dt=0.1, **options)
    written = suggestion(str(err.value), r"thin the result \((result\[.*?\]\[.*?\])\)")
    result = spice.run(RC, dt=0.1)  # the option left out
    thinned = eval(written, {"result": result})
    assert len(thinned) == 6  # t = 0, 0.2, …, 1: every other state of the 10 steps
    np.testing.assert_array_equal(thinned, np.asarray(result["v(out)"])[::2])
