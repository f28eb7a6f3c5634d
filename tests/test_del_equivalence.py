"""Unconstrained regular L: the (+) equations are the discrete Euler–Lagrange equations.

The reference is written independently of diracvi: NumPy with hand-derived gradients
(left-point rule: an explicit symplectic-Euler recursion) and SciPy's root finder on the
midpoint DEL equations.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.optimize

import diracvi as dv

M = np.array([[2.0, 0.3], [0.3, 1.0]])
K = np.array([[3.0, -1.0], [-1.0, 2.0]])


def potential_grad(q):
    # V = ½ qᵀKq + 0.1 q₀⁴ − 0.5 cos q₁
    return K @ q + np.array([0.4 * q[0] ** 3, 0.5 * np.sin(q[1])])


def lagrangian(q, v):
    pot = 0.5 * q @ K @ q + 0.1 * q[0] ** 4 - 0.5 * jnp.cos(q[1])
    return 0.5 * v @ M @ v - pot


def reference_retraction(q0, p0, h, steps):
    # p_k = M v_k + h ∇V(q_k);  p_{k+1} = M v_k
    q, p = [np.array(q0)], [np.array(p0)]
    for _ in range(steps):
        v = np.linalg.solve(M, p[-1] - h * potential_grad(q[-1]))
        q.append(q[-1] + h * v)
        p.append(M @ v)
    return np.array(q), np.array(p)


def reference_midpoint(q0, p0, h, steps):
    # p_k = M v_k + h/2 ∇V(q̄);  p_{k+1} = M v_k − h/2 ∇V(q̄)
    q, p = [np.array(q0)], [np.array(p0)]
    for _ in range(steps):
        qk, pk = q[-1], p[-1]

        def eq(qn, qk=qk, pk=pk):
            return M @ (qn - qk) / h + 0.5 * h * potential_grad(0.5 * (qk + qn)) - pk

        qn = scipy.optimize.fsolve(eq, qk + h * np.linalg.solve(M, pk), xtol=1e-12)
        v = (qn - qk) / h
        q.append(qn)
        p.append(M @ v - 0.5 * h * potential_grad(0.5 * (qk + qn)))
    return np.array(q), np.array(p)


# fsolve warns "not making good progress" once it sits at round-off; the comparison below
# (1e-11) is what decides whether the reference converged
@pytest.mark.filterwarnings("ignore:The iteration is not making good progress")
@pytest.mark.parametrize(
    ("discretization", "reference"),
    [("retraction", reference_retraction), ("midpoint", reference_midpoint)],
)
def test_plus_equations_are_the_del_equations(discretization, reference):
    system = dv.LagrangeDiracSystem(("a", "b"), lagrangian)
    q0, p0, h, steps = np.array([0.7, -0.4]), np.array([0.2, 0.5]), 0.05, 200
    traj = dv.simulate(system, q0, p0, dt=h, steps=steps, discretization=discretization)
    q_ref, p_ref = reference(q0, p0, h, steps)
    assert np.max(np.abs(traj.q - q_ref)) < 1e-11
    assert np.max(np.abs(traj.p - p_ref)) < 1e-11
    assert traj.multipliers.shape == (steps, 0)


def test_momenta_helper_is_the_legendre_transform():
    system = dv.LagrangeDiracSystem(("a", "b"), lagrangian)
    v = np.array([0.3, -1.2])
    np.testing.assert_allclose(dv.momenta(system, [0.1, 0.2], v), M @ v, rtol=0, atol=1e-15)


def test_momenta_at_many_times_compile_once():
    """p = m(t) v with m(t) = 1 + t²; the time is an input of the program, not a constant."""

    def driven(q, v, t):
        return 0.5 * (1.0 + t**2) * v @ v - 0.5 * q @ q

    system = dv.LagrangeDiracSystem(("a", "b"), driven)
    v = np.array([0.3, -1.2])
    for t in (0.0, 0.5, 1.5):
        p = dv.momenta(system, [0.1, 0.2], v, t=t)
        np.testing.assert_allclose(p, (1 + t**2) * v, rtol=0, atol=1e-15)
    traced = []

    def listener(event, *_, **__):
        if "trace" in event:
            traced.append(event)

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        dv.momenta(system, [0.1, 0.2], v, t=2.0)
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    assert traced == []  # a new time reuses the compiled program
