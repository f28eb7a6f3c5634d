"""PartitionedSolver under the order-4 rule "lobatto": stages kept local to their subsystem.

Each subsystem's step unknowns under "lobatto" are its own ``q_other``, its two stage
unknowns and its three stage multipliers; every interaction row is imposed at the three
stages, each copy with its own multiplier (``docs/discretizations.md``). These tests hold
the partitioned solver to the paper's theorem (torn ≡ monolithic), to dense Newton's
iterates, and to the automatic solver choice.

White-box: reads internals of ``diracvi.discretization.equations``,
``diracvi.discretization.rules``, ``diracvi.driver.plan``."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given

import diracvi as dv
from conftest import examples
from diracvi import problems
from diracvi.discretization.equations import StepEquations, first_guess
from diracvi.discretization.rules import get_rule
from test_partitioned import check_random_interconnection, constant_interconnection, star

PARTITIONED = dv.PartitionedSolver()
DENSE = dv.NewtonSolver(reuse_jacobian=False)
LOBATTO = get_rule("lobatto")


def relative(a, b) -> float:
    return float(np.max(np.abs(a - b), initial=0.0) / max(1.0, np.max(np.abs(a), initial=0.0)))


# (problem, scheme): every constant interconnection the other rules' tests tear, under
# both schemes; the cheapest by default and the twins with -m slow (each compiles two
# programs). The torn double pendulum's joint depends on θ₁: see the refusal test.
THEOREM = [
    ("chain-torn", "plus", True),
    ("chain-torn", "minus", True),
    ("spring-chain-torn", "minus", True),
    ("spring-chain-torn", "plus", True),
    ("rlc-torn", "minus", False),  # degenerate, with a massless port: the default case
    ("rlc-torn", "plus", True),
    ("dc-motor", "plus", True),
    ("dc-motor", "minus", True),
]


@pytest.mark.parametrize(
    ("name", "scheme"),
    [
        pytest.param(name, scheme, id=f"{name}-{scheme}", marks=[pytest.mark.slow] if slow else [])
        for name, scheme, slow in THEOREM
    ],
)
def test_partitioned_torn_model_equals_dense_monolithic_model(name, scheme):
    """The paper's theorem through the partitioned solver: the torn model stepped piece
    by piece equals the monolithic model stepped by dense Newton, ≤ 1e-12 relative."""
    problem = problems.get(name)
    kwargs = {"dt": problem.dt, "steps": 100, "discretization": "lobatto", "scheme": scheme}
    torn = dv.simulate(problem.system, problem.q0, problem.p0, solver=PARTITIONED, **kwargs)
    mono = dv.simulate(problem.system.monolithic(), problem.q0, problem.p0, solver=DENSE, **kwargs)
    assert torn.success and mono.success
    assert relative(mono.q, torn.q) <= 1e-12
    assert relative(mono.p, torn.p) <= 1e-12
    assert relative(mono.multipliers, torn.multipliers) <= 1e-10


def newton_iterates(system, q0, p0, scheme, iterations):
    """The first step's result after each count of pure Newton iterations from a guess
    off the solution, for dense Newton and the partitioned solver."""
    q0, p0 = jnp.asarray(q0), jnp.asarray(p0)
    eqs = StepEquations(system, LOBATTO, scheme, jnp.asarray(0.05), q0, p0)
    guess = first_guess(system, LOBATTO, q0, q0 + 0.02, jnp.zeros(system.m))

    @eqx.filter_jit
    def solve(solver):
        return solver.solve(eqs, guess, solver.init(eqs))

    return {
        (kind.__name__, count): solve(kind(max_steps=count, reuse_jacobian=False))
        for kind in (dv.NewtonSolver, dv.PartitionedSolver)
        for count in iterations
    }


@pytest.mark.parametrize(
    # with -m slow: the default run shows partitioned lobatto = dense on the torn RLC below
    "counts",
    [pytest.param((40,), marks=pytest.mark.slow), pytest.param((1, 2), marks=pytest.mark.slow)],
    ids=["converged", "1-2"],
)
def test_partitioned_newton_takes_dense_newtons_iterates(rng, counts):
    """Iterate by iterate (1, 2) and converged (both with -m slow) the same ``x`` as
    dense Newton on the interconnection's own step equations, after the same number of
    iterations: a nonlinear hub (``cos q`` terms) joined to three massless ports, under
    (−), with a dense interface."""
    system, q0, p0 = star(rng)
    out = newton_iterates(system, q0, p0, "minus", counts)
    for count in counts:
        dense, split = out[("NewtonSolver", count)], out[("PartitionedSolver", count)]
        assert relative(np.asarray(dense.x), np.asarray(split.x)) <= 1e-12
        assert int(dense.iterations) == int(split.iterations)
    if counts == (40,):
        assert int(out[("PartitionedSolver", 40)].status) == 0
        assert int(out[("PartitionedSolver", 40)].iterations) >= 3  # a nonlinear step
    else:  # the iterates move: these are not the converged x
        one, two = (np.asarray(out[("NewtonSolver", c)].x) for c in counts)
        assert relative(one, two) > 1e-10


def test_the_automatic_choice_picks_the_partitioned_solver_for_a_large_lobatto_chain():
    from diracvi.driver.plan import default_solver

    big = problems.chain_torn(masses=200, pieces=100).system  # 299 + 99 unknowns
    for rule in ("midpoint", "lobatto"):
        assert isinstance(default_solver(big, get_rule(rule), "plus"), dv.PartitionedSolver)
    layout = dv.PartitionedSolver.layout(big, "lobatto", "minus")
    assert layout.row_copies == 3
    # one slot per copy of a joint and side; in slot order the chain's T is banded
    assert layout.interface_size == 3 * 2 * 99
    assert layout.interface.startswith("banded")
    assert layout.local_unknowns == (6, 9, 9)  # 3(n + m): the wall piece, then ported ones


def test_lobatto_with_a_configuration_dependent_interaction_is_refused_with_the_fix():
    """The torn double pendulum's joint ``B(θ₁)`` is imposed at the stages, which move
    with the unknowns: not linear, not split by subsystem. Refused by name; the automatic
    choice falls back to dense Newton."""
    from diracvi.driver.plan import default_solver

    problem = problems.get("double-pendulum-torn")
    with pytest.raises(dv.ModelError) as info:
        dv.PartitionedSolver.check(problem.system, "lobatto", "plus")
    message = str(info.value)
    for needle in ("('joint_x', 'joint_y')", "discretization='lobatto'", "stages Q_j"):
        assert needle in message
    assert "dv.NewtonSolver()" in message
    assert isinstance(default_solver(problem.system, LOBATTO, "plus"), dv.NewtonSolver)
    # constant interactions are accepted under both schemes
    for scheme in ("plus", "minus"):
        dv.PartitionedSolver.check(problems.get("rlc-torn").system, "lobatto", scheme)


@pytest.mark.slow
def test_a_large_chain_is_stepped_by_the_partitioned_solver_automatically():
    """254 masses in five pieces (258 unknowns of the plain step, 774 with the stages):
    ``solver=None`` picks the partitioned solver, whose pieces keep their stages and
    stage multipliers local with banded factors, and the run equals dense Newton on the
    monolithic chain."""
    from diracvi.driver.plan import default_solver

    problem = problems.chain_torn(masses=250, pieces=5)
    system = problem.system
    assert isinstance(default_solver(system, LOBATTO, "plus"), dv.PartitionedSolver)
    layout = dv.PartitionedSolver.layout(system, "lobatto")
    assert layout.row_copies == 3
    sizes = [3 * (system.subsystems[0].n + system.subsystems[0].m)]
    sizes += [3 * (system.subsystems[1].n + system.subsystems[1].m)] * (len(layout.groups) - 1)
    assert list(layout.local_unknowns) == sizes
    # interleaved per coordinate, a piece's nearest-neighbour springs stay in a narrow band
    assert all(f.startswith("banded") for f in layout.local_factors)
    kwargs = {"dt": problem.dt, "steps": 10, "discretization": "lobatto"}
    auto = dv.simulate(system, problem.q0, problem.p0 + 0.5, **kwargs)
    assert "PartitionedSolver" in auto.solver
    mono = dv.simulate(system.monolithic(), problem.q0, problem.p0 + 0.5, solver=DENSE, **kwargs)
    assert relative(mono.q, auto.q) <= 1e-12
    assert relative(mono.p, auto.p) <= 1e-12


@pytest.mark.slow
@examples(4)  # each example compiles both solvers on the staged step (~10 s)
@given(case=constant_interconnection(discretizations=("lobatto",)))
def test_random_constant_interconnections_match_dense_newton_under_lobatto(case):
    """Connections, rows within one subsystem (the direct form) and rows across three,
    own constraints constant and configuration-dependent: the same run as dense Newton."""
    check_random_interconnection(case)
