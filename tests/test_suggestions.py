"""Where an error message suggests a value, the suggestion works: each test triggers the
error, reads the suggested value out of the message, applies it, and checks that the call
then succeeds (and, where the message promises more — "the end of the run", "at most half
the horizon" — that too). A message whose suggested value is wrong fails here."""

from __future__ import annotations

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
