"""dv.simulate under jax.jit, jax.grad, jax.jvp and jax.vmap (docs/gradients.md).

Gradients are checked against central finite differences of the same forward map (the
jitted traced run, whose values equal the untraced run's, see test_jit_equals_untraced):
one compilation for the values and one for the gradient per case keeps the file fast.

White-box: reads internals of ``diracvi.driver.traced``."""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems

STEPS = 40
DT = 0.05


def _fd_check(loss, args, rel=1e-6, eps=1e-5, has_aux=False):
    """Reverse-mode gradient of ``loss(*args)`` (each arg a 1-D array) against central
    differences of the same compiled function (one compilation for both); returns the
    auxiliary output at ``args`` if ``has_aux``."""
    both = jax.jit(jax.value_and_grad(loss, argnums=tuple(range(len(args))), has_aux=has_aux))

    def value(*a):
        out = both(*a)[0]
        return float(out[0] if has_aux else out)

    (out, grads) = both(*args)
    worst = 0.0
    for i, (arg, grad) in enumerate(zip(args, grads, strict=True)):
        fd = np.zeros(arg.shape)
        for j in range(arg.size):
            step = eps * max(1.0, abs(float(arg[j])))
            plus = list(args)
            minus = list(args)
            plus[i] = arg.at[j].add(step)
            minus[i] = arg.at[j].add(-step)
            fd[j] = (value(*plus) - value(*minus)) / (2 * step)
        err = np.max(np.abs(np.asarray(grad) - fd)) / max(np.max(np.abs(fd)), 1e-300)
        worst = max(worst, float(err))
    assert worst <= rel, worst
    return out[1] if has_aux else None


# ------------------------------------------------------------- a constrained model
def bead(theta):
    """A nonlinear, damped, nonholonomically constrained particle in the plane.
    theta = (mass [Lagrangian], damping [force], c [constraint one-form])."""
    mass, damping, c = theta[0], theta[1], theta[2]

    def lagrangian(q, v):
        return 0.5 * mass * v @ v - 0.5 * q @ q - 0.1 * q[0] ** 4

    def force(q, v):
        return -damping * v

    def forms(q):
        return jnp.stack([jnp.stack([c, 1.0 + 0.3 * jnp.sin(q[0])])])

    return dv.LagrangeDiracSystem(("x", "y"), lagrangian, constraints=forms, force=force)


THETA = jnp.array([1.3, 0.2, 0.7])
Q0 = jnp.array([0.4, -0.2])
P0 = jnp.array([0.3, 0.1])


SLOW = pytest.mark.slow  # each case compiles a run and its gradient (≈ 5–20 s)


@pytest.mark.parametrize(
    "discretization,scheme",
    [
        ("retraction", "plus"),
        pytest.param("midpoint", "plus", marks=SLOW),
        pytest.param("retraction", "minus", marks=SLOW),
        ("midpoint", "minus"),
    ],
)
def test_newton_gradients_match_finite_differences(discretization, scheme):
    """q0, p0 and a Lagrangian, a force and a constraint parameter, on the Newton path."""

    def loss(q0, p0, theta):
        traj = dv.simulate(
            bead(theta),
            q0,
            p0,
            dt=DT,
            steps=STEPS,
            discretization=discretization,
            scheme=scheme,
        )
        return jnp.sum(traj.q**2) + jnp.sum(traj.p[-1]) + jnp.sum(traj.multipliers)

    _fd_check(loss, (Q0, P0, THETA))


def test_forward_and_reverse_mode_agree_with_central_differences():
    """The nonlinear constrained bead, midpoint rule, over 40 steps (checkpointed: several
    segments): jax.jacfwd and jax.jacrev of the final state with respect to
    (q0, p0, θ) both equal central differences of the same compiled run."""

    def final(args):
        q0, p0, theta = args[:2], args[2:4], args[4:]
        traj = dv.simulate(bead(theta), q0, p0, dt=DT, steps=STEPS, discretization="midpoint")
        return jnp.concatenate([traj.q[-1], traj.p[-1], traj.multipliers[-1]])

    args = jnp.concatenate([Q0, P0, THETA])
    run = jax.jit(final)
    forward = np.asarray(jax.jit(jax.jacfwd(final))(args))
    reverse = np.asarray(jax.jit(jax.jacrev(final))(args))
    eps = 1e-5
    fd = np.stack(
        [
            (np.asarray(run(args.at[i].add(eps))) - np.asarray(run(args.at[i].add(-eps))))
            / (2 * eps)
            for i in range(args.size)
        ],
        axis=1,
    )
    scale = np.max(np.abs(fd))
    assert np.max(np.abs(forward - fd)) <= 1e-6 * scale
    assert np.max(np.abs(reverse - fd)) <= 1e-6 * scale
    assert np.max(np.abs(forward - reverse)) <= 1e-11 * scale


def test_step_derivative_uses_the_jacobian_at_the_solution():
    """One traced step from a guess far from its solution (h = 0.8: the quartic and the
    angle-dependent constraint make ∂r/∂x at the guess differ from ∂r/∂x at the
    solution by a few per cent): forward- and reverse-mode derivatives of the solved x
    with respect to (q, p, θ) equal central differences of the solve to 1e-7. A
    derivative formed with the Jacobian at the guess, or with factors the chord Newton
    iteration kept from an earlier iterate, is off by about as much as the Jacobians
    differ."""
    from diracvi.discretization.equations import StepEquations, first_guess
    from diracvi.discretization.rules import get_rule
    from diracvi.driver.traced import ImplicitStep

    rule = get_rule("midpoint")
    solver = ImplicitStep(dv.NewtonSolver())
    h = jnp.asarray(0.8)

    def solved(args):
        q, p, theta = args[:2], args[2:4], args[4:]
        system = bead(theta)
        eqs = StepEquations(system, rule, "plus", h, q, p, jnp.asarray(0.0))
        guess = first_guess(system, rule, q, q, jnp.zeros(system.m))  # x far from the root
        res = solver.solve(eqs, guess, solver.init(eqs))
        jac = jax.jacfwd(eqs.residual)
        return res.x, (res.status, res.iterations, jac(res.x), jac(guess))

    args = jnp.concatenate([jnp.array([0.9, -0.6]), jnp.array([1.5, 0.8]), THETA])
    _, (status, iterations, at_x, at_guess) = jax.jit(solved)(args)
    assert int(status) == 0 and int(iterations) >= 3  # a genuinely nonlinear solve
    change = np.max(np.abs(at_x - at_guess)) / np.max(np.abs(at_x))
    assert change > 1e-2  # ≫ the tolerance below: a stale Jacobian would be visibly wrong
    value = jax.jit(lambda a: solved(a)[0])
    forward = np.asarray(jax.jit(jax.jacfwd(lambda a: solved(a)[0]))(args))
    reverse = np.asarray(jax.jit(jax.jacrev(lambda a: solved(a)[0]))(args))
    eps = 1e-6
    fd = np.stack(
        [
            (np.asarray(value(args.at[i].add(eps))) - np.asarray(value(args.at[i].add(-eps))))
            / (2 * eps)
            for i in range(args.size)
        ],
        axis=1,
    )
    scale = np.max(np.abs(fd))
    assert np.max(np.abs(forward - fd)) <= 1e-7 * scale
    assert np.max(np.abs(reverse - fd)) <= 1e-7 * scale


# ------------------------------------------------------ a linear (affine) model: RLC
def rlc(theta):
    """The paper's parallel RLC (diracvi.problems.rlc_circuit) with traced R, L, C."""
    r, ell, cap = theta[0], theta[1], theta[2]

    def lagrangian(q, v):
        return 0.5 * ell * v[1] ** 2 - q[2] ** 2 / (2.0 * cap)

    def force(q, v):
        return jnp.stack([-r * v[0], 0.0 * v[1], 0.0 * v[2]])

    return dv.LagrangeDiracSystem(
        ("qR", "qL", "qC"),
        lagrangian,
        constraints=np.array([[1.0, -1.0, -1.0]]),
        force=force,
        name="rlc",
    )


RLC = jnp.array([1.0, 0.75, 3.0])


@pytest.mark.parametrize("discretization", [pytest.param("retraction", marks=SLOW), "midpoint"])
def test_linear_model_gradients_match_finite_differences(discretization):
    """The affine-stepped RLC: traced, Newton in one iteration, same implicit derivative."""
    q0 = jnp.zeros(3)
    p0 = jnp.array([0.0, 7.5, 0.0])

    def loss(q0, p0, theta):
        traj = dv.simulate(rlc(theta), q0, p0, dt=0.1, steps=STEPS, discretization=discretization)
        return jnp.sum(traj.q[:, 2] ** 2) + jnp.sum(traj.p[-1]), traj.q

    q = _fd_check(loss, (q0, p0, RLC), has_aux=True)
    # the traced (Newton) run agrees with the untraced affine map
    system = problems.rlc_circuit(dt=0.1, steps=STEPS).system
    untraced = dv.simulate(system, q0, p0, dt=0.1, steps=STEPS, discretization=discretization)
    assert untraced.solver == "affine step map"
    assert np.max(np.abs(np.asarray(q) - untraced.q)) <= 1e-12 * np.max(np.abs(untraced.q))


# ------------------------------------------- a torn model, on the partitioned solver
def torn_chain(theta):
    """Two masses | a third, torn at a massless port; nonlinear springs (stiffness k,
    hardening a)."""
    k, a = theta[0], theta[1]

    def spring(d):
        return 0.5 * k * d**2 + 0.25 * a * d**4

    def l1(q, v):
        return 0.5 * (v[0] ** 2 + v[1] ** 2) - spring(q[0]) - spring(q[1] - q[0])

    def l2(q, v):
        return 0.5 * v[1] ** 2 - spring(q[1] - q[0])

    left = dv.LagrangeDiracSystem(("q1", "q2"), l1, name="left")
    right = dv.LagrangeDiracSystem(("q2bar", "q3"), l2, name="right")
    return dv.interconnect([left, right], [dv.connect("left.q2", "right.q2bar")])


# in `-m slow` (18 s; the default suite's time on CI): by default, gradients through the
# Newton path (test_newton_gradients_match_finite_differences) and the sparse netlist path
# (tests/test_components.py's traced parts)
@pytest.mark.parametrize(
    "discretization,scheme",
    [pytest.param("retraction", "plus", marks=SLOW), pytest.param("midpoint", "minus", marks=SLOW)],
)
def test_torn_model_partitioned_gradients_match_finite_differences(discretization, scheme):
    q0 = jnp.array([0.1, 0.5, 0.5, 1.0])
    p0 = jnp.array([0.0, 0.2, 0.0, -0.3])

    def loss(q0, theta):
        traj = dv.simulate(
            torn_chain(theta),
            q0,
            p0,
            dt=DT,
            steps=STEPS,
            discretization=discretization,
            scheme=scheme,
            solver=dv.PartitionedSolver(),
        )
        assert "PartitionedSolver" in traj.solver
        return jnp.sum(traj.q**2) + jnp.sum(traj.multipliers)

    _fd_check(loss, (q0, jnp.array([1.0, 0.5])))


# 9 s, in `-m slow` (CI time): parameters as traced leaves are differentiated by default in
# test_newton_gradients_match_finite_differences and tests/test_components.py
@pytest.mark.slow
def test_equinox_module_parameters_and_filter_grad():
    """An equinox.Module Lagrangian: its arrays are leaves of the system."""

    class Spring(eqx.Module):
        k: jax.Array

        def __call__(self, q, v):
            return 0.5 * v @ v - 0.5 * self.k * q @ q - 0.05 * q[0] ** 4

    system = dv.LagrangeDiracSystem(("a", "b"), Spring(jnp.array(2.0)))
    q0, p0 = np.array([0.3, -0.1]), np.array([0.0, 0.4])

    @eqx.filter_jit
    @eqx.filter_grad
    def grad(system):
        return jnp.sum(dv.simulate(system, q0, p0, dt=DT, steps=STEPS).q[-1])

    g = grad(system)._lagrangian.arrays.k

    @jax.jit
    def value(k):  # the Module built inside the traced function
        system = dv.LagrangeDiracSystem(("a", "b"), Spring(k))
        return jnp.sum(dv.simulate(system, q0, p0, dt=DT, steps=STEPS).q[-1])

    eps = 1e-5
    fd = (value(2.0 + eps) - value(2.0 - eps)) / (2 * eps)
    assert abs(float(g) - float(fd)) <= 1e-6 * abs(float(fd))


def test_driven_model_t0_and_input_gradients():
    """A force F(q, v, t) closing over a traced input amplitude, and a traced t0; forward
    mode (jacfwd) against finite differences."""

    def loss(args):
        u, t0 = args[0], args[1]

        def force(q, v, t):
            return jnp.stack([u * jnp.sin(3.0 * t)])

        system = dv.LagrangeDiracSystem(
            ("x",), lambda q, v: 0.5 * v @ v - 0.5 * q @ q - 0.2 * q[0] ** 4, force=force
        )
        traj = dv.simulate(system, jnp.array([0.2]), jnp.array([0.0]), dt=DT, steps=STEPS, t0=t0)
        return jnp.sum(traj.q**2)

    args = jnp.array([0.8, 0.3])
    jac = jax.jit(jax.jacfwd(loss))(args)
    value = jax.jit(loss)
    eps = 1e-5
    fd = np.array(
        [(value(args.at[i].add(eps)) - value(args.at[i].add(-eps))) / (2 * eps) for i in range(2)]
    )
    assert np.max(np.abs(np.asarray(jac) - fd)) <= 1e-6 * np.max(np.abs(fd))


# ------------------------------------------------------------------- composability
def _pendulum():
    return dv.LagrangeDiracSystem(
        ("th",), lambda q, v: 0.5 * v[0] ** 2 + 9.81 * jnp.cos(q[0]), name="pendulum"
    )


def test_jit_equals_untraced_and_compiles_once():
    system = _pendulum()
    p0 = np.array([0.0])
    traces = []

    @jax.jit
    def run(q0):
        traces.append(1)
        return dv.simulate(system, q0, p0, dt=0.01, steps=200, save_every=4)

    for q0 in ([0.5], [1.0]):
        traced = run(jnp.array(q0))
        ref = dv.simulate(system, np.array(q0), p0, dt=0.01, steps=200, save_every=4)
        for name in ("t", "q", "p", "energy", "constraint_violation"):
            a, b = np.asarray(getattr(traced, name)), getattr(ref, name)
            assert np.max(np.abs(a - b), initial=0.0) <= 1e-14 * max(np.max(np.abs(b)), 1.0)
        assert int(traced.status) == 0 and traced.steps == ref.steps
    assert len(traces) == 1  # compiled once


def test_vmap_over_initial_states_equals_single_runs():
    system = _pendulum()
    q0s = jnp.array([[0.1], [0.7], [1.5]])
    batch = jax.jit(jax.vmap(lambda q0: dv.simulate(system, q0, jnp.zeros(1), dt=0.02, steps=50)))(
        q0s
    )
    assert batch.q.shape == (3, 51, 1)
    for i in range(3):
        single = dv.simulate(system, np.asarray(q0s[i]), np.zeros(1), dt=0.02, steps=50)
        assert np.max(np.abs(np.asarray(batch.q[i]) - single.q)) <= 1e-14


def test_adjoints_agree(monkeypatch):
    """Rematerialized and fully stored reverse mode give the same gradient: each step
    rematerialized (the default for a run this short), and also split into checkpointed
    segments (forced: this run is small enough to be stored whole by default). The
    backward pass re-forms each step's linearization from its stored solution, so it
    must repeat the stored one's numbers to round-off."""
    from diracvi.discretization.rules import get_rule
    from diracvi.driver import traced

    assert traced.stored_bytes(_pendulum(), get_rule("midpoint"), 90) <= traced.STORE_ALL_BYTES
    system = _pendulum()

    def loss(q0, adjoint):
        traj = dv.simulate(system, q0, jnp.zeros(1), dt=0.01, steps=90, adjoint=adjoint)
        return jnp.sum(traj.q**2)

    q0 = jnp.array([0.9])
    full = jax.jit(jax.grad(loss), static_argnums=1)(q0, "full")
    stepwise = jax.jit(jax.grad(loss), static_argnums=1)(q0, "checkpoint")
    monkeypatch.setattr(traced, "STORE_ALL_BYTES", 0)
    segmented = jax.jit(jax.grad(loss), static_argnums=1)(q0, "checkpoint")
    assert np.allclose(stepwise, full, rtol=1e-13, atol=0)
    assert np.allclose(segmented, full, rtol=1e-13, atol=0)


# ≈ 10 CPU s (two reverse-mode programs of the torn pendulum compiled), in `-m slow` (CI time)
@pytest.mark.slow
def test_checkpoint_adjoint_keeps_less_than_full():
    """``adjoint="checkpoint"`` rematerializes each step (``traced.ImplicitStep`` with
    ``remat``): reverse mode keeps the steps' solutions and inputs, not their
    linearizations. On the torn double pendulum (4 coordinates, 2 constraints: the step's
    6×6 ``∂r/∂x`` and its inverse per step when stored) the residuals JAX keeps for the
    backward pass take less than half of ``adjoint="full"``'s, and the gradients agree
    to round-off."""
    from diracvi import problems

    problem = problems.double_pendulum_torn()

    def loss(q0, adjoint):
        traj = dv.simulate(
            problem.system,
            q0,
            problem.p0,
            dt=problem.dt,
            steps=50,
            discretization="midpoint",
            adjoint=adjoint,
        )
        return jnp.sum(traj.q**2)

    q0 = jnp.asarray(problem.q0)

    def kept(adjoint):
        _, backward = jax.jit(lambda a: jax.vjp(lambda x: loss(x, adjoint), a))(q0)
        leaves = jax.tree.leaves(backward)
        return sum(leaf.nbytes for leaf in leaves), np.asarray(backward(jnp.ones(()))[0])

    full_bytes, full = kept("full")
    remat_bytes, remat = kept("checkpoint")
    assert remat_bytes < 0.5 * full_bytes
    assert np.allclose(remat, full, rtol=1e-13, atol=0)


def test_host_only_options_are_refused_when_traced(tmp_path):
    system = _pendulum()
    with pytest.raises(dv.ModelError, match="checkpoint="):
        jax.jit(
            lambda q0: (
                dv.simulate(
                    system, q0, jnp.zeros(1), dt=0.01, steps=10, checkpoint=tmp_path / "c.nc"
                ).q
            )
        )(jnp.array([0.1]))
    with pytest.raises(dv.ModelError, match="project_initial"):
        jax.jit(
            lambda q0: (
                dv.simulate(system, q0, jnp.zeros(1), dt=0.01, steps=10, project_initial=True).q
            )
        )(jnp.array([0.1]))
    with pytest.raises(dv.ModelError, match="adjoint"):
        dv.simulate(system, [0.1], [0.0], dt=0.01, steps=10, adjoint="backsolve")


def test_traced_failure_status_and_throw():
    """throw=False: the status code in the result; throw=True: a runtime error."""
    system = _pendulum()
    solver = dv.NewtonSolver(max_steps=1, reuse_jacobian=False)

    def run(q0, throw):
        return dv.simulate(system, q0, jnp.zeros(1), dt=0.5, steps=5, solver=solver, throw=throw)

    traj = jax.jit(lambda q0: run(q0, False))(jnp.array([2.5]))
    assert int(traj.status) == dv.SolveStatus.MAX_ITERATIONS
    with warnings.catch_warnings(), pytest.raises(Exception, match="a step failed"):
        warnings.simplefilter("ignore")
        jax.block_until_ready(jax.jit(lambda q0: run(q0, True).q)(jnp.array([2.5])))


def test_traced_constant_constraint_array():
    """A constant one-form matrix holding a traced parameter (forward mode)."""

    def final(c):
        system = dv.LagrangeDiracSystem(
            ("x", "y"),
            lambda q, v: 0.5 * v @ v - 0.5 * q @ q - 0.1 * q[0] ** 4,
            constraints=jnp.stack([jnp.stack([c, 1.0])]),
        )
        return jnp.sum(dv.simulate(system, Q0, P0, dt=DT, steps=STEPS).q[-1])

    both = jax.jit(lambda c: jax.jvp(final, (c,), (1.0,)))  # one compilation for both
    slope = both(0.7)[1]
    eps = 1e-5
    fd = (both(0.7 + eps)[0] - both(0.7 - eps)[0]) / (2 * eps)
    assert abs(float(slope) - float(fd)) <= 1e-6 * abs(float(fd))


@pytest.mark.slow  # compiling the reverse-mode program of the staged step takes a while
def test_lobatto_runs_traced_with_implicit_function_gradients():
    """The staged rule under jax.grad: the traced run equals the untraced one, and the
    gradient with respect to q₀ matches central differences."""
    problem = problems.get("forced-oscillator")

    def final(q0):
        traj = dv.simulate(
            problem.system, q0, problem.p0, dt=DT, steps=20, discretization="lobatto"
        )
        return traj.q[-1, 0]

    q0 = jnp.asarray(problem.q0)
    untraced = dv.simulate(
        problem.system, problem.q0, problem.p0, dt=DT, steps=20, discretization="lobatto"
    )
    assert abs(float(jax.jit(final)(q0)) - float(untraced.q[-1, 0])) <= 1e-13
    _fd_check(final, (q0,))


def test_tangent_inverse_elimination_matches_lapack():
    """The traced step's inverse Jacobian (plain-lax Gauss–Jordan with partial pivoting)
    against LAPACK, unrolled (n ≤ 16) and looped (n = 21), on matrices that need row
    exchanges (zero and tiny leading pivots)."""
    from diracvi.driver.traced import _UNROLL_SIZE, _inverse

    rng = np.random.default_rng(7)
    inverse = jax.jit(_inverse)
    assert 8 <= _UNROLL_SIZE < 21  # both code paths below
    for n in (1, 3, 8, 21):
        a = rng.normal(size=(n, n))
        a[0, 0] = 0.0 if n > 1 else 2.0
        if n > 2:
            a[1, 1] = 1e-14  # a tiny pivot that must not be used
        x = np.asarray(inverse(jnp.asarray(a)))
        expected = np.linalg.inv(a)
        cond = np.linalg.cond(a)
        assert np.max(np.abs(x - expected)) <= 1e-13 * cond * np.max(np.abs(expected))
