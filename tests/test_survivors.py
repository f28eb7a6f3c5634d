"""Tests written against mutants that survived the suite (issue 18): each one fails when the
named piece of the library is wrong. See also test_reference_steps.py."""

import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems


# ------------------------------------------------ affine verification tolerance
def weak_cubic_spring(top):
    """An oscillator with a cubic spring term of strength 1e-6 beyond ``q = top``."""

    def lagrangian(q, v):
        beyond = jnp.where(q[0] > top, q[0] - top, 0.0)
        return 0.5 * v[0] ** 2 - 0.5 * q[0] ** 2 - 0.25e-6 * beyond**4

    return dv.LagrangeDiracSystem(("x",), lagrangian, name="weak")


@pytest.mark.parametrize(
    ("top", "solver"),
    [
        (0.5, None),  # detection sees a linear model at its three points; the term acts later
        (-10.0, dv.AffineSolver(detect_rtol=5e-4)),  # detection loosened by the user
    ],
    ids=["missed-by-detection", "loose-detection"],
)
def test_weak_nonlinearity_is_caught_by_the_per_step_verification(top, solver):
    """A 1e-6 nonlinearity: the affine path must fall back to Newton (or equal it) to 1e-12."""
    system = weak_cubic_spring(top)
    kwargs = {"dt": 0.01, "steps": 300}
    fast = dv.simulate(system, [0.0], [1.0], solver=solver, **kwargs)
    newton = dv.simulate(system, [0.0], [1.0], solver=dv.NewtonSolver(), **kwargs)
    np.testing.assert_allclose(fast.q, newton.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.p, newton.p, rtol=0, atol=1e-12)
    assert fast.solver.startswith("affine step map, then NewtonSolver")  # it fell back


# ----------------------------------------------------------- ensemble warning row
def test_ensemble_warns_for_an_inconsistent_member_beside_a_consistent_one():
    problem = problems.get("rlc-torn")
    good_q, good_p = problem.q0, problem.p0
    bad_q = good_q.copy()
    bad_q[problem.system.coords.index("cap.qS2")] += 0.5  # joined ports apart
    kwargs = {"dt": 0.01, "steps": 3}
    for rows in ([good_q, bad_q], [bad_q, good_q]):  # the inconsistent one first or second
        with pytest.warns(dv.InconsistentInitialDataWarning, match="5.000e-01"):
            dv.simulate_ensemble(problem.system, np.stack(rows), np.stack([good_p] * 2), **kwargs)
    with warnings.catch_warnings():
        warnings.simplefilter("error", dv.InconsistentInitialDataWarning)
        dv.simulate_ensemble(
            problem.system, np.stack([good_q] * 2), np.stack([good_p] * 2), **kwargs
        )


# ---------------------------------------------------------------- NetCDF fields
ARRAYS = (
    "t",
    "q",
    "p",
    "multipliers",
    "energy",
    "constraint_residual",
    "constraint_violation",
    "newton_iterations",
    "step_index",
)
SCALARS = (
    "coords",
    "constraint_names",
    "dt",
    "scheme",
    "discretization",
    "system_name",
    "status",
    "message",
    "steps_requested",
    "save_every",
    "solver",
    "steps",
)


def assert_round_trip(traj, back):
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(back, name), getattr(traj, name), err_msg=name)
    for name in SCALARS:
        assert getattr(back, name) == getattr(traj, name), name
    assert len(back.final_state) == len(traj.final_state) == 4
    for a, b in zip(back.final_state, traj.final_state, strict=True):
        np.testing.assert_array_equal(a, b)


def test_every_trajectory_field_survives_netcdf(tmp_path):
    problem = problems.get("double-pendulum-torn")
    traj = dv.simulate(
        problem.system,
        problem.q0,
        problem.p0,
        dt=0.01,
        steps=40,
        save_every=4,
        scheme="minus",
        discretization="midpoint",
        solver=dv.NewtonSolver(),
    )
    # the fields are not their defaults, so a field that is not written is noticed
    assert traj.save_every == 4 and traj.system_name == "pendulum" and traj.solver
    assert not np.array_equal(traj.final_state[2], traj.q[-1])
    assert_round_trip(traj, dv.load(traj.save(tmp_path / "pendulum.nc")))


def test_a_failed_run_saved_with_throw_false_round_trips(tmp_path):
    cliff = dv.LagrangeDiracSystem(
        ("q",), lambda q, v: 0.5 * v @ v + jnp.sqrt(1.0 - q[0]), name="cliff"
    )
    traj = dv.simulate(cliff, [0.0], [2.0], dt=0.01, steps=500, throw=False)
    assert traj.status != 0 and traj.steps < traj.steps_requested == 500
    back = dv.load(traj.save(tmp_path / "failed.nc"))
    assert_round_trip(traj, back)
    assert not back.success and "NaN or Inf" in back.message


# ------------------------------------------- resume carry: a killed Newton run
FIELDS = ("t", "q", "p", "multipliers", "energy", "constraint_residual", "newton_iterations")
PENDULUM_SCRIPT = """
import sys
import diracvi as dv
from diracvi import problems
problem = problems.get("double-pendulum-torn")
dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps={steps},
            solver=dv.NewtonSolver(), checkpoint=sys.argv[1], checkpoint_every={every})
"""


def run_pendulum(path, steps, every):
    problem = problems.get("double-pendulum-torn")
    return dv.simulate(
        problem.system,
        problem.q0,
        problem.p0,
        dt=0.01,
        steps=steps,
        solver=dv.NewtonSolver(),
        checkpoint=path,
        checkpoint_every=every,
    )


def test_killed_newton_run_resumes_bitwise_including_iteration_counts(tmp_path):
    """Newton's first guess extrapolates from q_{k−1} and the last μ: the carry the
    checkpoint keeps. A resumed run that lost it converges to round-off nearby, in a
    different number of iterations — bitwise equality catches both."""
    steps, every = 6_000, 500
    path = tmp_path / "killed.nc"
    script = tmp_path / "long_run.py"
    script.write_text(PENDULUM_SCRIPT.format(steps=steps, every=every))
    env = {**os.environ, "PYTHONPATH": str(Path(dv.__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, str(script), str(path)], env=env)
    try:
        deadline = time.monotonic() + 300
        while not path.exists():
            if proc.poll() is not None:
                pytest.fail(f"the run ended (code {proc.returncode}) before it was killed")
            if time.monotonic() > deadline:
                pytest.fail("no checkpoint appeared within 300 s")
            time.sleep(0.005)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
    partial = dv.load(path)
    assert every <= partial.steps < steps and partial.steps % every == 0
    resumed = run_pendulum(path, steps, every)
    whole = run_pendulum(tmp_path / "whole.nc", steps, every)
    assert resumed.steps == steps and np.sum(whole.newton_iterations) > steps
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(resumed, field), getattr(whole, field), field)
