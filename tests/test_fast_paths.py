"""Every fast path gives the trajectory plain Newton gives (≤ 1e-12), and says what ran:
the affine step map (with its per-step verification and fallback), Newton with reused
factors, thinned and diagnostics-only saving, and ensembles.

White-box: reads internals of ``diracvi.discretization.diagnostics``."""

import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from conftest import one_rule_each, run
from diracvi import problems

PLAIN = dv.NewtonSolver(reuse_jacobian=False)
LINEAR = ["spring-chain", "spring-chain-torn", "rlc", "rlc-torn", "chain-torn", "dc-motor"]


def rel(a, b):
    return float(np.max(np.abs(a - b)) / max(1.0, float(np.max(np.abs(b)))))


def assert_same_run(fast, plain, tol=1e-12):
    """Equal to ``tol`` relative to the size of the state (q and p together: a drifting
    coordinate such as an integrated charge sets the round-off of the momenta it drives)."""
    assert fast.success and plain.success
    size = max(1.0, float(np.max(np.abs(plain.q))), float(np.max(np.abs(plain.p))))
    assert np.max(np.abs(fast.q - plain.q)) <= tol * size
    assert np.max(np.abs(fast.p - plain.p)) <= tol * size
    if plain.multipliers.size:
        assert rel(fast.multipliers, plain.multipliers) <= tol * 10  # λ carries 1/h


def _affine_cases():
    """One rule per model by default (taking turns), the twins with -m slow; the torn
    spring chain and the DC motor (6 s each) too (the default suite's time on CI): the
    untorn chain, the RLC, the torn RLC and the torn n-mass chain stay, both rules
    between them."""
    cases = one_rule_each(LINEAR)
    slow = {"spring-chain-torn", "dc-motor"}
    return [
        pytest.param(*c.values, marks=[pytest.mark.slow]) if c.values[0] in slow else c
        for c in cases
    ]


@pytest.mark.parametrize(("name", "discretization"), _affine_cases())
def test_affine_step_map_equals_plain_newton(name, discretization):
    problem = problems.get(name)
    fast = run(problem, discretization=discretization)
    plain = run(problem, discretization=discretization, solver=PLAIN)
    assert fast.solver == "affine step map"
    assert np.all(fast.newton_iterations == 0)
    assert_same_run(fast, plain)
    np.testing.assert_allclose(fast.energy, plain.energy, rtol=1e-11, atol=1e-12)


# the torn spring chain (9 s) with -m slow (CI time): the torn RLC keeps the backward scheme
@pytest.mark.parametrize(
    "name", [pytest.param("spring-chain-torn", marks=pytest.mark.slow), "rlc-torn"]
)
def test_affine_step_map_backward_scheme_equals_plain_newton(name):
    problem = problems.get(name)
    fast = run(problem, scheme="minus", discretization="midpoint", steps=300)
    plain = run(problem, scheme="minus", discretization="midpoint", steps=300, solver=PLAIN)
    assert fast.solver == "affine step map"
    assert_same_run(fast, plain)


def falling_onto_a_spring(top=0.5):
    """Free fall under a unit force onto a spring (stiffness 100) whose top is at
    ``x = top``.

    The step equations are affine wherever the three detection probes look (near the
    origin), so detection accepts the affine map; the spring is met only later, at
    t = 1, where the per-step verification must catch it.
    """

    def lagrangian(q, v):
        contact = jnp.where(q[0] > top, q[0] - top, 0.0)
        return 0.5 * v[0] ** 2 + q[0] - 0.5 * 100.0 * contact**2

    return dv.LagrangeDiracSystem(("x",), lagrangian, name="ball")


def test_affine_check_failure_falls_back_to_newton_and_equals_it():
    system = falling_onto_a_spring()
    kwargs = {"dt": 1e-2, "steps": 300}
    fast = dv.simulate(system, [0.0], [0.0], **kwargs)
    plain = dv.simulate(system, [0.0], [0.0], **kwargs, solver=PLAIN)
    assert fast.solver.startswith("affine step map, then NewtonSolver")
    assert "from step 0" in fast.solver  # the chunk that failed is redone from its start
    assert np.max(fast.q) > 0.5  # it did reach the spring
    assert_same_run(fast, plain)


def test_affine_fallback_midway_in_a_chunked_run_equals_newton(tmp_path):
    system = falling_onto_a_spring()
    kwargs = {"dt": 1e-2, "steps": 300}
    fast = dv.simulate(
        system, [0.0], [0.0], **kwargs, checkpoint=tmp_path / "c.nc", checkpoint_every=50
    )
    plain = dv.simulate(system, [0.0], [0.0], **kwargs, solver=PLAIN)
    # the spring is met at t = 1 (step 100): two chunks run affine, then Newton
    assert "from step 100" in fast.solver
    assert_same_run(fast, plain)
    resumed = dv.simulate(
        system, [0.0], [0.0], **kwargs, checkpoint=tmp_path / "c.nc", checkpoint_every=50
    )
    np.testing.assert_array_equal(resumed.q, fast.q)
    assert resumed.solver == fast.solver


def test_nonlinear_systems_are_not_stepped_affinely():
    problem = problems.get("double-pendulum-torn")
    traj = run(problem, steps=50)
    assert traj.solver == repr(dv.NewtonSolver())
    forced = run(problem, steps=50, solver=dv.AffineSolver(fallback=PLAIN))
    assert forced.solver == repr(PLAIN)  # detection refused: the fallback ran from the start
    assert_same_run(forced, run(problem, steps=50, solver=PLAIN))


@pytest.mark.parametrize(
    ("name", "discretization"),
    [
        ("double-pendulum-torn", "retraction"),
        ("double-pendulum-torn", "midpoint"),
        ("rolling-disk", "midpoint"),
        ("rolling-disk", "retraction"),
    ],
)
def test_newton_with_reused_factors_equals_plain_newton(name, discretization):
    problem = problems.get(name)
    reuse = run(problem, discretization=discretization, steps=400, solver=dv.NewtonSolver())
    plain = run(problem, discretization=discretization, steps=400, solver=PLAIN)
    assert_same_run(reuse, plain)


@pytest.mark.parametrize("name", ["rlc-torn", "double-pendulum-torn"])
def test_save_every_keeps_every_kth_step_of_the_full_run(name):
    problem = problems.get(name)
    full = run(problem, steps=600)
    thin = run(problem, steps=600, save_every=20)
    np.testing.assert_array_equal(thin.t, full.t[::20])
    np.testing.assert_allclose(thin.q, full.q[::20], rtol=0, atol=1e-13)
    np.testing.assert_allclose(thin.energy, full.energy[19::20], rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(thin.multipliers, full.multipliers[19::20], rtol=1e-10, atol=1e-12)
    # the largest |ω_d| over each interval (round-off sized: equal up to round-off)
    blocks = np.abs(full.constraint_residual).max(axis=1).reshape(-1, 20).max(axis=1)
    np.testing.assert_allclose(thin.constraint_violation, blocks, rtol=0, atol=1e-13)
    assert np.all(thin.constraint_violation >= np.abs(thin.constraint_residual).max(axis=1))
    np.testing.assert_array_equal(
        thin.newton_iterations, full.newton_iterations.reshape(-1, 20).sum(axis=1)
    )
    assert thin.steps == 600 and thin.save_every == 20


def test_diagnostics_only_run_keeps_no_states_but_the_last():
    problem = problems.get("chain-torn")
    full = run(problem, steps=500)
    diag = run(problem, steps=500, save_every=50, save_states=False)
    assert diag.q is None and diag.p is None and diag.multipliers is None
    assert diag.energy.shape == diag.constraint_violation.shape == (10,)
    np.testing.assert_allclose(diag.final_q, full.q[-1], rtol=0, atol=1e-13)
    np.testing.assert_allclose(diag.final_p, full.p[-1], rtol=0, atol=1e-13)
    assert diag.constraint_violation.max() <= 1e-12
    with pytest.raises(dv.ModelError, match="save_states=False"):
        diag["s0.q0"]


def test_save_every_must_divide_steps():
    problem = problems.get("rlc")
    with pytest.raises(dv.ModelError, match="save_every=7 does not divide steps=400"):
        run(problem, steps=400, save_every=7)
    with pytest.raises(dv.ModelError, match="checkpoint_every=30 is not a multiple"):
        run(problem, steps=400, save_every=20, checkpoint="x.nc", checkpoint_every=30)


def test_thinned_checkpointed_run_round_trips(tmp_path):
    problem = problems.get("double-pendulum-torn")
    kwargs = {"dt": problem.dt, "steps": 600, "save_every": 10, "save_states": False}
    path = tmp_path / "thin.nc"
    whole = dv.simulate(problem.system, problem.q0, problem.p0, **kwargs)
    first = dv.simulate(
        problem.system, problem.q0, problem.p0, **kwargs, checkpoint=path, checkpoint_every=200
    )
    again = dv.simulate(  # reads the finished checkpoint instead of recomputing
        problem.system, problem.q0, problem.p0, **kwargs, checkpoint=path, checkpoint_every=200
    )
    for field in ("energy", "final_q", "final_p", "constraint_violation", "newton_iterations"):
        np.testing.assert_array_equal(getattr(again, field), getattr(first, field))
    np.testing.assert_allclose(first.energy, whole.energy, rtol=1e-12)
    np.testing.assert_allclose(first.final_q, whole.final_q, rtol=1e-12)
    saved = dv.load(path)
    assert saved.q is None and saved.save_every == 10 and saved.steps == 600


def test_ensemble_members_equal_single_runs():
    problem = problems.get("double-pendulum-torn")
    rng = np.random.default_rng(3)
    q0 = np.tile(problem.q0, (6, 1))
    p0 = problem.p0 * (1.0 + 0.2 * rng.standard_normal((6, 1)))
    ens = dv.simulate_ensemble(problem.system, q0, p0, dt=problem.dt, steps=300)
    assert len(ens) == 6 and ens.success and ens.q.shape == (6, 301, problem.system.n)
    for i in range(6):
        single = dv.simulate(problem.system, q0[i], p0[i], dt=problem.dt, steps=300)
        assert_same_run(ens[i], single)


def test_affine_ensemble_equals_single_runs():
    problem = problems.get("rlc-torn")
    scale = np.linspace(0.5, 2.0, 5)[:, None]
    ens = dv.simulate_ensemble(
        problem.system, problem.q0 * scale, problem.p0 * scale, dt=problem.dt, steps=400
    )
    assert ens.solver == "affine step map"
    for i in range(5):
        single = dv.simulate(
            problem.system, problem.q0 * scale[i], problem.p0 * scale[i], dt=problem.dt, steps=400
        )
        assert_same_run(ens[i], single)


def test_a_failing_member_leaves_the_others_intact():
    """V = −2√x pulls a particle towards x = 0; the member thrown inward crosses it,
    where the model's force 1/√x is undefined (NaN)."""

    def lagrangian(q, v):
        return 0.5 * v[0] ** 2 + 2.0 * jnp.sqrt(q[0])

    system = dv.LagrangeDiracSystem(("x",), lagrangian, name="pole")
    q0 = np.array([[1.0], [1.0], [1.0]])
    p0 = np.array([[0.5], [-40.0], [1.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ens = dv.simulate_ensemble(system, q0, p0, dt=0.01, steps=200, throw=False)
    assert ens.status[0] == 0 and ens.status[2] == 0 and ens.status[1] != 0
    bad = ens[1]
    assert bad.steps < 200 and "step" in bad.message
    assert np.all(np.isnan(ens.q[1, bad.steps + 1 :]))
    for i in (0, 2):
        assert_same_run(ens[i], dv.simulate(system, q0[i], p0[i], dt=0.01, steps=200))
    with pytest.raises(dv.StepFailure, match="1 of 3 members failed"):
        dv.simulate_ensemble(system, q0, p0, dt=0.01, steps=200)


def test_ensemble_input_errors_name_the_shape():
    problem = problems.get("rlc")
    with pytest.raises(dv.ModelError, match=r"shape \(members, 3\)"):
        dv.simulate_ensemble(problem.system, problem.q0, problem.p0, dt=0.1, steps=10)
    with pytest.raises(dv.ModelError, match="not finite"):
        bad = np.tile(problem.q0, (2, 1))
        bad[1, 0] = np.nan
        dv.simulate_ensemble(problem.system, bad, bad, dt=0.1, steps=10)


def test_large_interconnections_are_stepped_by_the_sparse_map_or_the_partitioned_solver():
    """Above the dense limit a linear interconnection is stepped by the sparse affine map
    (factored once), and the partitioned solver, asked for, gives the same run."""
    problem = problems.chain_torn(300, 3)  # 302 coordinates: above the dense limit
    kwargs = {"dt": problem.dt, "steps": 60, "save_every": 6}
    auto = dv.simulate(problem.system, problem.q0, problem.p0, **kwargs)
    parted = dv.simulate(
        problem.system, problem.q0, problem.p0, **kwargs, solver=dv.PartitionedSolver()
    )
    plain = dv.simulate(problem.system, problem.q0, problem.p0, **kwargs, solver=PLAIN)
    assert auto.solver.startswith("sparse affine step map")
    assert parted.solver == repr(dv.PartitionedSolver())
    assert_same_run(parted, plain)
    assert_same_run(auto, plain)
    np.testing.assert_allclose(auto.energy, plain.energy, rtol=1e-12)
    np.testing.assert_allclose(auto.constraint_violation, plain.constraint_violation, atol=1e-13)


def test_grouped_diagnostics_equal_the_per_subsystem_sum():
    from diracvi.discretization.diagnostics import _plain, step_diagnostics

    problem = problems.chain_torn(40, 10)  # ten pieces: evaluated as groups
    rng = np.random.default_rng(7)
    a = problem.q0 + 0.1 * rng.standard_normal(problem.system.n)
    b = a + 0.01 * rng.standard_normal(problem.system.n)
    for discretization in ("retraction", "midpoint"):
        rule = dv.Midpoint() if discretization == "midpoint" else dv.Retraction()
        grouped = step_diagnostics(problem.system, rule, "plus", 0.01)(a, b)
        plain = _plain(problem.system, rule, "plus", 0.01)(a, b)
        np.testing.assert_allclose(grouped[0], plain[0], rtol=1e-14)
        np.testing.assert_allclose(grouped[1], plain[1], rtol=1e-14, atol=1e-15)


@pytest.mark.parametrize("solver", [dv.NewtonSolver, dv.PartitionedSolver])
@pytest.mark.parametrize(
    ("arg", "value"), [("rtol", -1.0), ("floor", 0.0), ("max_steps", 0), ("contraction", 2.0)]
)
def test_solver_settings_that_cannot_work_are_refused(solver, arg, value):
    with pytest.raises(dv.ModelError, match=rf"{solver.__name__}\({arg}={value!r}\)"):
        solver(**{arg: value})


def test_affine_solver_settings_are_checked():
    with pytest.raises(dv.ModelError, match="fallback must be a step solver"):
        dv.AffineSolver(fallback="newton")
    with pytest.raises(dv.ModelError, match=r"verify_rtol=0\.5"):
        dv.AffineSolver(verify_rtol=0.5)
