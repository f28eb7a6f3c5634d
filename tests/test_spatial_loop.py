"""A closed spatial loop: the RSSR four-bar (crank, coupler on two spherical joints, rocker
on a revolute axis skew to the crank's) in director form, against its one-coordinate
equation integrated by SciPy's DOP853 (no diracvi).

Fast: the director model's energy at two states is the reduced model's (same masses,
inertias, loop closure); the reduced reference keeps its energy and its closure. Slow
(each compiles a 36- or 108-coordinate step, 30 s to 5 min): the crank angle at order 2;
the 34 holonomic rows at round-off; torn into seven subsystems ≡ monolithic to 1e-12;
10⁵ steps with the rows below 1e-12.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from conftest import loglog_slope
from diracvi.problems.spatial_loop import _Loop, rssr_energy, rssr_linkage, rssr_reference

MIDPOINT = {"discretization": "midpoint", "solver": dv.NewtonSolver()}


def _velocities(model, p):
    """``v = (M̄ ⊗ I₃)⁻¹ p`` body by body (massless copies of a torn model left out)."""
    v = np.zeros(12 * len(model.bodies))
    for name, s in model.bodies.items():
        v[s] = np.linalg.solve(model.parts[name].mbar, p[s].reshape(4, 3)).reshape(12)
    return v


def test_director_model_has_the_reduced_models_energy():
    """Three bodies, four joints, the coupler's spin zero: the director model's energy is
    the reduced ``½ I(θ) θ̇² + V(θ)`` at two states (same masses, inertias, closure)."""
    for theta0, omega0 in [(0.4, 6.0), (2.5, -3.0)]:
        prob = rssr_linkage(theta0=theta0, omega0=omega0)
        model = prob.parameters["model"]
        q, v = jnp.asarray(model.q0), jnp.asarray(_velocities(model, model.p0))
        ours = float(prob.system.energy(q, v))
        assert ours == pytest.approx(rssr_energy(theta0, omega0), rel=1e-13)


def test_reduced_reference_keeps_energy_and_closure():
    """The reference's own checks over 0.5 s: energy to 1e-10 relative, and the rocker
    angle closes the loop ``|C − B| = ℓ`` to round-off."""
    theta, rate = rssr_reference(np.linspace(0.0, 0.5, 11), 0.4, 6.0, rates=True)
    energy = [rssr_energy(th, w) for th, w in zip(theta, rate, strict=True)]
    assert np.ptp(energy) < 1e-10 * abs(energy[0])
    loop = _Loop(9.81)
    for th in theta:
        b, _, _ = loop.crank(th)
        c, _, _ = loop.rocker(loop.phi(th))
        assert abs(np.linalg.norm(c - b) - loop.l) < 1e-14


def _run(torn, h, steps):
    prob = rssr_linkage(torn=torn, dt=h, steps=steps)
    traj = dv.simulate(prob.system, prob.q0, prob.p0, dt=h, steps=steps, **MIDPOINT)
    rows = jax.vmap(lambda q: prob.system.position_constraints(q, 0.0))(jnp.asarray(traj.q))
    return prob, traj, float(np.max(np.abs(np.asarray(rows))))


@pytest.mark.slow
def test_rssr_crank_angle_converges_at_order_two():
    """The crank's joint angle (from the directors) over 1 s against DOP853 on the reduced
    equation: order 2, and every row of the loop at round-off."""
    hs, errors = [0.01, 0.005, 0.0025], []
    for h in hs:
        prob, traj, rows = _run(False, h, round(1.0 / h))
        assert rows < 1e-14
        angle = prob.parameters["model"].joint_position(traj.q, "hinge_a")
        errors.append(np.max(np.abs(angle - prob.parameters["reference"](traj.t))))
    assert loglog_slope(hs, errors) == pytest.approx(2.0, abs=0.05)
    assert errors[-1] < 2e-3


@pytest.mark.slow
def test_torn_rssr_is_the_monolithic_one():
    """Seven subsystems (three bodies, four joints on massless copies) ≡ the monolithic
    model to 1e-12 over 300 steps, every row of both at round-off."""
    _, mono, rows = _run(False, 0.005, 300)
    assert rows < 1e-14
    _, torn, rows = _run(True, 0.005, 300)
    assert rows < 1e-14
    assert np.max(np.abs(torn.q[:, :36] - mono.q)) < 1e-12


@pytest.mark.slow
def test_rssr_holds_its_loop_over_1e5_steps():
    """10⁵ steps of 5 ms (500 s, about 590 crank turns): rows below 1e-12, energy band at
    the scheme's O(h²) size with no trend."""
    prob = rssr_linkage(dt=0.005, steps=100_000)
    traj = dv.simulate(
        prob.system, prob.q0, prob.p0, dt=prob.dt, steps=prob.steps, save_every=100, **MIDPOINT
    )
    rows = jax.vmap(lambda q: prob.system.position_constraints(q, 0.0))(jnp.asarray(traj.q))
    assert np.max(np.abs(np.asarray(rows))) < 1e-12
    energy = traj.energy / abs(traj.energy[0])
    tenth = len(energy) // 10
    assert np.ptp(energy) < 1e-2
    assert np.ptp(energy[-tenth:]) < 2.0 * np.ptp(energy[:tenth])
