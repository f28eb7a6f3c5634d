"""Fuzzing the public constructors and simulate(): every bad input ends in a diracvi error
with a message — never another exception, a crash or a hang."""

import jax.numpy as jnp
import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import diracvi as dv
from conftest import examples

EXPECTED = (dv.ModelError, dv.UnsolvableStepError, dv.StepFailure)

junk = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-3, 3),
    st.floats(allow_nan=True),
    st.text(max_size=4),
    st.lists(st.integers(-2, 2), max_size=3),
    st.just(object()),
)

lagrangians = st.sampled_from(
    [
        lambda q, v: 0.5 * v @ v - 0.5 * q @ q,  # fine
        lambda q, v: v,  # not a scalar
        lambda q, v: jnp.sum(v).astype(jnp.int32),  # wrong dtype
        lambda q, v: "energy",  # not an array
        lambda q, v: 0.5 * v @ v - q[7],  # index out of range (clipped by JAX)
        lambda q, v: 0.5 * v @ jnp.ones(5),  # shape mismatch
        lambda q, v: float(v[0]),  # concretizes a tracer
        lambda q, v: 0.5 * v @ v + jnp.log(q[0]),  # NaN for q ≤ 0 at run time
        lambda q, v: 1 / 0,  # raises
    ]
)

forms = st.one_of(
    st.none(),
    junk,
    st.builds(
        lambda r, c, bad: np.where(np.arange(r * c).reshape(r, c) == 0, bad, 1.0),
        st.integers(0, 3),
        st.integers(0, 4),
        st.sampled_from([1.0, np.nan, np.inf]),
    ),
    st.sampled_from([lambda q: q, lambda q: jnp.ones((1, 2)), lambda q: jnp.ones((1, 9))]),
)


@examples(60)
@given(
    coords=st.one_of(junk, st.lists(st.sampled_from(["x", "y", "", " z", "x"]), max_size=3)),
    lagrangian=lagrangians,
    constraints=forms,
    force=st.one_of(st.none(), junk, st.sampled_from([lambda q, v: -v, lambda q, v: v[:1]])),
    name=st.one_of(st.none(), junk, st.sampled_from(["ok", "a.b", " "])),
)
def test_construction_fails_cleanly(coords, lagrangian, constraints, force, name):
    try:
        dv.LagrangeDiracSystem(coords, lagrangian, constraints=constraints, force=force, name=name)
    except dv.ModelError as exc:
        assert str(exc)


@examples(25)
@given(
    lagrangian=lagrangians,
    q0=st.one_of(junk, st.lists(st.floats(-2, 2), min_size=2, max_size=2)),
    p0=st.one_of(junk, st.lists(st.floats(-2, 2), min_size=2, max_size=2)),
    dt=st.one_of(junk, st.floats(1e-3, 0.1)),
    steps=st.one_of(junk, st.integers(1, 20)),
    scheme=st.sampled_from(["plus", "minus", "sideways"]),
)
def test_simulate_fails_cleanly(lagrangian, q0, p0, dt, steps, scheme):
    try:
        system = dv.LagrangeDiracSystem(("x", "y"), lagrangian)
        traj = dv.simulate(system, q0, p0, dt=dt, steps=steps, scheme=scheme)
    except EXPECTED as exc:
        assert str(exc)
        if isinstance(exc, dv.StepFailure):
            assert exc.trajectory.status != 0
    else:
        assert traj.success and np.all(np.isfinite(traj.q))


@examples(12)
@given(
    lagrangian=lagrangians,
    q0=st.lists(st.floats(-2, 2), min_size=2, max_size=2),
    p0=st.lists(st.floats(-2, 2), min_size=2, max_size=2),
    discretization=st.sampled_from(["retraction", "midpoint"]),
)
def test_simulate_with_valid_data_and_any_model_fails_cleanly(lagrangian, q0, p0, discretization):
    """Valid arguments, so every model reaches the solver: errors arise at run time."""
    try:
        system = dv.LagrangeDiracSystem(("x", "y"), lagrangian)
        traj = dv.simulate(system, q0, p0, dt=0.01, steps=20, discretization=discretization)
    except EXPECTED as exc:
        assert str(exc)
    else:
        assert traj.success and np.all(np.isfinite(traj.q))
