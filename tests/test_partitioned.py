"""PartitionedSolver: the same steps as dense Newton, solved subsystem by subsystem.

White-box: reads internals of ``diracvi.discretization.equations``,
``diracvi.discretization.rules``, ``diracvi.solvers``."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import diracvi as dv
from conftest import examples
from diracvi import problems
from diracvi.discretization.equations import StepEquations, first_guess
from diracvi.discretization.rules import get_rule
from diracvi.problems.spring_chain import SegmentLagrangian

DENSE = dv.NewtonSolver(reuse_jacobian=False)
PARTITIONED = dv.PartitionedSolver()


def relative(a, b) -> float:
    return float(np.max(np.abs(a - b), initial=0.0) / max(1.0, np.max(np.abs(a), initial=0.0)))


def same_as_dense(system, q0, p0, *, dt, steps, discretization="retraction", scheme="plus"):
    kwargs = {"dt": dt, "steps": steps, "discretization": discretization, "scheme": scheme}
    dense = dv.simulate(system, q0, p0, solver=DENSE, **kwargs)
    split = dv.simulate(system, q0, p0, solver=PARTITIONED, **kwargs)
    assert dense.success and split.success
    assert relative(dense.q, split.q) <= 1e-12
    assert relative(dense.p, split.p) <= 1e-12
    assert relative(dense.multipliers, split.multipliers) <= 1e-12
    return split


def nested_chain():
    """chain_torn(9, 3) with its first two pieces joined first: a nested block."""
    flat = problems.chain_torn(9, 3)
    s0, s1, s2 = flat.system.subsystems
    front = dv.interconnect([s0, s1], [dv.connect(f"s0.{s0.coords[-1]}", "s1.qbar")], name="f")
    whole = dv.interconnect([front, s2], [dv.connect(f"f.s1.{s1.coords[-1]}", "s2.qbar")])
    return dataclasses.replace(flat, system=whole)


# (problem, discretization, scheme): every problem under both schemes where its step is
# solvable (the torn RLC's left-point (−) step is not), and the midpoint rule wherever
# the interactions are constant
CASES = [
    (lambda: problems.chain_torn(9, 9), "retraction", "plus"),  # single-mass pieces
    (lambda: problems.chain_torn(17, 5), "retraction", "minus"),  # uneven pieces
    (lambda: problems.chain_torn(6, 3), "midpoint", "plus"),
    (lambda: problems.get("rlc-torn"), "retraction", "plus"),
    (lambda: problems.get("rlc-torn"), "midpoint", "minus"),
    (lambda: problems.get("double-pendulum-torn"), "retraction", "plus"),
    (lambda: problems.get("double-pendulum-torn"), "retraction", "minus"),
    (lambda: problems.get("dc-motor"), "retraction", "minus"),
    (lambda: problems.get("dc-motor"), "midpoint", "plus"),
    (nested_chain, "retraction", "plus"),
]
IDS = [
    "chain9x9-plus",
    "chain17x5-minus",
    "chain6x3-midpoint",
    "rlc-plus",
    "rlc-midpoint-minus",
    "pendulum-plus",
    "pendulum-minus",
    "motor-minus",
    "motor-midpoint",
    "nested-chain",
]


# the heaviest twins (each compiles both solvers) run with -m slow
SLOW_CASES = {
    "chain9x9-plus",
    "chain17x5-minus",
    "rlc-midpoint-minus",
    "nested-chain",
    "pendulum-minus",
    "motor-minus",
    "motor-midpoint",
}


@pytest.mark.parametrize(
    ("make", "discretization", "scheme"),
    [
        pytest.param(*case, id=i, marks=[pytest.mark.slow] if i in SLOW_CASES else [])
        for case, i in zip(CASES, IDS, strict=True)
    ],
)
def test_same_trajectory_as_dense_newton(make, discretization, scheme):
    problem = make()
    same_as_dense(
        problem.system,
        problem.q0,
        problem.p0,
        dt=problem.dt,
        steps=20,
        discretization=discretization,
        scheme=scheme,
    )


LONG_RUNS = [
    (name, discretization, scheme)
    for name in ("chain-torn", "spring-chain-torn", "rlc-torn", "dc-motor")
    for discretization in ("retraction", "midpoint")
    for scheme in ("plus", "minus")
    # the torn RLC's left-point (−) step is singular: simulate() refuses it before stepping
    if (name, discretization, scheme) != ("rlc-torn", "retraction", "minus")
]


@pytest.mark.slow
@pytest.mark.parametrize(("name", "discretization", "scheme"), LONG_RUNS)
def test_every_constant_interconnection_over_a_long_run(name, discretization, scheme):
    problem = problems.get(name)
    same_as_dense(
        problem.system,
        problem.q0,
        problem.p0,
        dt=problem.dt,
        steps=500,
        discretization=discretization,
        scheme=scheme,
    )


# ------------------------------------------------------------------ layout
def test_equal_chain_segments_are_batched_and_the_interface_is_tridiagonal():
    problem = problems.chain_torn(9, 9)
    layout = dv.PartitionedSolver.layout(problem.system)
    # the wall piece, seven equal ported pieces (one vmap), and the end piece (one row)
    assert layout.groups == (("s0",), tuple(f"s{i}" for i in range(1, 8)), ("s8",))
    assert layout.interface == "tridiagonal"
    assert layout.interface_size == 2 * 8  # two slots per joint


class Quadratic(eqx.Module):
    """``L = ½ vᵀ M v − ½ qᵀ K q + c · cos q`` with its matrices as PyTree leaves."""

    mass: jax.Array
    stiff: jax.Array
    wobble: jax.Array

    def __call__(self, q, v):
        return 0.5 * v @ self.mass @ v - 0.5 * q @ self.stiff @ q + self.wobble @ jnp.cos(q)


class Tilted(eqx.Module):
    """A configuration-dependent own constraint ``A(q) = a + t ⊙ sin q``."""

    row: jax.Array
    tilt: jax.Array

    def __call__(self, q):
        return self.row + self.tilt * jnp.sin(q)[None, :]


def quadratic(rng, n):
    a, b = rng.normal(size=(n, n)), rng.normal(size=(n, n))
    return Quadratic(
        jnp.asarray(a @ a.T + n * np.eye(n)), jnp.asarray(b @ b.T), jnp.asarray(rng.normal(size=n))
    )


def star(rng):
    """A hub with three coordinates, each joined to the massless port of a one-mass leaf."""
    hub = dv.LagrangeDiracSystem(("x", "y", "z"), quadratic(rng, 3), name="hub")
    leaves = [
        dv.LagrangeDiracSystem(
            ("qbar", "q0"),
            SegmentLagrangian(jnp.asarray([1.0 + i]), jnp.asarray([2.0 - 0.5 * i]), True),
            name=f"leaf{i}",
        )
        for i in range(3)
    ]
    joints = [dv.connect(f"hub.{c}", f"leaf{i}.qbar") for i, c in enumerate("xyz")]
    system = dv.interconnect([hub, *leaves], joints, name="star")
    hub_q = rng.normal(size=3)
    q0 = np.concatenate([hub_q, *([hub_q[i], hub_q[i] + 1.0] for i in range(3))])
    return system, q0, rng.normal(size=system.n)


# 8 s, in `-m slow` (the default suite's time on CI): the star interface only there; by
# default the tridiagonal one (test_equal_chain_segments_are_batched_and_the_interface_is_...)
@pytest.mark.slow
def test_a_star_interface_is_solved_densely(rng):
    system, q0, p0 = star(rng)
    layout = dv.PartitionedSolver.layout(system)
    assert layout.groups == (("hub",), ("leaf0", "leaf1", "leaf2"))
    assert layout.interface == "dense"
    same_as_dense(system, q0, p0, dt=0.01, steps=20)


# ------------------------------------------------------------------ random systems
@st.composite
def constant_interconnection(draw, discretizations=("retraction", "midpoint")):
    """2–5 subsystems (mass matrices, springs, own constraints of every kind) joined by
    constant rows: connections, rows within one subsystem, rows across two or three."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    sizes = draw(st.lists(st.integers(1, 3), min_size=2, max_size=5))
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    subsystems, free = [], []
    for i, n in enumerate(sizes):
        kind = draw(st.sampled_from(["none", "constant", "q-dependent"])) if n >= 2 else "none"
        row, tilt = rng.normal(size=(1, n)), 0.3 * rng.normal(size=(1, n))
        forms = {"none": None, "constant": row, "q-dependent": Tilted(row, tilt)}[kind]
        subsystems.append(
            dv.LagrangeDiracSystem(
                [f"x{j}" for j in range(n)], quadratic(rng, n), constraints=forms, name=f"s{i}"
            )
        )
        if kind == "none" and n >= 2:
            free.append(i)  # room for one more row inside it
    total = int(offsets[-1])
    interactions = []
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["connect", "within", "across"]))
        if kind == "within" and free:
            i = free.pop(draw(st.integers(0, len(free) - 1)))
            involved = [i]
        else:
            involved = draw(st.permutations(range(len(sizes))))[: 2 if kind == "connect" else 3]
        if kind == "connect":
            (i, a), (j, b) = [(k, draw(st.integers(0, sizes[k] - 1))) for k in involved[:2]]
            interactions.append(dv.connect(f"s{i}.x{a}", f"s{j}.x{b}"))
            continue
        row = np.zeros((1, total))
        for k in involved:
            row[0, offsets[k] : offsets[k + 1]] = rng.normal(size=sizes[k])
        interactions.append(dv.Interaction(row))
    system = dv.interconnect(subsystems, interactions)
    discretization = draw(st.sampled_from(list(discretizations)))
    scheme = draw(st.sampled_from(["plus", "minus"]))
    q0, p0 = dv.project_initial_state(system, 0.5 * rng.normal(size=total), rng.normal(size=total))
    return system, q0, p0, discretization, scheme


# each example compiles both solvers (~5–10 s): one by default (the default suite's time
# on CI; the fixed cases above cover the solver's kinds of interface), 10 with the slow profile
@examples(1)
@given(case=constant_interconnection())
def test_random_constant_interconnections_match_dense_newton(case):
    check_random_interconnection(case)


def check_random_interconnection(case):
    system, q0, p0, discretization, scheme = case
    kwargs = {"dt": 0.01, "steps": 20, "discretization": discretization, "scheme": scheme}
    try:
        dense = dv.simulate(system, q0, p0, solver=DENSE, throw=False, **kwargs)
    except dv.UnsolvableStepError:
        # dependent random rows: the partitioned solver must refuse the model as well
        # (a checked outcome, not a discarded draw)
        with pytest.raises(dv.UnsolvableStepError):
            dv.simulate(system, q0, p0, solver=PARTITIONED, throw=False, **kwargs)
        return
    split = dv.simulate(system, q0, p0, solver=PARTITIONED, throw=False, **kwargs)
    assert split.status == dense.status == 0
    for a, b in ((dense.q, split.q), (dense.p, split.p), (dense.multipliers, split.multipliers)):
        assert relative(a, b) <= 1e-12


# ------------------------------------------------------------------ failures
def first_step(system, q0, p0, solver):
    """One solve of the first (+) step, without simulate()'s dense solvability check."""
    eqs = StepEquations(system, get_rule("retraction"), "plus", jnp.asarray(0.01), q0, p0)
    guess = jnp.concatenate([jnp.asarray(q0), jnp.zeros(system.m)])
    return eqx.filter_jit(lambda e, g: solver.solve(e, g, solver.init(e)))(eqs, guess)


def test_singular_block_and_singular_interface_report_singular():
    problem = problems.get("spring-chain-torn")
    left, right = problem.system.subsystems
    q0, p0 = jnp.asarray(problem.q0), jnp.asarray(problem.p0)
    # the right piece's massless port, joined to nothing: its own block is singular
    loose = dv.interconnect([left, right], [])
    # an all-zero interaction row: every block is fine, the interface system is not
    zero = dv.interconnect([left, right], [dv.Interaction(np.zeros((1, 4)))])
    for system in (loose, zero):
        split = first_step(system, q0, p0, PARTITIONED)
        dense = first_step(system, q0, p0, DENSE)
        assert int(split.status) == int(dense.status) == dv.SolveStatus.SINGULAR


def test_a_single_system_is_refused_with_the_fix():
    single = problems.get("spring-chain").system
    with pytest.raises(dv.ModelError, match=r"NewtonSolver\(\).*dv\.interconnect"):
        dv.PartitionedSolver.check(single)
    with pytest.raises(dv.ModelError, match="needs an interconnected system"):
        dv.simulate(single, [0, 1, 2], [0, 0, 3], dt=0.01, steps=2, solver=PARTITIONED)


def test_midpoint_with_configuration_dependent_interaction_is_refused_with_the_fix():
    problem = problems.get("double-pendulum-torn")
    dv.PartitionedSolver.check(problem.system, "retraction", "minus")  # B at the known q
    with pytest.raises(dv.ModelError) as info:
        dv.PartitionedSolver.check(problem.system, "midpoint", "plus")
    message = str(info.value)
    for needle in ("('joint_x', 'joint_y')", "discretization='midpoint'", "dv.NewtonSolver()"):
        assert needle in message
    assert "discretization='retraction'" in message
    with pytest.raises(dv.ModelError, match="depends on the configuration"):
        dv.simulate(
            problem.system,
            problem.q0,
            problem.p0,
            dt=0.01,
            steps=2,
            discretization="midpoint",
            solver=PARTITIONED,
        )


def test_module_parameters_are_leaves_so_equal_segments_share_one_structure():
    a, b = problems.chain_torn(6, 3).system.subsystems[1:]
    assert a.name != b.name
    assert [x.shape for x in jax.tree_util.tree_leaves(a)] == [(2,), (2,)]  # masses, springs
    assert not np.array_equal(jax.tree_util.tree_leaves(a)[0], jax.tree_util.tree_leaves(b)[0])


# ------------------------------------------------------------------ banded local factors
@pytest.mark.parametrize(
    ("kl", "ku"),
    [(2, 1), (0, 2), *(pytest.param(*b, marks=pytest.mark.slow) for b in ((0, 0), (1, 1), (3, 0)))],
)
def test_banded_lu_with_pivoting_solves_like_numpy(rng, kl, ku):
    from diracvi.solvers import banded as _banded

    size = 23
    i, j = np.indices((size, size))
    a = np.where((j - i <= ku) & (i - j <= kl), rng.normal(size=(size, size)), 0.0)
    if kl and ku:  # zeros on the diagonal: elimination without row swaps would fail
        a[np.arange(0, size, 3), np.arange(0, size, 3)] = 0.0
    assert _banded.bandwidths(a != 0) == (kl, ku)

    @jax.jit
    def solve(products, b):
        factors = _banded.lu(_banded.from_products(products, kl, ku), kl, ku)
        return _banded.solve(factors, b, kl, ku)

    b = rng.normal(size=(size, 3))
    x = np.asarray(solve(jnp.asarray(_banded.seeds(size, kl, ku) @ a.T), jnp.asarray(b)))
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize(
    ("discretization", "scheme", "band"),
    [
        ("midpoint", "plus", "(1, 1)"),
        pytest.param("retraction", "minus", "(0, 0)", marks=pytest.mark.slow),
        # stages interleaved per coordinate: [q_other_c, S_1c, S_2c] couple c ± 1
        pytest.param("lobatto", "minus", "(4, 4)", marks=pytest.mark.slow),
    ],
)
def test_chain_pieces_get_banded_factors_and_the_same_step_as_dense(discretization, scheme, band):
    problem = problems.chain_torn(40, 2)  # pieces of 20 and 21 unknowns
    system, rule = problem.system, get_rule(discretization)
    layout = dv.PartitionedSolver.layout(system, rule, scheme)
    assert layout.local_factors == (f"banded{band}",) * 2
    q0, p0 = jnp.asarray(problem.q0), jnp.asarray(problem.p0 + 0.3)
    eqs = StepEquations(system, rule, scheme, jnp.asarray(0.05), q0, p0)
    guess = first_guess(system, rule, q0, q0 + 0.01, jnp.zeros(system.m))  # two iterations

    @eqx.filter_jit
    def step(solver):
        return solver.solve(eqs, guess, solver.init(eqs))

    banded, dense = step(PARTITIONED), step(dv.PartitionedSolver(local_factors="dense"))
    assert int(banded.status) == int(dense.status) == 0
    assert relative(np.asarray(dense.x), np.asarray(banded.x)) <= 1e-13


def test_a_piece_whose_step_jacobian_is_not_banded_keeps_dense_factors(rng):
    # a full mass matrix couples every velocity: J_i is dense in any order
    pieces = [
        dv.LagrangeDiracSystem(tuple(f"q{i}" for i in range(12)), quadratic(rng, 12), name=f"p{k}")
        for k in range(2)
    ]
    system = dv.interconnect(pieces, [dv.connect("p0.q11", "p1.q0")])
    assert dv.PartitionedSolver.layout(system, "midpoint").local_factors == ("dense",)
    # a diagonal mass and nearest-neighbour springs: banded in the given order
    chain = problems.chain_torn(40, 2).system
    assert dv.PartitionedSolver.layout(chain, "midpoint").local_factors[0] == "banded(1, 1)"
    with pytest.raises(ValueError, match="local_factors"):
        dv.PartitionedSolver(local_factors="sparse")
