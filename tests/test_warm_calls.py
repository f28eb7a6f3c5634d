"""A warm ``simulate`` (plan cached, the quick consistency check, a whole run returned
from one compiled chunk) checks exactly what a cold call checks, and returns what the
general chunk-by-chunk march returns.

White-box: reads internals of ``diracvi.driver``."""

import pickle

import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.driver import simulate as _simulate


@pytest.fixture(scope="module")
def chain():
    problem = problems.get("spring-chain-torn")
    # warm: the plan, its checker and the compiled chunk of this configuration exist
    dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps=20)
    return problem


@pytest.mark.parametrize(
    ("change", "needles"),
    [
        ({"q0": np.array([0.0, np.nan, 1.0, 2.0])}, ["q0", "not finite", "left.q2"]),
        ({"p0": np.array([0.0, 0.0, np.inf, 3.0])}, ["p0", "not finite", "right.q2bar"]),
        ({"q0": np.zeros(3)}, ["q0", "(3,)", "length 4"]),
        ({"dt": -0.01}, ["dt=-0.01", "> 0"]),
        ({"dt": np.inf}, ["dt=inf", "finite"]),
        ({"steps": True}, ["steps=True", "whole number"]),
        ({"steps": 0}, ["steps=0", "≥ 1"]),
        ({"t0": np.nan}, ["t0=nan", "finite"]),
        ({"save_every": 3}, ["save_every=3", "does not divide steps=20"]),
    ],
)
def test_a_warm_call_still_rejects_bad_arguments(chain, change, needles):
    args = {"q0": chain.q0, "p0": chain.p0, "dt": 0.01, "steps": 20, **change}
    with pytest.raises(dv.ModelError) as info:
        dv.simulate(chain.system, args.pop("q0"), args.pop("p0"), **args)
    for needle in needles:
        assert needle in str(info.value)


@pytest.mark.parametrize("offset", [0.25, 1e-9])
def test_a_warm_call_still_reports_joined_ports_apart(chain, offset):
    q0 = chain.q0.copy()
    q0[2] += offset  # right.q2bar no longer at left.q2
    with pytest.warns(dv.InconsistentInitialDataWarning, match="joined ports differ"):
        dv.simulate(chain.system, q0, chain.p0, dt=0.01, steps=20)
    fixed = dv.simulate(chain.system, q0, chain.p0, dt=0.01, steps=20, project_initial=True)
    assert fixed.q[0, 1] == fixed.q[0, 2]


def test_a_warm_call_still_reports_momenta_a_degenerate_lagrangian_forbids(recwarn):
    problem = problems.get("lc")
    kwargs = {"dt": 0.01, "steps": 20, "discretization": "midpoint"}
    dv.simulate(problem.system, problem.q0, problem.p0, **kwargs)
    assert not [w for w in recwarn if issubclass(w.category, dv.InconsistentInitialDataWarning)]
    p0 = problem.p0 + np.array([0.0, 1e-7, 0.0])
    with pytest.warns(dv.InconsistentInitialDataWarning, match="momenta a degenerate"):
        dv.simulate(problem.system, problem.q0, p0, **kwargs)


def test_a_whole_run_returns_what_the_chunked_march_returns(chain, tmp_path):
    """The direct path (one chunk, every step taken, fields unpacked on first access)
    against the general march, which a checkpointed run takes."""
    kwargs = {"dt": 0.01, "steps": 20, "save_every": 2}
    fast = dv.simulate(chain.system, chain.q0, chain.p0, **kwargs)
    march = dv.simulate(chain.system, chain.q0, chain.p0, checkpoint=tmp_path / "c.nc", **kwargs)
    for name in (
        "t",
        "q",
        "p",
        "p_nodal",
        "multipliers",
        "energy",
        "constraint_residual",
        "constraint_violation",
        "newton_iterations",
        "step_index",
    ):
        np.testing.assert_array_equal(getattr(fast, name), getattr(march, name), err_msg=name)
    for a, b in zip(fast.final_state, march.final_state, strict=True):
        np.testing.assert_array_equal(a, b)
    assert (fast.solver, fast.status, fast.message, fast.steps) == (
        march.solver,
        march.status,
        march.message,
        march.steps,
    )
    copy = pickle.loads(pickle.dumps(dv.simulate(chain.system, chain.q0, chain.p0, **kwargs)))
    np.testing.assert_array_equal(copy.multipliers, fast.multipliers)
    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        fast.nonsense  # noqa: B018


def test_a_warm_call_takes_the_configurations_path_and_returns_the_same_run(chain, monkeypatch):
    """The second call of a configuration skips the configuration's checks and plan
    (they would raise here) and returns, bitwise, what the first call returned; the
    trajectory keeps its own copy of the initial state."""
    kwargs = {"dt": 0.01, "steps": 20, "save_every": 4}
    first = dv.simulate(chain.system, chain.q0, chain.p0, **kwargs)

    def refused(*args, **kw):
        raise AssertionError("the configuration was checked again")

    monkeypatch.setattr(_simulate, "check_run", refused)
    q0, p0 = chain.q0.copy(), chain.p0.copy()
    warm = dv.simulate(chain.system, q0, p0, **kwargs)
    q0[:] = 99.0  # the caller's arrays change after the call
    p0[:] = 99.0
    for name in ("t", "q", "p", "p_nodal", "multipliers", "energy", "constraint_residual"):
        np.testing.assert_array_equal(getattr(warm, name), getattr(first, name), err_msg=name)
    assert (warm.solver, warm.status, warm.steps, warm.coords) == (
        first.solver,
        first.status,
        first.steps,
        first.coords,
    )
    # another t0 is a value of the call, not of the configuration
    later = dv.simulate(chain.system, chain.q0, chain.p0, t0=2.5, **kwargs)
    np.testing.assert_array_equal(later.t, first.t + 2.5)
    np.testing.assert_array_equal(later.q, first.q)


def test_the_programs_input_verdict_agrees_with_the_initial_data_check(chain):
    """A warm call trusts the verdict computed inside the compiled chunk: it must accept
    exactly the data the checker's linear test accepts, and refuse non-finite data."""
    system = chain.system
    run = _simulate.check_run(system, "plus", "retraction", 0.01, 20, 1, None)
    plan = _simulate.prepared_plan(system, run, None, chain.q0, chain.p0)
    chunk = plan.chunk(plan.step_map is not None, 1, True, 20)
    assert chunk.layout.verdict is not None
    rng = np.random.default_rng(7)
    verdicts, accepted = [], []
    for scale in (0.0, 1e-15, 1e-13, 3e-13, 1e-12, 1e-11, 1e-9, 1e-3):
        for _ in range(3):
            q0 = chain.q0 + scale * rng.standard_normal(4)
            p0 = chain.p0 + scale * rng.standard_normal(4)
            x = chunk.flat_input(plan.h_array, (0.0, 0.0), (q0, p0, q0, np.zeros(system.m)))
            verdicts.append(chunk.run(x)[chunk.layout.verdict])
            accepted.append(plan.checker.accepts(q0, p0))
    verdicts = np.array(verdicts)
    np.testing.assert_array_equal(verdicts <= 1.0, accepted)
    assert any(accepted) and not all(accepted)  # both sides of the test were reached
    bad = chain.q0.copy()
    bad[0] = np.nan
    x = chunk.flat_input(plan.h_array, (0.0, 0.0), (bad, chain.p0, bad, np.zeros(system.m)))
    assert chunk.run(x)[chunk.layout.verdict] == np.inf
