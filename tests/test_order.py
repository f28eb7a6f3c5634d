"""Order of accuracy against exact solutions: the fitted log–log slope is the rule's order.

White-box: reads internals of ``diracvi.discretization.lobatto``."""

import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope
from diracvi import problems

HS = np.array([0.04, 0.02, 0.01])
ORDER = {"retraction": 1, "midpoint": 2}

#: the error constant C of error ≈ C h^p, measured (it is the same at every h of HS, and
#: at h = 0.005, to within 1.5 %); the tests allow 20 % above it. A scheme with the right
#: order but a wrong constant (a force or a node weighted wrongly) fails here, not on the
#: slope.
CONSTANT = {
    ("spring-chain", "retraction"): 0.502,
    ("spring-chain", "midpoint"): 0.565,
    ("lc", "midpoint"): 0.0582,
    ("rlc", "retraction"): 1.293,
    ("rlc", "midpoint"): 0.267,
    ("rolling-disk", "retraction"): 0.832,
    ("rolling-disk", "midpoint"): 0.123,
    ("damped-oscillator", "retraction"): 0.431,
    ("damped-oscillator", "midpoint"): 0.131,
    ("dc-motor", "retraction"): 1.606,
    ("dc-motor", "midpoint"): 0.546,
    ("spring-chain", "retraction", "minus"): 0.501,
}
MARGIN = 1.2


def assert_error_constant(key, hs, errors, order):
    constants = np.asarray(errors) / np.asarray(hs) ** order
    assert np.all(constants <= MARGIN * CONSTANT[key]), (key, constants)
    assert np.all(constants >= CONSTANT[key] / MARGIN), (key, constants)


def global_error(problem, discretization, h, horizon, scheme="plus"):
    steps = round(horizon / h)
    traj = dv.simulate(
        problem.system,
        problem.q0,
        problem.p0,
        dt=h,
        steps=steps,
        discretization=discretization,
        scheme=scheme,
    )
    return np.max(np.abs(traj.q - problem.exact(traj.t)))


@pytest.mark.parametrize(
    ("name", "discretization", "horizon"),
    [
        ("spring-chain", "retraction", 2.0),
        ("spring-chain", "midpoint", 2.0),
        ("lc", "midpoint", 2.0),
        ("rlc", "retraction", 2.0),
        ("rlc", "midpoint", 2.0),
        # order 1 is shown by spring chain and RLC (regular and degenerate, the latter
        # forced and constrained): these three with -m slow
        pytest.param("rolling-disk", "retraction", 2.0, marks=pytest.mark.slow),
        ("rolling-disk", "midpoint", 2.0),
        pytest.param("damped-oscillator", "retraction", 2.0, marks=pytest.mark.slow),
        ("damped-oscillator", "midpoint", 2.0),
        pytest.param("dc-motor", "retraction", 0.2, marks=pytest.mark.slow),
        ("dc-motor", "midpoint", 0.2),
    ],
)
def test_convergence_order(name, discretization, horizon):
    problem = problems.get(name)
    hs = HS * (0.1 if name == "dc-motor" else 1.0)
    errors = [global_error(problem, discretization, h, horizon) for h in hs]
    slope = loglog_slope(hs, errors)
    assert abs(slope - ORDER[discretization]) < 0.15, (slope, errors)
    assert_error_constant((name, discretization), hs, errors, ORDER[discretization])


def test_minus_scheme_converges_backward_in_time():
    problem = problems.get("spring-chain")
    errors = [global_error(problem, "retraction", h, 2.0, scheme="minus") for h in HS]
    assert abs(loglog_slope(HS, errors) - 1) < 0.15
    assert_error_constant(("spring-chain", "retraction", "minus"), HS, errors, 1)


def test_lc_circuit_under_the_left_point_rule_is_reported_unsolvable():
    """A capacitor loop leaves q_{k+1} of both capacitors undetermined (see circuits.py)."""
    problem = problems.get("lc")
    with pytest.raises(dv.UnsolvableStepError) as info:
        dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps=10)
    message = str(info.value)
    assert "not solvable at this state" in message
    assert "q_{k+1}[qC1]" in message and "q_{k+1}[qC2]" in message
    assert "midpoint" in message


# ------------------------------------------------------------------ order 4: "lobatto"
LOBATTO_HS = np.array([0.04, 0.02, 0.01])


def lobatto_errors(problem, horizon, hs=LOBATTO_HS):
    """Per-coordinate max error over the run at each h, shape (len(hs), n)."""
    rows = []
    for h in hs:
        traj = dv.simulate(
            problem.system,
            problem.q0,
            problem.p0,
            dt=h,
            steps=round(horizon / h),
            discretization="lobatto",
        )
        exact = problem.exact or problem.numerical_solution  # DOP853 where no closed form
        rows.append(np.max(np.abs(traj.q - exact(traj.t)), axis=0))
    return np.asarray(rows)


@pytest.mark.parametrize(
    "name",
    [
        # three Newton compilations each (≈ 10 s): with -m slow; the spring chain too (the
        # default suite's time on CI): the degenerate RLC's test below is regular too
        pytest.param("spring-chain", marks=pytest.mark.slow),
        "forced-oscillator",
        pytest.param("cartesian-pendulum", marks=pytest.mark.slow),
        pytest.param("rolling-disk", marks=pytest.mark.slow),
        pytest.param("chaplygin-sleigh", marks=pytest.mark.slow),
    ],
)
def test_lobatto_is_fourth_order(name):
    """Regular (spring chain), forced and driven (forced oscillator), nonholonomic
    (rolling disk; Chaplygin sleigh, vs its closed-form heading and DOP853 for the contact
    point) and holonomic (Cartesian pendulum, vs DOP853) models: slope 4."""
    errors = lobatto_errors(problems.get(name), 2.0).max(axis=1)
    assert abs(loglog_slope(LOBATTO_HS, errors) - 4.0) < 0.3, errors
    assert errors[-1] < 1e-7  # far below the midpoint rule's error at this h (≈ 1e-5)


def test_lobatto_is_fourth_order_in_every_coordinate_of_the_degenerate_rlc_circuit():
    """Paper §5.2's RLC (degenerate L, resistor, KCL): the resistor and capacitor charges
    obey a first-order equation (R q̇^R = −q^C/C); Lobatto IIID collocates it at all three
    stages, so they converge at order 4 like the inductor charge (a quadratic-path Galerkin
    rule, this rule's predecessor, gave order 2 there)."""
    errors = lobatto_errors(problems.get("rlc"), 2.0)
    slopes = [loglog_slope(LOBATTO_HS, errors[:, j]) for j in range(3)]  # qR, qL, qC
    assert np.all(np.abs(np.asarray(slopes) - 4.0) < 0.3), (slopes, errors)
    assert np.max(errors[-1]) < 1e-9, errors


def test_lobatto_stage_algebra_is_lobatto_iiid():
    """The hand-inverted stage map of :class:`~diracvi.Lobatto` is IIID's: the stage
    positions are ``q_k + h Σ a_ij V_j`` and the step ``q_k + h Σ b_j V_j`` for the
    velocities it returns, IIID is its own symplectic partner, and its ``a`` is
    invertible (a wrong coefficient, or IIIA/IIIB, fails one of these)."""
    from diracvi.discretization.lobatto import IIID, NODES, WEIGHTS

    a, b = np.array(IIID), np.array(WEIGHTS)
    rng = np.random.default_rng(0)
    qk, qk1, stage = rng.normal(size=3), rng.normal(size=3), rng.normal(size=(3, 2))
    h, tk = 0.3, 1.25
    nodes = dv.Lobatto.nodes(qk, stage, qk1, h, tk)
    vs = np.array([np.asarray(v) for _, v, _ in nodes])
    for i, (q, _, t) in enumerate(nodes):
        np.testing.assert_allclose(q, qk + h * a[i] @ vs, atol=1e-13)
        assert t == tk + NODES[i] * h
    np.testing.assert_allclose(qk1, qk + h * b @ vs, atol=1e-13)
    np.testing.assert_allclose(b[:, None] * a + (b[:, None] * a).T, np.outer(b, b), atol=1e-15)
    assert abs(np.linalg.det(a)) > 1e-3
    # order conditions of a 4th-order Runge–Kutta method (B(4), and C(1): rows sum to c)
    c = np.array(NODES)
    np.testing.assert_allclose(a.sum(axis=1), c, atol=1e-15)
    for k in range(1, 5):
        assert abs(b @ c ** (k - 1) - 1.0 / k) < 1e-15
    assert abs(b @ (a @ c) - 1.0 / 6.0) < 1e-15


@pytest.mark.slow  # three Newton compilations
def test_lobatto_double_pendulum_against_dop853():
    """The (reduced) double pendulum, nonlinear and non-separable, vs DOP853 at 1e-13."""
    import jax
    import jax.numpy as jnp
    import scipy.integrate

    problem = problems.get("double-pendulum-torn").reduced
    system, horizon = problem.system, 1.0

    @jax.jit
    def acceleration(y):
        q, v = y[:2], y[2:]
        mass = jax.hessian(system.lagrangian, argnums=1)(q, v)
        dldq = jax.grad(system.lagrangian, argnums=0)(q, v)
        mixed = jax.jacfwd(jax.grad(system.lagrangian, argnums=1), argnums=0)(q, v)
        return jnp.concatenate([v, jnp.linalg.solve(mass, dldq - mixed @ v)])

    v0 = np.array(problems.get("double-pendulum-torn").parameters["omega0"])
    reference = scipy.integrate.solve_ivp(
        lambda _, y: np.asarray(acceleration(y)),
        (0.0, horizon),
        np.concatenate([problem.q0, v0]),
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
    ).y[:2, -1]
    errors = []
    for h in LOBATTO_HS:
        traj = dv.simulate(
            system, problem.q0, problem.p0, dt=h, steps=round(horizon / h), discretization="lobatto"
        )
        errors.append(np.max(np.abs(traj.q[-1] - reference)))
    assert abs(loglog_slope(LOBATTO_HS, errors) - 4.0) < 0.3, errors
