"""Long-time energy behaviour, dissipation, and the sign of the resistor force.

White-box: reads internals of ``diracvi.problems._problem``."""

import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope, run
from diracvi import problems
from diracvi.problems._problem import linear_flow
from diracvi.problems.spring_chain import chain_stiffness


def tenths(energy):
    n = len(energy) // 10
    return energy[:n].mean(), energy[-n:].mean()


@pytest.fixture(scope="module")
def long_runs():
    problem = problems.get("spring-chain")
    return {
        disc: run(problem, steps=100_000, discretization=disc)
        for disc in ("retraction", "midpoint")
    }


def test_spring_chain_energy_oscillates_without_drift(long_runs):
    """10^5 steps at h = 0.01: bounded oscillation, equal means in the first and last tenth."""
    energy = long_runs["retraction"].energy
    amplitude = energy.max() - energy.min()
    first, last = tenths(energy)
    assert amplitude / energy.mean() < 0.01  # O(h) oscillation, measured 0.0088
    assert abs(last - first) < 0.02 * amplitude  # measured 0.0044
    # the midpoint rule conserves this quadratic energy up to round-off
    mid = long_runs["midpoint"].energy
    assert (mid.max() - mid.min()) / mid.mean() < 1e-10


def test_the_drift_metric_detects_a_non_symplectic_method():
    """Explicit Euler on the same chain drifts by orders of magnitude under the same metric."""
    stiffness = chain_stiffness([1.0, 1.0, 1.0])
    q, v, h = np.array([0.0, 1.0, 2.0]), np.array([0.0, 0.0, 3.0]), 0.01
    energy = np.empty(20_000)
    for k in range(energy.size):
        energy[k] = 0.5 * v @ v + 0.5 * q @ stiffness @ q
        q, v = q + h * v, v - h * stiffness @ q
    first, last = tenths(energy)
    assert abs(last - first) > 0.02 * (energy.max() - energy.min())


@pytest.mark.parametrize("discretization", ["retraction", "midpoint"])
def test_damper_removes_energy(discretization):
    problem = problems.get("damped-oscillator")
    traj = run(problem, discretization=discretization)
    energy = traj.energy
    assert energy[-1] < 0.2 * energy[0]  # exact: e^{-cT/m} ≈ 0.14 of the start (oscillating)
    # over every half period the energy goes down (it may wiggle within one step)
    window = round(np.pi / problem.dt)
    assert np.all(np.diff(energy[::window]) < 0)
    undamped = dv.LagrangeDiracSystem(("x",), problem.system.lagrangian)
    free = dv.simulate(
        undamped,
        problem.q0,
        problem.p0,
        dt=problem.dt,
        steps=problem.steps,
        discretization=discretization,
    )
    assert free.energy[-1] > 0.95 * free.energy[0]


@pytest.mark.parametrize("discretization", ["retraction", "midpoint"])
def test_energy_follows_the_power_balance_at_the_rules_order(discretization):
    """E_k against the exact dissipated energy E(t): the error shrinks as h^order."""
    problem = problems.get("damped-oscillator")
    m, k, c = (problem.parameters[x] for x in ("m", "k", "c"))
    gen = np.array([[0.0, 1.0], [-k / m, -c / m]])
    hs = np.array([0.04, 0.02, 0.01, 0.005])
    errors = []
    for h in hs:
        traj = run(problem, dt=h, steps=round(5.0 / h), discretization=discretization)
        shift = 0.0 if discretization == "retraction" else 0.5 * h  # the quadrature node
        t = traj.t[:-1] + shift
        x = linear_flow(gen, np.array([problem.q0[0], problem.p0[0] / m]), t)
        exact = 0.5 * m * x[:, 1] ** 2 + 0.5 * k * x[:, 0] ** 2
        errors.append(np.max(np.abs(traj.energy - exact)))
    order = {"retraction": 1, "midpoint": 2}[discretization]
    assert abs(loglog_slope(hs, errors) - order) < 0.2


def test_rlc_resistor_dissipates_and_the_papers_printed_sign_would_not():
    """Paper §5.2 prints f_d^− = −hF, i.e. p_k^R = −R Δq^R + μ: a negative resistance.

    With the physical force F = (−R v^R, 0, 0) the circuit loses energy; flipping the force
    (which is what the printed discrete equations amount to) makes it gain energy.
    """
    problem = problems.get("rlc")
    traj = run(problem)
    assert traj.energy[-1] < 1e-3 * traj.energy[0]
    system = problem.system
    flipped = dv.LagrangeDiracSystem(
        system.coords,
        system.lagrangian,
        constraints=np.array([[1.0, -1.0, -1.0]]),
        force=lambda q, v: -system.force(q, v),
    )
    papers = dv.simulate(flipped, problem.q0, problem.p0, dt=problem.dt, steps=100)
    assert papers.energy[-1] > 10 * papers.energy[0]


def test_rlc_energy_matches_the_continuous_decay():
    """Midpoint energy tracks E(t) of the exact DAE solution to O(h²)."""
    problem = problems.get("rlc")
    traj = run(problem, dt=0.01, steps=1000, discretization="midpoint")
    ell, cap = problem.parameters["l"], problem.parameters["C"]
    t = traj.t[:-1] + 0.005
    q = problem.exact(t)
    dt = 1e-6
    v_l = (problem.exact(t + dt)[:, 1] - problem.exact(t - dt)[:, 1]) / (2 * dt)
    exact = 0.5 * ell * v_l**2 + q[:, 2] ** 2 / (2 * cap)
    assert np.max(np.abs(traj.energy - exact)) < 1e-3 * exact[0]


def series_lc(ell=0.5, cap=2.0):
    """An inductor and one capacitor in series: ``L = ½ l (v^L)² − (q^C)²/(2C)``, KCL
    ``v^L − v^C = 0`` (degenerate in ``q^C``); its energy ``Q²/(2C) + ½ l I²`` is exact."""
    return dv.LagrangeDiracSystem(
        ("qL", "qC"),
        lambda q, v: 0.5 * ell * v[0] ** 2 - q[1] ** 2 / (2.0 * cap),
        constraints=np.array([[1.0, -1.0]]),
        name="lc-series",
    )


def lobatto_lc_energy(steps):
    traj = dv.simulate(
        series_lc(),
        np.array([0.0, 1.0]),
        np.array([0.0, 0.0]),
        dt=0.1,  # 31 steps per period (ω = 1)
        steps=steps,
        discretization="lobatto",
        save_states=False,
    )
    exact = 1.0**2 / (2.0 * 2.0)
    return (traj.energy - exact) / exact


def assert_bounded_without_drift(error):
    """Lobatto IIID is a symplectic Runge–Kutta method: on the linear LC circuit it keeps
    a quadratic form of the state exactly, so the step energy's error is a constant
    O(h⁴) offset (measured 1.04e-6 at h = 0.1) and all that changes over the run is
    round-off (measured 2.4e-11 over 1e5 steps, below 1e-15 per step). A non-symplectic
    fourth-order rule would drift by about h⁴ per unit time, ~1e-4 over 1e5 steps."""
    first, last = tenths(error)
    spread = error.max() - error.min()
    assert abs(error.mean()) < 1e-5  # the O(h⁴) offset
    assert spread < 1e-15 * len(error)  # round-off growth only: bounded, no drift
    assert abs(last - first) <= spread


def test_lobatto_lc_energy_is_bounded_over_1e5_steps():
    assert_bounded_without_drift(lobatto_lc_energy(100_000))


@pytest.mark.slow
def test_lobatto_lc_energy_is_bounded_over_1e6_steps():
    assert_bounded_without_drift(lobatto_lc_energy(1_000_000))
