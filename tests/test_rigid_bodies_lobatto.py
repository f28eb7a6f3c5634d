"""The order-4 rule (``discretization="lobatto"``) on rigid bodies in director form.

A body's six orthonormality rows ``dᵢ·dⱼ = δᵢⱼ`` and a spherical joint's three are
quadratic holonomic rows; the rule holds them at the new node and by its two stage rows
``g(Q₂) = 0``, ``g(Q₃) − g(Q₁) = 0`` (``docs/discretizations.md``). All slow (each run
compiles a 12- to 60-coordinate staged step, 20–100 s): the heavy top against the
Euler–Poisson equations by SciPy — order 4 on every director coordinate and on the body
angular velocity Ω, the symmetric top's Ω₃ and the pivot exact to round-off —; the free
body's orthonormality and |L| to round-off over 10⁴ steps, its energy in a band without
trend, and order 4 against Euler's equations; the spatial double pendulum torn ≡
monolithic and order 4 against MuJoCo.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope
from diracvi.problems.rigid_bodies import (
    _turned,
    euler_solution,
    free_rigid_body,
    heavy_top,
    spatial_double_pendulum,
)
from test_rigid_bodies import _body_omega, _free_body_invariants

LOBATTO = {"discretization": "lobatto", "solver": dv.NewtonSolver()}


def _slopes(hs, errors):
    """The fitted order of each column of ``errors`` (one row per step size), and the
    largest residual of the log-log fits (0 for errors exactly ∝ hʳ: the step sizes are in
    the asymptotic range, above round-off)."""
    log_h, slopes, residual = np.log(hs), [], 0.0
    for column in np.log(np.asarray(errors)).T:
        slope = loglog_slope(hs, np.exp(column))
        fitted = column.mean() + slope * (log_h - log_h.mean())  # the least-squares line
        slopes.append(slope)
        residual = max(residual, np.max(np.abs(column - fitted)))
    return np.array(slopes), residual


@pytest.mark.slow
def test_heavy_top_is_order_four_in_every_director_and_in_omega():
    """Directors and Ω₁, Ω₂ against the Euler–Poisson reference (DOP853, 1e-12) over 0.4 s
    (spin 5 rad/s: strong nutation): order 4.0 in each (measured 4.00 ± 0.003, errors 4e-7
    … 2e-9); Ω₃, constant for the symmetric top, and the pivot at round-off."""
    mass, c, g = 1.0, np.array([0.0, 0.0, 0.5]), np.array([0.0, 0.0, -9.81])
    j_o = np.diag([0.4, 0.4, 0.2]) + mass * (c @ c * np.eye(3) - np.outer(c, c))
    hs, directors, omegas = [0.02, 0.01, 0.005], [], []
    for h in hs:
        prob = heavy_top(dt=h, steps=round(0.4 / h), spin=5.0)
        tr = dv.simulate(prob.system, prob.q0, prob.p0, dt=h, steps=prob.steps, **LOBATTO)
        assert np.max(np.abs(tr.q[:, :3])) < 1e-13  # the spherical joint at the origin
        directors.append(np.max(np.abs(tr.q[:, 3:12] - prob.numerical_solution(tr.t)[:, 3:]), 0))
        ref, _ = euler_solution(
            j_o,
            (0.0, 0.0, 5.0),
            _turned((0.4, 0.0, 0.0)),
            tr.t,
            torque=lambda r: np.cross(c, r.T @ (mass * g)),
        )
        omegas.append(np.max(np.abs(_body_omega(tr.q, tr.p, j_o) - ref), 0))
    omegas = np.array(omegas)
    assert np.max(omegas[:, 2]) < 1e-11  # Ω₃ = 5 exactly in the reference
    slopes, residual = _slopes(hs, np.concatenate([directors, omegas[:, :2]], axis=1))
    np.testing.assert_allclose(slopes, 4.0, atol=0.05)
    assert residual < 0.01
    assert np.max(directors[-1]) < 3e-9


@pytest.mark.slow
def test_free_body_keeps_its_invariants_and_is_order_four():
    """10⁴ steps of 0.01 (through the tennis-racket flips): ‖RᵀR − I‖ and |L| to round-off,
    the energy in a band (the rule's O(h⁴) band, 4.9e-11 relative; 16 times that at h =
    0.02) the same in the first and the last tenth; Ω and the directors against Euler's
    equations by DOP853 at order 4, the centre of mass exact."""
    prob, traj, orth, drift = _free_body_invariants(LOBATTO)
    assert orth < 1e-14
    assert drift < 1e-12
    energy = (traj.energy - traj.energy[0]) / abs(traj.energy[0])
    assert np.ptp(energy) < 1e-10
    tenth = len(energy) // 10
    first, last = np.ptp(energy[:tenth]), np.ptp(energy[-tenth:])
    assert abs(last - first) < 0.1 * first  # a band, not a drift

    inertia = np.diag(prob.parameters["J"])
    hs, omegas, coords = [0.04, 0.02, 0.01], [], []
    for h in hs:
        p = free_rigid_body(dt=h, steps=round(4.0 / h))
        tr = dv.simulate(p.system, p.q0, p.p0, dt=h, steps=p.steps, **LOBATTO)
        ref, _ = euler_solution(inertia, p.parameters["Omega0"], _turned((0.3, -0.2, 0.5)), tr.t)
        omegas.append(np.max(np.abs(_body_omega(tr.q, tr.p, inertia) - ref), 0))
        exact = p.numerical_solution(tr.t)
        assert np.max(np.abs(tr.q[:, :3] - exact[:, :3])) < 1e-14  # uniform translation
        coords.append(np.max(np.abs(tr.q[:, 3:] - exact[:, 3:]), 0))
    slopes, residual = _slopes(hs, np.concatenate([coords, omegas], axis=1))
    np.testing.assert_allclose(slopes, 4.0, atol=0.05)
    assert residual < 0.02
    assert np.max(omegas[-1]) < 1e-10


@pytest.mark.slow
def test_torn_double_pendulum_is_the_monolithic_one_under_lobatto():
    """One subsystem per body and joint ≡ the monolithic system: positions to 1e-12 and, each
    body's momentum summed with its massless copies' (the joints' reactions act on the
    copies), momenta to 1e-12 (measured 5e-14, 1.2e-13 over 100 steps); every row ≤ 1e-13."""
    runs = []
    for torn in (False, True):
        prob = spatial_double_pendulum(torn=torn, dt=0.01, steps=100)
        tr = dv.simulate(prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps, **LOBATTO)
        g = jax.vmap(prob.system.position_constraints)(jnp.asarray(tr.q))
        assert np.max(np.abs(np.asarray(g))) < 1e-13
        runs.append(tr)
    mono, torn = runs
    np.testing.assert_array_less(np.abs(mono.q - torn.q[:, :24]), 1e-12)
    momenta = torn.p[:, :24].copy()
    for start in range(24, torn.q.shape[1], 12):  # each 12-block a copy of one body
        copy = torn.q[:, start : start + 12]
        (body,) = [b for b in (0, 12) if np.max(np.abs(copy - torn.q[:, b : b + 12])) < 1e-12]
        momenta[:, body : body + 12] += torn.p[:, start : start + 12]
    np.testing.assert_array_less(np.abs(mono.p - momenta), 1e-12)


@pytest.mark.slow
def test_spatial_double_pendulum_is_order_four_against_mujoco():
    """Both links' centres of mass after 1 s against MuJoCo (RK4, 1e-4 s): order 4 (measured
    2.0e-7, 1.3e-8, 7.9e-10 at h = 0.02, 0.01, 0.005: slope 4.00)."""
    pytest.importorskip("mujoco")
    from _mujoco_pendulum import centre_errors

    hs = [0.02, 0.01, 0.005]
    errors = centre_errors(hs, "lobatto")
    assert loglog_slope(hs, errors) == pytest.approx(4.0, abs=0.05)
    assert errors[-1] < 2e-9
