"""Packed interconnections: alike subsystems' parameters stacked once, vmapped per group.

The packed system must compute what the subsystem-by-subsystem one computes (every
per-subsystem term, the step residual, a whole simulated trajectory), and its compiled
chunk must not grow with the number of alike pieces.

White-box: reads internals of ``diracvi.discretization.equations``,
``diracvi.discretization.maps``, ``diracvi.discretization.rules``,
``diracvi.driver.plan``, ``diracvi.driver.stepping``, ``diracvi.model``."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
import diracvi.driver.plan as plan_module
from diracvi import problems
from diracvi.discretization.equations import residual
from diracvi.discretization.maps import discrete_constraints, discrete_momenta
from diracvi.discretization.rules import get_rule
from diracvi.driver.stepping import chunk_runner
from diracvi.model import stacked as _stacked
from diracvi.problems.spring_chain import _segment

jax.config.update("jax_enable_x64", True)


def two_kinds(pieces: int = 9):
    """A torn chain whose pieces after the wall piece alternate between 3 and 4 masses
    (two kinds, interleaved), plus a constrained piece of a third kind at the end:
    three groups whose members are not contiguous."""
    rng = np.random.default_rng(7)
    segments, links, last = [], [], None
    for j in range(pieces):
        size = 2 if j == 0 else (3 if j % 2 else 4)
        m, k = rng.uniform(0.5, 2.0, size), rng.uniform(0.5, 2.0, size)
        segments.append(_segment(f"s{j}", m, k, with_port=j > 0))
        if last is not None:
            links.append(dv.connect(last, f"s{j}.qbar"))
        last = f"s{j}.q{size - 1}"

    def lagrangian(q, v):
        return 0.5 * (v[1] ** 2 + 2.0 * v[2] ** 2) - 0.5 * (q[1] - q[0]) ** 2 - q[2] ** 2

    tail = dv.LagrangeDiracSystem(
        ("qbar", "a", "b"), lagrangian, constraints=np.array([[0.0, 1.0, -1.0]]), name="tail"
    )
    segments.append(tail)
    links.append(dv.connect(last, "tail.qbar"))
    return dv.interconnect(segments, links, name="kinds")


def relative(a, b) -> float:
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b), initial=0.0) / max(1.0, np.max(np.abs(a), initial=0.0)))


@pytest.mark.parametrize(
    ("rule_name", "max_runs"),
    [
        # blocks read and written through index tables (pieces alternating more than
        # MAX_RUNS times: rare, and ~20 s to compile) with -m slow
        # and the slices too (24 s; the default suite's time on CI): the packed run is
        # checked by default against the unpacked one (test_packed_trajectory_matches_unpacked)
        pytest.param("retraction", 2, marks=pytest.mark.slow),
        pytest.param("midpoint", _stacked.MAX_RUNS, marks=pytest.mark.slow),  # a slice a run
        pytest.param("retraction", _stacked.MAX_RUNS, marks=pytest.mark.slow),
        pytest.param("midpoint", 2, marks=pytest.mark.slow),
    ],
)
def test_packed_terms_match_subsystem_by_subsystem(monkeypatch, rule_name, max_runs):
    monkeypatch.setattr(_stacked, "MAX_RUNS", max_runs)
    system = two_kinds()
    packed = system._packed()
    assert len(packed._packing.stacks) == 4  # wall piece, 3-mass, 4-mass, constrained
    assert packed._packing.tables.sliced == (max_runs > 2)
    rule = get_rule(rule_name)
    rng = np.random.default_rng(1)
    n, m = system.n, system.m
    q, v, q1, p = (jnp.asarray(rng.uniform(-1, 1, n)) for _ in range(4))
    mu = jnp.asarray(rng.uniform(-1, 1, m))
    x = jnp.concatenate([q1, mu])
    h = 0.05
    pairs = [
        (lambda s: s.energy(q, v), 1e-14),
        (lambda s: s.lagrangian(q, v), 1e-14),
        (lambda s: s.force(q, v), 0.0),
        (lambda s: s.multiplier_force(q, mu), 0.0),
        (lambda s: discrete_momenta(rule, s, q, q1, h), 0.0),
        (lambda s: discrete_constraints(rule, s, "plus", q, q1, h), 0.0),
        (lambda s: s.constraint_forms(q), 0.0),
        (lambda s: residual(s, rule, "plus", h, q, p, x), 0.0),
    ]
    for term, tol in pairs:
        for a, b in zip(jax.tree.leaves(term(system)), jax.tree.leaves(term(packed)), strict=True):
            assert a.shape == b.shape
            assert relative(a, b) <= tol
    assert packed.constraint_names == system.constraint_names
    assert packed.coords == system.coords
    assert (packed.time_dependent, packed.has_force) == (system.time_dependent, system.has_force)
    for i in (0, 3, len(system.subsystems) - 1):  # a member in full, with its own name
        full = packed._member(i)
        assert full.name == system.subsystems[i].name
        assert (
            relative(
                full.energy(q[: full.n], v[: full.n]),
                system.subsystems[i].energy(q[: full.n], v[: full.n]),
            )
            == 0.0
        )


def _simulate(system, packed: bool, monkeypatch, **kwargs):
    plan_module.clear_cache()
    if not packed:
        monkeypatch.setattr(plan_module, "GROUPED_MIN_SUBSYSTEMS", 10**9)
    try:
        return dv.simulate(system, solver=dv.PartitionedSolver(), **kwargs)
    finally:
        monkeypatch.undo()
        plan_module.clear_cache()


@pytest.mark.parametrize("model", [pytest.param("chain", marks=pytest.mark.slow), "kinds"])
def test_packed_trajectory_matches_unpacked(monkeypatch, model):
    if model == "chain":
        problem = problems.chain_torn(40, 8)
        system, q0, p0 = problem.system, problem.q0, problem.p0
    else:
        system = two_kinds()
        q0 = np.zeros(system.n)  # joined ports agree; the tail's constraint holds
        p0 = np.zeros(system.n)
        p0[system.coords.index("s1.q0")] = 1.0
    kwargs = {"q0": q0, "p0": p0, "dt": 0.01, "steps": 12}
    a = _simulate(system, True, monkeypatch, **kwargs)
    b = _simulate(system, False, monkeypatch, **kwargs)
    assert a.success and b.success
    for name in ("q", "p", "multipliers", "energy"):
        assert relative(getattr(a, name), getattr(b, name)) <= 1e-14, name


def _chunk_program(pieces: int):
    """``(program inputs, equations)`` of the chunk compiled for a torn chain of
    ``pieces`` pieces of 5 masses (its arrays as inputs, as ``CompiledChunk`` passes
    them when they are too large to bake in)."""
    problem = problems.chain_torn(5 * pieces, pieces)
    packed = problem.system._packed()
    rule = get_rule("retraction")
    dynamic, static = eqx.partition(packed, eqx.is_array)

    def chunk(dynamic, carry):
        system = eqx.combine(dynamic, static)
        run = chunk_runner(system, rule, "plus", dv.PartitionedSolver(), 1, False, 3)
        return run(0.01, jnp.zeros(2), carry)

    n, m = packed.n, packed.m
    carry = (jnp.zeros(n), jnp.zeros(n), jnp.zeros(n), jnp.zeros(m))
    jaxpr = jax.make_jaxpr(chunk)(dynamic, carry)
    return len(jax.tree.leaves(dynamic)), len(jaxpr.jaxpr.invars), len(jaxpr.jaxpr.eqns)


def test_chunk_program_does_not_grow_with_alike_pieces():
    small, large = _chunk_program(16), _chunk_program(64)
    assert small[0] == large[0] <= 8  # stacked parameter arrays: a few per kind of piece
    assert small[1] == large[1]  # program inputs
    assert small[2] == large[2]  # equations of the traced chunk
