"""Long runs write completed chunks atomically; a killed run resumes bitwise identically."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import diracvi as dv
from diracvi import problems

FIELDS = ("t", "q", "p", "multipliers", "energy", "constraint_residual", "newton_iterations")
SCRIPT = """
import sys
import diracvi as dv
from diracvi import problems
problem = problems.get("rlc-torn")
dv.simulate(problem.system, problem.q0, problem.p0, dt=0.001, steps={steps},
            checkpoint=sys.argv[1], checkpoint_every={every})
"""


def assert_bitwise_equal(a, b):
    for field in FIELDS:
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)


def run_rlc(path, steps, every):
    problem = problems.get("rlc-torn")
    return dv.simulate(
        problem.system,
        problem.q0,
        problem.p0,
        dt=0.001,
        steps=steps,
        checkpoint=path,
        checkpoint_every=every,
    )


def test_checkpointed_run_equals_a_plain_run_and_is_readable(tmp_path):
    path = tmp_path / "run.nc"
    traj = run_rlc(path, 1000, 300)
    problem = problems.get("rlc-torn")
    plain = dv.simulate(problem.system, problem.q0, problem.p0, dt=0.001, steps=1000)
    np.testing.assert_allclose(traj.q, plain.q, rtol=0, atol=1e-13)
    assert_bitwise_equal(dv.load(path), traj)
    # asking again returns the finished run from disk, bit for bit
    assert_bitwise_equal(run_rlc(path, 1000, 300), traj)


def test_checkpoint_of_another_run_is_refused(tmp_path):
    path = tmp_path / "run.nc"
    run_rlc(path, 100, 50)
    with pytest.raises(dv.ModelError, match="different run"):
        run_rlc(path, 200, 50)


@pytest.mark.slow  # 13 s; tests/test_survivors.py kills and resumes a Newton run by default
def test_killed_run_resumes_bitwise_identically(tmp_path):
    steps, every = 200_000, 10_000
    path = tmp_path / "killed.nc"
    script = tmp_path / "long_run.py"
    script.write_text(SCRIPT.format(steps=steps, every=every))
    env = {**os.environ, "PYTHONPATH": str(Path(dv.__file__).parents[1])}
    proc = subprocess.Popen([sys.executable, str(script), str(path)], env=env)
    try:
        # kill as soon as the first chunk is on disk: polling is a cheap stat, so a loaded
        # machine cannot let the remaining chunks finish before the kill lands
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
    resumed = run_rlc(path, steps, every)
    assert resumed.steps == steps
    uninterrupted = run_rlc(tmp_path / "whole.nc", steps, every)
    assert_bitwise_equal(resumed, uninterrupted)
    assert not list(tmp_path.glob(".*.tmp"))
