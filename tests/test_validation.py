"""Bad input raises an error naming the argument, the value and the fix — before stepping."""

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv


def quadratic(q, v):
    return 0.5 * v @ v - 0.5 * q @ q


@pytest.fixture
def system():
    return dv.LagrangeDiracSystem(("a", "b"), quadratic, constraints=[[1.0, -1.0]])


def good(**kw):
    return {"dt": 0.01, "steps": 10, **kw}


@pytest.mark.parametrize(
    ("kwargs", "needles"),
    [
        ({"q0": [0.0, 1.0, 2.0]}, ["q0", "(3,)", "length 2"]),
        ({"p0": [0.0]}, ["p0", "(1,)", "length 2"]),
        ({"q0": [np.nan, 0.0]}, ["q0", "not finite", "['a']"]),
        ({"p0": [0.0, np.inf]}, ["p0", "not finite", "['b']"]),
        ({"steps": 0}, ["steps=0", "≥ 1"]),
        ({"steps": -3}, ["steps=-3", "≥ 1"]),
        ({"steps": 2.5}, ["steps=2.5", "whole number"]),
        ({"dt": 0.0}, ["dt=0.0", "> 0"]),
        ({"dt": -0.1}, ["dt=-0.1", "> 0"]),
        ({"dt": float("nan")}, ["dt=nan", "finite"]),
        ({"dt": "0.1"}, ["dt='0.1'", "real number"]),
        ({"scheme": "forward"}, ["scheme='forward'", "'plus'", "'minus'"]),
        ({"discretization": "rk4"}, ["discretization='rk4'", "'retraction'", "'midpoint'"]),
    ],
)
def test_simulate_rejects_bad_arguments(system, kwargs, needles):
    args = {"q0": [0.0, 0.0], "p0": [1.0, 1.0], **good(), **kwargs}
    q0, p0 = args.pop("q0"), args.pop("p0")
    with pytest.raises(dv.ModelError) as info:
        dv.simulate(system, q0, p0, **args)
    for needle in needles:
        assert needle in str(info.value)


@pytest.mark.parametrize(
    ("kwargs", "needles"),
    [
        ({"lagrangian": lambda q, v: v}, ["lagrangian", "shape (2,)", "scalar"]),
        ({"lagrangian": "L"}, ["lagrangian='L'", "callable"]),
        ({"lagrangian": lambda q, v: q[5] + undefined}, ["lagrangian failed", "NameError"]),  # noqa: F821
        ({"constraints": [[1.0, 0.0, 0.0]]}, ["constraints", "(1, 3)", "(m, 2)"]),
        ({"constraints": lambda q: jnp.ones(3)}, ["constraints returned shape (3,)", "(m, 2)"]),
        ({"constraints": [[1.0, np.nan]]}, ["constraints", "NaN"]),
        ({"force": lambda q, v: jnp.zeros(3)}, ["force returned shape (3,)", "(2,)"]),
        ({"coords": ("a", "a")}, ["coords repeats ['a']"]),
        ({"coords": ()}, ["coords=() is empty"]),
        ({"coords": "ab"}, ["coords='ab'", "sequence of names"]),
        ({"name": "my.system"}, ["name='my.system'", "without dots"]),
        ({"constraint_names": ("x", "y")}, ["constraint_names has 2 names", "1 constraint"]),
    ],
)
def test_system_construction_rejects_bad_models(kwargs, needles):
    args = {
        "coords": ("a", "b"),
        "lagrangian": quadratic,
        "constraints": [[1.0, -1.0]],
        **kwargs,
    }
    with pytest.raises(dv.ModelError) as info:
        dv.LagrangeDiracSystem(**args)
    for needle in needles:
        assert needle in str(info.value)


def test_simulate_rejects_non_systems():
    with pytest.raises(dv.ModelError, match="not a diracvi system"):
        dv.simulate(quadratic, [0.0], [0.0], dt=0.1, steps=1)


def test_unsolvable_step_names_the_coordinates():
    """A coordinate with no velocity term and no constraint is left undetermined."""
    system = dv.LagrangeDiracSystem(("x", "port"), lambda q, v: 0.5 * v[0] ** 2 - q[1] ** 2)
    with pytest.raises(dv.UnsolvableStepError) as info:
        dv.simulate(system, [0.0, 0.0], [1.0, 0.0], dt=0.1, steps=5)
    message = str(info.value)
    assert "q_{k+1}[port]" in message and "q_{k+1}[x]" not in message
    assert "momentum balance of port" in message


def test_a_traced_step_is_refused_by_name():
    """q0, p0, t0 and parameters may be traced (tests/test_gradients.py); dt may not."""
    import jax

    from diracvi import problems

    problem = problems.get("damped-oscillator")

    def traced(dt):
        return dv.simulate(problem.system, problem.q0, problem.p0, dt=dt, steps=3).q

    with pytest.raises(dv.ModelError, match="dt is a JAX tracer, but dt must be a concrete"):
        jax.jit(traced)(0.01)
