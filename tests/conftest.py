import numpy as np
import pytest
from hypothesis import HealthCheck, settings

import diracvi as dv

settings.register_profile(
    "default",
    max_examples=15,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    derandomize=True,
)
settings.load_profile("default")


def run(problem, **overrides):
    """Simulate a built-in problem with its own step and horizon unless overridden."""
    kwargs = {"dt": problem.dt, "steps": problem.steps, "t0": problem.t0, **overrides}
    return dv.simulate(problem.system, problem.q0, problem.p0, **kwargs)


def loglog_slope(hs, errors) -> float:
    """The fitted exponent r of error ≈ C h^r."""
    return float(np.polyfit(np.log(hs), np.log(errors), 1)[0])


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)
