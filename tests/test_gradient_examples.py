"""The two gradient examples (docs/gradients.md), run lean: identification of the RLC
and optimal control of a driven pendulum."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _load(name):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# 32 s, in `-m slow` (CI time): gradients through a run by default in tests/test_gradients.py
# (test_forward_and_reverse_mode_agree_with_central_differences); the example's statistics here
@pytest.mark.slow
def test_rlc_identification_recovers_values_within_three_standard_errors():
    example = _load("identify_rlc")
    estimate, errors, data, fitted = example.identify(steps=100, seed=1)
    assert np.all(errors > 0) and np.all(errors < 0.05 * example.TRUE)
    assert np.all(np.abs(estimate - example.TRUE) <= 3 * errors), (estimate, errors)
    # the residuals are noise-sized at the optimum
    assert abs(np.std(data - fitted) / example.SIGMA - 1) < 0.2


@pytest.mark.slow  # ~30 s of L-BFGS; the identification example stays in the default run
def test_optimal_control_reaches_the_target_state():
    example = _load("optimal_control_pendulum")
    controls, history = example.optimize(iterations=15, steps=50)
    traj = example.run(controls, steps=50)
    assert history[-1] < 1e-3 * history[0]
    assert abs(float(traj.q[-1, 0]) - example.TARGET) < 2e-3
    assert abs(float(traj.p[-1, 0])) < 2e-3
