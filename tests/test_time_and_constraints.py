"""Engine contracts of driven models, affine and holonomic constraints.

The physics (orders against closed forms, power balance, linkages against reduced
solve_ivp references) is in test_driven.py and test_holonomic.py; here: how callables are
read, where each rule evaluates time and the affine term, bad input, initial data and
resumed runs.

White-box: reads internals of ``diracvi.driver``."""

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi.driver import checkpoint as _checkpoint


def _free_mass():
    return lambda q, v: 0.5 * v @ v


# ------------------------------------------------------------------ signatures
def test_time_argument_is_read_from_the_signature():
    auto = dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v)
    driven = dv.LagrangeDiracSystem(("x",), lambda q, v, t: 0.5 * v @ v, force=None)
    forced = dv.LagrangeDiracSystem(("x",), _free_mass(), force=lambda q, v, t: jnp.sin(t) + 0 * q)
    assert not auto.time_dependent
    assert driven.time_dependent and forced.time_dependent
    # a system's own methods (which take t) may be reused as another system's callables
    again = dv.LagrangeDiracSystem(("x",), forced.lagrangian, force=forced.force)
    assert again.time_dependent


@pytest.mark.parametrize(
    ("kwargs", "arg"),
    [
        ({"lagrangian": lambda q, v, t=0.0: 0.5 * v @ v}, "lagrangian"),
        ({"force": lambda q, v, *rest: -v}, "force"),
        ({"constraints": lambda q, t=0.0: jnp.ones((1, 2))}, "constraints"),
        ({"holonomic": lambda q, t=1.0: q[:1]}, "holonomic"),
    ],
)
def test_a_callable_that_accepts_both_forms_is_refused(kwargs, arg):
    args = {"lagrangian": lambda q, v: 0.5 * v @ v, **kwargs}
    with pytest.raises(dv.ModelError, match=rf"{arg}=.*ambiguous.*Fix"):
        dv.LagrangeDiracSystem(("x", "y"), **args)


def test_a_callable_of_the_wrong_arity_names_both_forms():
    with pytest.raises(dv.ModelError, match=r"force=.*F\(q, v\) or as F\(q, v, t\)"):
        dv.LagrangeDiracSystem(("x",), _free_mass(), force=lambda q: -q)


def test_a_driven_callable_that_fails_names_the_argument_and_its_form():
    with pytest.raises(dv.ModelError, match=r"force failed when JAX traced it as F\(q, v, t\)"):
        dv.LagrangeDiracSystem(("x",), _free_mass(), force=lambda q, v, t: np.sin(t) * v)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"holonomic": lambda q: q @ q - 1.0}, r"holonomic returned shape \(\)"),
        ({"holonomic": lambda q: jnp.zeros((1, 2))}, r"holonomic returned shape \(1, 2\)"),
        (
            {"constraints": jnp.eye(2)[:1], "constraint_offset": jnp.zeros(2)},
            r"constraint_offset has shape \(2,\).*\(1,\)",
        ),
        (
            {"constraints": jnp.eye(2)[:1], "constraint_offset": lambda q, t: q},
            r"constraint_offset has shape \(2,\)",
        ),
        ({"constraint_offset": [1.0]}, "without constraints"),
        (
            {"holonomic": lambda q: q[:1], "holonomic_names": ("a", "b")},
            "holonomic_names has 2 names",
        ),
        (
            {
                "constraints": jnp.eye(2)[:1],
                "constraint_names": ("c",),
                "holonomic": lambda q: q[1:],
                "holonomic_names": ("c",),
            },
            "share",
        ),
    ],
)
def test_bad_constraints_name_the_argument(kwargs, message):
    with pytest.raises(dv.ModelError, match=message):
        dv.LagrangeDiracSystem(("x", "y"), lambda q, v: 0.5 * v @ v, **kwargs)


def test_t0_must_be_a_finite_number():
    system = dv.LagrangeDiracSystem(("x",), _free_mass())
    with pytest.raises(dv.ModelError, match="t0=nan must be finite"):
        dv.simulate(system, [0.0], [1.0], dt=0.1, steps=2, t0=float("nan"))


# --------------------------------------------------------- the affine term b
@pytest.mark.parametrize("rule", ["retraction", "midpoint"])
@pytest.mark.parametrize("scheme", ["plus", "minus"])
def test_prescribed_velocity_is_the_rules_quadrature_of_it(rule, scheme):
    """ẋ = u(t) by A v + b = 0 with A = [1], b = −u(t): the positions are exactly the
    rule's quadrature of ∫u dt (left-point t_k, or t_{k+1} for the (−) retraction
    constraint; midpoint t_k + h/2), here summed independently in NumPy."""

    def u(t):
        return jnp.cos(3.0 * t) + t

    system = dv.LagrangeDiracSystem(
        ("x", "y"),
        lambda q, v: 0.5 * v @ v - 0.5 * q[1] ** 2,
        constraints=[[1.0, 0.0]],
        constraint_offset=lambda q, t: jnp.array([-u(t)]),
    )
    h, steps, t0 = 0.01, 300, 0.7
    traj = dv.simulate(
        system, [0.0, 1.0], [0.0, 0.0], dt=h, steps=steps, t0=t0, scheme=scheme, discretization=rule
    )
    sign = 1.0 if scheme == "plus" else -1.0
    j = np.arange(steps)
    tk = t0 + h * j if scheme == "plus" else t0 - h * (j + 1)  # earlier end of each step
    node = {"retraction": tk if scheme == "plus" else tk + h, "midpoint": tk + h / 2}[rule]
    expected = np.concatenate([[0.0], np.cumsum(sign * h * np.asarray(u(node)))])
    np.testing.assert_allclose(traj.q[:, 0], expected, rtol=0, atol=1e-12)
    assert np.max(np.abs(traj.constraint_residual)) <= 1e-12
    assert traj.solver == "affine step map"  # a driven linear model keeps the fast path


def test_time_nodes_of_a_driven_force_per_rule():
    """A free mass pushed by F(t): p_{k+1} − p_k is the rule's quadrature of ∫F dt, so
    the left-point rule sees F(t_k) and the midpoint rule F(t_k + h/2)."""

    def push(q, v, t):
        return jnp.array([jnp.exp(t)])

    system = dv.LagrangeDiracSystem(("x",), _free_mass(), force=push)
    h, steps, t0 = 0.05, 40, -0.3
    for rule, shift in (("retraction", 0.0), ("midpoint", 0.5)):
        traj = dv.simulate(system, [0.0], [0.0], dt=h, steps=steps, t0=t0, discretization=rule)
        tk = t0 + h * np.arange(steps)
        np.testing.assert_allclose(np.diff(traj.p[:, 0]), h * np.exp(tk + shift * h), rtol=1e-13)


# ------------------------------------------------------ holonomic constraints
def _pendulum():
    return dv.LagrangeDiracSystem(
        ("x", "y"),
        lambda q, v: 0.5 * v @ v - 9.81 * q[1],
        holonomic=lambda q: jnp.array([q @ q - 1.0]),
        holonomic_names=("rod",),
    )


def test_holonomic_rows_are_reported_by_name_and_hold_every_step():
    traj = dv.simulate(_pendulum(), [0.6, -0.8], [0.0, 0.0], dt=0.01, steps=300, scheme="minus")
    assert traj.constraint_names == ("rod",)
    assert np.max(np.abs(np.sum(traj.q**2, axis=1) - 1.0)) <= 1e-13
    np.testing.assert_allclose(traj.multiplier("rod"), traj.multipliers[:, 0])


def test_initial_state_off_the_holonomic_constraint_is_reported_and_projected():
    system = _pendulum()
    with pytest.warns(dv.InconsistentInitialDataWarning, match=r"holonomic constraints \['rod'\]"):
        dv.simulate(system, [0.6, -0.9], [0.0, 0.0], dt=0.01, steps=2)
    traj = dv.simulate(system, [0.6, -0.9], [0.0, 0.0], dt=0.01, steps=2, project_initial=True)
    assert abs(traj.q[0] @ traj.q[0] - 1.0) <= 1e-14
    # the least change: straight towards the circle, along the radius
    np.testing.assert_allclose(traj.q[0], np.array([0.6, -0.9]) / np.hypot(0.6, 0.9), atol=1e-14)


# ----------------------------------------------------------------- resuming
def test_a_killed_driven_newton_run_resumes_bitwise(tmp_path, monkeypatch):
    """The step times come from the integer step index, so a run resumed from its
    checkpoint sees exactly the times (and so the numbers) of an uninterrupted one."""
    system = dv.LagrangeDiracSystem(
        ("x",),
        lambda q, v, t: 0.5 * v @ v - 0.25 * q[0] ** 4,
        force=lambda q, v, t: jnp.array([jnp.cos(1.3 * t)]) - 0.1 * v,
    )
    args = dict(dt=0.01, steps=300, t0=0.123, discretization="midpoint", checkpoint_every=100)
    whole = dv.simulate(system, [0.5], [0.0], checkpoint=tmp_path / "whole.nc", **args)
    assert "Newton" in whole.solver
    write, calls = _checkpoint.write, []

    def killed(*a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt  # the process dies after its first chunk is on disk
        write(*a, **k)

    monkeypatch.setattr(_checkpoint, "write", killed)
    with pytest.raises(KeyboardInterrupt):
        dv.simulate(system, [0.5], [0.0], checkpoint=tmp_path / "run.nc", **args)
    monkeypatch.setattr(_checkpoint, "write", write)
    resumed = dv.simulate(system, [0.5], [0.0], checkpoint=tmp_path / "run.nc", **args)
    for field in ("t", "q", "p", "energy", "multipliers", "newton_iterations"):
        np.testing.assert_array_equal(getattr(resumed, field), getattr(whole, field), field)
    # another t0 is another run: its checkpoint is not reused
    with pytest.raises(dv.ModelError, match="different run"):
        dv.simulate(system, [0.5], [0.0], checkpoint=tmp_path / "run.nc", **{**args, "t0": 0.0})


# --------------------------------------------------------------- partitioned
@pytest.mark.slow  # compiles the partitioned and the dense solver (~15–25 s)
def test_partitioned_solver_steps_driven_subsystems():
    """A chain torn into 6 pieces, each pushed by F(t) (alike pieces: one vmapped group),
    a holonomic-free nonlinear spring so Newton runs: equal to plain dense Newton."""

    def piece(q, v, t):
        return 0.5 * v[1] ** 2 - 0.5 * (q[1] - q[0]) ** 2 - 0.01 * (q[1] - q[0]) ** 4

    def push(q, v, t):
        return jnp.array([0.0, 0.2 * jnp.sin(2.0 * t + q[1])])

    first = dv.LagrangeDiracSystem(("q",), lambda q, v: 0.5 * v @ v - 0.5 * q @ q, name="p0")
    pieces = [first] + [
        dv.LagrangeDiracSystem(("qbar", "q"), piece, force=push, name=f"p{j}") for j in range(1, 6)
    ]
    links = [dv.connect(f"p{j - 1}.q", f"p{j}.qbar") for j in range(1, 6)]
    system = dv.interconnect(pieces, links)
    q0 = np.array([0.0] + [x for j in range(1, 6) for x in (j - 1.0, float(j))])
    p0 = np.zeros_like(q0)
    args = dict(dt=0.02, steps=60, t0=0.5, discretization="midpoint")
    part = dv.simulate(system, q0, p0, solver=dv.PartitionedSolver(), **args)
    dense = dv.simulate(system, q0, p0, solver=dv.NewtonSolver(reuse_jacobian=False), **args)
    # the driven pieces with a link on either side are stepped as one vmapped group
    groups = dv.PartitionedSolver.layout(system, "midpoint").groups
    assert tuple(f"p{j}" for j in range(1, 5)) in groups
    np.testing.assert_allclose(part.q, dense.q, rtol=0, atol=1e-12 * np.max(np.abs(dense.q)))
    np.testing.assert_allclose(part.p_nodal, dense.p_nodal, rtol=0, atol=1e-11)
    np.testing.assert_allclose(part.energy, dense.energy, rtol=1e-12)
