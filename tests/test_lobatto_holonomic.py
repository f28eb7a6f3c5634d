"""The order-4 rule with a holonomic constraint: the spherical pendulum in Cartesian
coordinates (``L = ½|v|² − g z``, rod ``g(q) = |q|² − 1``), issue 31.

``"lobatto"`` used to pair the row ``g(q_{k+1}) = 0`` with a multiplier acting at the
stage ``Q₃ ≠ q_{k+1}``; the momentum's component along ``∇g(q_k)`` then survived the step
(step-map eigenvalue −1.0009 at g = 1, h = 0.01) and grew until Newton failed (t ≈ 548 at
h = 0.01, t = 27.3 at h = 0.1). Now that row's multiplier acts at the known node and the
stage rows are ``g(Q₂) = 0``, ``g(Q₃) − g(Q₁) = 0`` (``docs/discretizations.md``).

References: the conical pendulum (uniform rotation at the polar angle α with
``ω² = g/(ℓ cos α)``) is an exact solution; energy and ``L_z = x p_y − y p_x`` are
conserved by the flow.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope
from diracvi.discretization.equations import first_guess, new_momentum, residual
from diracvi.discretization.rules import get_rule
from diracvi.model.system import LagrangeDiracSystem

GRAVITY = 9.81
ALPHA = np.pi / 3  # polar angle from the downward vertical


def spherical_pendulum():
    return LagrangeDiracSystem(
        ("x", "y", "z"),
        lambda q, v: 0.5 * v @ v - GRAVITY * q[2],
        holonomic=lambda q: jnp.atleast_1d(q @ q - 1.0),
        holonomic_names=("rod",),
        name="spherical pendulum",
    )


SYSTEM = spherical_pendulum()  # one object: every run below reuses its compiled step
Q0 = np.array([np.sin(ALPHA), 0.0, -np.cos(ALPHA)])


def conical(t):
    """The exact conical motion from ``Q0``: ``(sin α cos ωt, sin α sin ωt, −cos α)``."""
    omega = np.sqrt(GRAVITY / np.cos(ALPHA))
    t = np.asarray(t)[:, None]
    return np.hstack(
        [
            np.sin(ALPHA) * np.cos(omega * t),
            np.sin(ALPHA) * np.sin(omega * t),
            -np.cos(ALPHA) + 0 * t,
        ]
    )


def conical_momentum():
    return np.array([0.0, np.sin(ALPHA) * np.sqrt(GRAVITY / np.cos(ALPHA)), 0.0])


def test_the_steps_ignore_the_momentum_along_the_rod():
    """Adding ``c ∇g(q₀)`` to ``p₀`` changes nothing after it: the nodal multiplier
    absorbs that component, as under ``"midpoint"``, so no mode of the step map lives in
    it. The old placement carried it on (step-map eigenvalue −1.0009 at g = 1,
    h = 0.01): the two runs below then differ by ≈ c·h in q and ≈ c in p."""
    q0 = jnp.asarray(Q0)
    p0 = jnp.array([0.0, 2.0 * np.sin(ALPHA), 0.0])
    h = np.float64(0.01)  # the dtype of the order test's steps: the same program
    q, p = _run(q0, p0, h)
    q_pushed, p_pushed = _run(q0, p0 + 0.1 * 2.0 * q0, h)
    assert np.max(np.abs(q_pushed - q)) <= 1e-13
    assert np.max(np.abs(p_pushed - p)) <= 1e-12


def _residual(q, p, x, h):
    return residual(SYSTEM, get_rule("lobatto"), "plus", h, q, p, x)


def _solve(q, p, h):
    """One (+) step's unknowns by Newton from the rule's first guess (fixed count)."""
    x = first_guess(SYSTEM, get_rule("lobatto"), q, q + h * p, jnp.zeros(1))

    def newton(_, x):
        return x - jnp.linalg.solve(jax.jacfwd(_residual, 2)(q, p, x, h), _residual(q, p, x, h))

    return jax.lax.fori_loop(0, 8, newton, x)


@jax.jit  # one program for every call: eager JAX would trace each small operation
def _run(q, p, h):
    """``(q_k, p_k)``, k = 1 … 40, of the rule's (+) equations, Newton on each step
    (``h`` traced: one program for every step size)."""

    def step(state, _):
        q, p = state
        x = _solve(q, p, h)
        new = (x[: SYSTEM.n], new_momentum(SYSTEM, get_rule("lobatto"), "plus", h, q, x))
        return new, new

    return jax.lax.scan(step, (q, p), None, length=40)[1]


def test_the_step_equations_have_order_four_on_the_conical_pendulum():
    """The rule's step equations (Newton on ``residual``, stepped here in one compiled
    program) against the exact conical motion at t = 1: fitted order 4.0 ± 0.2 and the
    rod at round-off. Measured: 7.9e-5, 5.0e-6, 3.1e-7."""
    hs = np.array([0.1, 0.05, 0.025])
    errors = []
    for h in hs:
        q = np.asarray(_run(jnp.asarray(Q0), jnp.asarray(conical_momentum()), h)[0])
        k = round(1.0 / h) - 1  # q[k] is the state at t = (k + 1) h
        errors.append(np.max(np.abs(q[k] - conical([1.0])[0])))
        assert np.max(np.abs(np.sum(q**2, axis=1) - 1.0)) <= 1e-13
    assert abs(loglog_slope(hs, errors) - 4.0) <= 0.2, errors


@pytest.mark.slow
def test_order_four_on_the_conical_pendulum():
    """The same through ``dv.simulate`` (one compiled plan per step size, hence slow)."""
    hs = np.array([0.1, 0.05, 0.025])
    errors = []
    for h in hs:
        traj = dv.simulate(SYSTEM, Q0, conical_momentum(), dt=h, steps=40, discretization="lobatto")
        k = round(1.0 / h)
        errors.append(np.max(np.abs(traj.q[k] - conical([traj.t[k]])[0])))
        assert np.max(np.abs(np.sum(traj.q**2, axis=1) - 1.0)) <= 1e-13
    assert abs(loglog_slope(hs, errors) - 4.0) <= 0.2, errors


def _bounded_run(h, steps, save_every=1):
    p0 = np.array([0.0, 2.0 * np.sin(ALPHA), 0.0])
    traj = dv.simulate(
        SYSTEM, Q0, p0, dt=h, steps=steps, discretization="lobatto", save_every=save_every
    )
    assert traj.success
    energy = np.asarray(traj.energy)
    rel = energy / energy[0] - 1.0
    tenth = len(rel) // 10
    lz = traj.q[:, 0] * traj.p[:, 1] - traj.q[:, 1] * traj.p[:, 0]
    rod = np.max(np.abs(np.sum(traj.q**2, axis=1) - 1.0))
    return rel, tenth, np.ptp(lz) / abs(lz[0]), rod


def test_energy_stays_bounded_at_a_large_step():
    """h = 0.1 for 1000 steps (t = 100): the old placement failed at step 273; now the
    energy error stays in a band (measured 8.1e-5) with the same range in the first and
    last tenth, the rod at round-off and L_z conserved to round-off."""
    rel, tenth, lz_spread, rod = _bounded_run(0.1, 1000)
    assert np.max(np.abs(rel)) <= 1.5e-4
    assert np.max(np.abs(rel[-tenth:])) <= 1.5 * np.max(np.abs(rel[:tenth]))
    assert rod <= 1e-13
    assert lz_spread <= 1e-11


@pytest.mark.slow
def test_energy_band_holds_to_t_1000_at_h_001():
    """Issue 31's run, h = 0.01 to t = 1000 (10⁵ steps): the old placement's energy error
    grew from 3e-8 at t = 300 to 0.12 at t = 547 and Newton failed at t = 548.35; now
    the relative energy error stays in its first tenth's band (measured [−6.3e-9, 9.5e-9]
    in both tenths), the rod at round-off (6.7e-16) and L_z to 4.0e-12."""
    rel, tenth, lz_spread, rod = _bounded_run(0.01, 100_000, save_every=10)
    assert np.max(np.abs(rel)) <= 1e-8
    assert np.max(np.abs(rel[-tenth:])) <= 1.5 * np.max(np.abs(rel[:tenth]))
    assert rod <= 1e-13
    assert lz_spread <= 1e-10
