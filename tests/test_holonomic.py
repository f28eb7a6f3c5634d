"""Holonomic constraints against independent references: ``g(q_k) = 0`` to round-off over
long runs, the Cartesian pendulum and a four-bar linkage against reduced-coordinate DOP853
solutions at the rule's order, and a holonomic subsystem inside an interconnection
(torn ≡ monolithic).

References: ``problem.numerical_solution`` (θ-equation of the pendulum, the crank-angle
equation of the four-bar, the (x, θ) cart-pendulum; NumPy + SciPy solve_ivp DOP853 at
rtol = atol = 1e-12, no diracvi).
"""

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope, run
from diracvi import problems

HS = np.array([0.02, 0.01, 0.005])
ORDER = {"retraction": 1, "midpoint": 2}
BOTH = ["retraction", "midpoint"]


def _rod(traj, length=1.0):
    return np.max(np.abs(np.sum(traj.q**2, axis=1) - length**2))


def _errors(problem, discretization, horizon, hs=HS):
    """Max position error against the reference, and max |g|, for each step size."""
    errors, worst_g = [], 0.0
    for h in hs:
        traj = dv.simulate(
            problem.system,
            problem.q0,
            problem.p0,
            dt=h,
            steps=round(horizon / h),
            discretization=discretization,
        )
        assert traj.success
        errors.append(np.max(np.abs(traj.q - problem.numerical_solution(traj.t))))
        g = np.asarray([problem.system.position_constraints(q) for q in traj.q])
        worst_g = max(worst_g, float(np.max(np.abs(g))))
    return errors, worst_g


# --------------------------------------------------------------- g = 0 holds
@pytest.mark.parametrize("discretization", BOTH)
def test_pendulum_stays_on_its_circle(discretization):
    """Short default-suite variant of the 10⁵-step run below."""
    traj = run(problems.get("cartesian-pendulum"), steps=5000, discretization=discretization)
    assert _rod(traj) <= 1e-12
    # the reported holonomic residual is g(q_{k+1})/h
    assert np.max(np.abs(traj.constraint_residual)) * traj.dt <= 1e-12


@pytest.mark.slow
@pytest.mark.parametrize("discretization", BOTH)
def test_pendulum_stays_on_its_circle_over_1e5_steps(discretization):
    """Issue 11: |g(q_k)| ≤ 1e-12 over 10⁵ steps for both rules (t = 1000). Without the
    position constraint the left-point rule drifts to |q| − 1 ≈ 0.9 by t = 100."""
    problem = problems.get("cartesian-pendulum")
    traj = run(problem, steps=100_000, discretization=discretization, save_every=100)
    assert traj.success
    assert _rod(traj) <= 1e-12
    assert np.max(traj.constraint_violation) * traj.dt <= 1e-12
    if discretization == "midpoint":
        # a conservative system: the energy oscillates without drift
        e = traj.energy
        assert np.max(np.abs(e - e[0])) <= 0.02 * abs(9.81)


# ------------------------------------------------------------ orders
@pytest.mark.parametrize(
    "discretization", [pytest.param("retraction", marks=pytest.mark.slow), "midpoint"]
)
def test_cartesian_pendulum_converges_to_the_theta_equation(discretization):
    errors, worst_g = _errors(problems.get("cartesian-pendulum"), discretization, 2.0)
    assert abs(loglog_slope(HS, errors) - ORDER[discretization]) <= 0.2, errors
    assert worst_g <= 1e-12


@pytest.mark.parametrize(
    "discretization", [pytest.param("retraction", marks=pytest.mark.slow), "midpoint"]
)
def test_four_bar_converges_to_the_reduced_crank_equation(discretization):
    """Three link angles with two loop-closure rows, gravity and a driving torque
    τ₀ cos Ωt on the crank, against the 1-DOF crank-angle ODE (DOP853): the fitted slope
    is the rule's order, and the loop closes to round-off at every step. Measured
    (horizon 2): retraction 0.128, 0.066, 0.033; midpoint 5.2e-3, 1.3e-3, 3.2e-4."""
    errors, worst_g = _errors(problems.get("four-bar"), discretization, 2.0)
    order = ORDER[discretization]
    assert abs(loglog_slope(HS, errors) - order) <= 0.2, errors
    assert errors[-1] <= {1: 10.0, 2: 20.0}[order] * HS[-1] ** order, errors
    assert worst_g <= 1e-12


def test_four_bar_reference_is_consistent():
    """The reference itself: it closes the loop, and its energy changes by the torque's
    work (T + V − ∫τ θ̇₁ dt constant), integrated alongside by DOP853."""
    import scipy.integrate

    problem = problems.get("four-bar")
    prm = problem.parameters
    linkage = problems.FourBar(
        prm["a"], prm["b"], prm["c"], prm["d"], *prm["masses"], prm["g"], prm["tau0"], prm["Omega"]
    )
    t = np.linspace(0.0, 3.0, 31)
    sol = scipy.integrate.solve_ivp(
        lambda s, y: [*linkage.rhs(s, y[:2]), linkage.torque(s) * y[1]],
        (0.0, 3.0),
        [prm["theta0"], prm["omega0"], 0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        t_eval=t,
    )
    balance = []
    for theta1, omega1, work in sol.y.T:
        th = linkage.angles(theta1)
        balance.append(linkage.energy(th, linkage.velocity_ratios(th) * omega1) - work)
    assert np.ptp(balance) <= 1e-8 * max(1.0, np.max(np.abs(sol.y[2])))
    q = problem.numerical_solution(t)
    g = np.asarray([problem.system.position_constraints(x) for x in q])
    assert np.max(np.abs(g)) <= 1e-13
    np.testing.assert_allclose(q[:, 0], sol.y[0], rtol=0, atol=1e-9)


# ----------------------------------------- a holonomic subsystem, interconnected
@pytest.mark.parametrize(
    "discretization", [pytest.param("retraction", marks=pytest.mark.slow), "midpoint"]
)
def test_holonomic_subsystem_torn_equals_monolithic(discretization):
    problem = problems.get("cart-pendulum-torn")
    args = dict(dt=problem.dt, steps=300, discretization=discretization)
    torn = dv.simulate(problem.system, problem.q0, problem.p0, **args)
    mono = dv.simulate(problem.system.monolithic(), problem.q0, problem.p0, **args)
    assert mono.constraint_names == torn.constraint_names
    assert any("rod" in name for name in torn.constraint_names)
    for field in ("q", "p", "p_nodal", "multipliers"):
        a, b = getattr(torn, field), getattr(mono, field)
        assert np.max(np.abs(a - b)) <= 1e-12 * max(1.0, np.max(np.abs(b))), field
    bob = torn.q[:, 2:] - np.stack([torn.q[:, 1], 0 * torn.q[:, 1]], axis=1)
    assert np.max(np.abs(np.sum(bob**2, axis=1) - 1.0)) <= 1e-12
    assert np.max(np.abs(torn["cart.x"] - torn["pend.xs"])) <= 1e-13


@pytest.mark.slow
def test_holonomic_subsystem_converges_to_the_reduced_cart_pendulum():
    errors, _ = _errors(problems.get("cart-pendulum-torn"), "midpoint", 2.0)
    assert abs(loglog_slope(HS, errors) - 2) <= 0.2, errors


# ------------------------------------------------- a time-dependent constraint
def test_pendulum_on_a_shaken_pivot_converges_under_midpoint():
    r"""``g(q, t) = (x − A sin Ωt)² + y² − ℓ²``: the pivot is prescribed (a shaker).
    Reference: ``ℓ θ̈ = −g sin θ + A Ω² sin Ωt cos θ`` (θ from the downward vertical), by
    DOP853. Checks the time node of the holonomic row (``t_{k+1}`` for (+)) at order 2."""
    import scipy.integrate

    amp, om, grav = 0.2, 3.0, 9.81
    system = dv.LagrangeDiracSystem(
        ("x", "y"),
        lambda q, v: 0.5 * v @ v - grav * q[1],
        holonomic=lambda q, t: jnp.atleast_1d((q[0] - amp * jnp.sin(om * t)) ** 2 + q[1] ** 2 - 1),
    )
    theta0 = 0.5
    q0 = np.array([np.sin(theta0), -np.cos(theta0)])
    # the bob moves with the pivot at t = 0: ẋ = A Ω + cos θ θ̇ (θ̇₀ = 0)
    p0 = np.array([amp * om, 0.0])
    sol = scipy.integrate.solve_ivp(
        lambda t, y: [y[1], -grav * np.sin(y[0]) + amp * om**2 * np.sin(om * t) * np.cos(y[0])],
        (0.0, 2.0),
        [theta0, 0.0],
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=True,
    )
    errors = []
    for h in HS:
        traj = dv.simulate(system, q0, p0, dt=h, steps=round(2.0 / h), discretization="midpoint")
        th = sol.sol(traj.t)[0]
        ref = np.stack([amp * np.sin(om * traj.t) + np.sin(th), -np.cos(th)], axis=1)
        errors.append(np.max(np.abs(traj.q - ref)))
        pivot = amp * np.sin(om * traj.t)
        assert np.max(np.abs((traj.q[:, 0] - pivot) ** 2 + traj.q[:, 1] ** 2 - 1)) <= 1e-12
    assert abs(loglog_slope(HS, errors) - 2) <= 0.2, errors
