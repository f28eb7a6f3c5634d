"""White-box: the circuit-scale sparse affine path (``diracvi.solvers.sparse_affine``).

A sparse step matrix of the interconnected parts, factored once: the same trajectory as
the dense affine map and Newton to round-off, chosen automatically for a large linear
netlist, against ngspice to 1e-3 of the peak, and gradients through the traced path.
"""

from __future__ import annotations

import jax
import numpy as np
import pytest

import diracvi as dv
from diracvi import spice
from diracvi.bench.ladders import ladder
from diracvi.solvers.sparse_affine import SparseAffineSolver
from diracvi.spice._ngspice import available, ngspice

SPARSE = "sparse affine step map (condensed to the nodes, SuperLU)"
FIELDS = ("q", "p", "p_nodal", "multipliers", "energy")


def _run(netlist, solver, **kw):
    args = dict(dt=netlist.dt, steps=netlist.steps, discretization="midpoint")
    args.update(kw)
    return dv.simulate(netlist.system, netlist.q0, netlist.p0, solver=solver, **args)


def _assert_same(a, b, rtol=1e-10, fields=FIELDS):
    for name in fields:
        x, y = getattr(a, name), getattr(b, name)
        scale = max(float(np.max(np.abs(y))), 1e-300)
        assert x.shape == y.shape, name
        assert np.max(np.abs(x - y)) <= rtol * scale, (name, np.max(np.abs(x - y)) / scale)


@pytest.fixture(scope="module")
def ladder50():
    return spice.read(ladder(50, steps=100))


# 29 s: the KCL-rows and automatic-choice tests cover the sparse path by default
@pytest.mark.slow
def test_sparse_equals_dense_affine_and_newton(ladder50):
    """A driven 50-stage ladder: the sparse map, the dense affine map and Newton agree
    to 1e-10 of each quantity's peak; its constraint residuals are at round-off."""
    sparse = _run(ladder50, SparseAffineSolver())
    dense = _run(ladder50, None)
    newton = _run(ladder50, dv.NewtonSolver())
    assert sparse.solver == SPARSE
    assert dense.solver == "affine step map"
    _assert_same(sparse, dense)
    _assert_same(sparse, newton)
    # constraints: round-off of the step's size (|λ| ~ 1/h · |Δq| scale)
    assert np.max(np.abs(sparse.constraint_residual)) <= 1e-12
    assert np.max(np.abs(sparse.constraint_residual - dense.constraint_residual)) <= 1e-12
    np.testing.assert_array_equal(sparse.t, dense.t)
    for a, b in zip(sparse.final_state, dense.final_state, strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * max(np.max(np.abs(b)), 1e-300))


@pytest.mark.slow  # ~13 s
def test_autonomous_minus_and_saving():
    """No source (constant offsets), the backward scheme, ``save_every`` and a run that
    keeps only diagnostics: each as the general solver computes it."""
    netlist = spice.read(ladder(12, steps=60, source=False, v0=1.0))
    for scheme in ("plus", "minus"):
        sparse = _run(netlist, SparseAffineSolver(), scheme=scheme)
        newton = _run(netlist, dv.NewtonSolver(), scheme=scheme)
        assert sparse.solver == SPARSE
        _assert_same(sparse, newton)
    every = _run(netlist, SparseAffineSolver(), save_every=5)
    whole = _run(netlist, dv.NewtonSolver(), save_every=5)
    assert every.solver == SPARSE
    _assert_same(every, whole)
    np.testing.assert_allclose(
        every.constraint_violation, whole.constraint_violation, rtol=0, atol=1e-12
    )
    bare = _run(netlist, SparseAffineSolver(), save_states=False)
    assert bare.q is None and bare.solver == SPARSE
    ref = _run(netlist, dv.NewtonSolver(), save_states=False)
    _assert_same(bare, ref, fields=("energy",))
    np.testing.assert_allclose(bare.final_q, ref.final_q, rtol=0, atol=1e-10)


# the path choice on a large netlist; tests/test_fast_paths.py checks it at a smaller size by
# default
@pytest.mark.slow
def test_chosen_automatically_for_a_large_linear_netlist():
    """From 256 unknowns (where the partitioned solver took over) a linear netlist is
    stepped by the sparse map, with the partitioned solver's trajectory."""
    netlist = spice.read(ladder(100, steps=30))
    assert netlist.system.n + netlist.system.m >= 256
    auto = _run(netlist, None)
    assert auto.solver == SPARSE
    partitioned = _run(netlist, dv.PartitionedSolver())
    assert partitioned.solver == "PartitionedSolver()"
    _assert_same(auto, partitioned)


def test_not_affine_falls_back():
    """A diode: the sparse path does not apply and the run says what stepped it."""
    from diracvi.spice._ngspice import CIRCUITS

    netlist = spice.read(CIRCUITS["rectifier"][0])
    traj = _run(netlist, SparseAffineSolver(), steps=50)
    assert "sparse" not in traj.solver
    ref = _run(netlist, dv.NewtonSolver(), steps=50)
    _assert_same(traj, ref, rtol=1e-9, fields=("q", "p"))


@pytest.mark.skipif(not available(), reason="ngspice is not installed")
def test_ladder_against_ngspice(ladder50):
    """The 50-stage ladder (2 periods of the source) against a fine ngspice run: within
    1e-3 of each probe's peak."""
    text = ladder(50, steps=2000)
    netlist = spice.read(text)
    result = spice.run(netlist, dt=netlist.dt, solver=SparseAffineSolver())  # fixed step
    assert result.trajectory.solver == SPARSE
    probes = ("v(n1)", "v(n10)", "v(n50)", "i(L1)", "i(L25)")
    ref_t, ref = ngspice(text, probes, tmax=netlist.stop / 20000)
    for p in probes:
        peak = np.max(np.abs(ref[p]))
        got = np.interp(ref_t, result.time, result[p])
        assert np.max(np.abs(got - ref[p])) <= 1e-3 * peak, p


@pytest.mark.slow  # ~19 s
def test_gradient_central_differences():
    """A gradient through ``simulate`` of a ladder (the traced JAX path) equals central
    differences of host runs, which take the sparse map."""
    netlist = spice.read(ladder(10, steps=40, source=False, v0=1.0))
    index = netlist.system.coords.index("C1.q")
    e = np.zeros(netlist.system.n)
    e[index] = 1.0

    def loss(s, solver=None):
        traj = dv.simulate(
            netlist.system, netlist.q0 + s * e, netlist.p0, dt=netlist.dt,
            steps=netlist.steps, discretization="midpoint", solver=solver,
        )  # fmt: skip
        return (traj.q[-1] ** 2).sum() * 1e12

    grad = float(jax.grad(loss)(0.0))
    step = 1e-9
    plus = float(loss(step, SparseAffineSolver()))
    minus = float(loss(-step, SparseAffineSolver()))
    assert dv.simulate(
        netlist.system, netlist.q0, netlist.p0, dt=netlist.dt, steps=2,
        discretization="midpoint", solver=SparseAffineSolver(),
    ).solver == SPARSE  # fmt: skip
    fd = (plus - minus) / (2 * step)
    assert abs(grad - fd) <= 1e-6 * abs(fd)


def test_inconsistent_momenta_still_reported():
    """The initial-data check on this path (on the packed system): a momentum around a
    loop of massless branches (``Rx`` beside ``C5``), which no velocity can produce, is
    reported."""
    from diracvi import InconsistentInitialDataWarning

    text = ladder(20, steps=10, source=False, v0=1.0).replace(".tran", "Rx n5 0 100\n.tran")
    netlist = spice.read(text)
    p0 = np.array(netlist.p0)
    p0[netlist.system.coords.index("Rx.q")] = 1e-3
    with pytest.warns(InconsistentInitialDataWarning):
        traj = dv.simulate(
            netlist.system, netlist.q0, p0, dt=netlist.dt, steps=netlist.steps,
            discretization="midpoint", solver=SparseAffineSolver(),
        )  # fmt: skip
    assert traj.solver == SPARSE


# ------------------------------------------------------------------ sparse KCL rows
def _dense_kcl(system):
    """The same interconnection with its KCL rows given as one dense ``Interaction``
    (how the netlist reader built them before they were kept sparse)."""
    forms = np.asarray(system.interaction_forms(jax.numpy.zeros(system.n)))
    inter = dv.Interaction(forms, names=system.interaction_names)
    return dv.interconnect(list(system.subsystems), [inter], name=system.name)


# dense twin of every KCL row (9 s); ladders against ngspice cover the sparse rows by default
@pytest.mark.slow
def test_sparse_kcl_rows_equal_the_dense_ones():
    """The netlist's KCL kept as sparse triples gives the dense rows' step equations to
    round-off under every rule (staged lobatto included), the same ``Bᵀλ`` and the same
    trajectory (Newton, 20 steps) to 1e-12 of each quantity's peak."""
    from diracvi.discretization.equations import residual, unknown_count
    from diracvi.discretization.rules import get_rule

    netlist = spice.read(ladder(4, steps=20))
    sparse = netlist.system
    assert sparse.incidence() is not None and not sparse.interactions
    dense = _dense_kcl(sparse)
    assert dense.incidence() is None and dense.interactions
    rng = np.random.default_rng(7)
    q, p = rng.standard_normal(sparse.n), rng.standard_normal(sparse.n)
    lam = rng.standard_normal(sparse.m)
    np.testing.assert_array_equal(sparse.multiplier_force(q, lam), dense.multiplier_force(q, lam))
    np.testing.assert_array_equal(sparse.constraint_forms(q), dense.constraint_forms(q))
    for name in ("retraction", "midpoint", "lobatto"):
        rule = get_rule(name)
        x = rng.standard_normal(unknown_count(sparse, rule))
        for scheme in ("plus", "minus"):
            a = np.asarray(residual(sparse, rule, scheme, 1e-6, q, p, x, 0.3e-3))
            b = np.asarray(residual(dense, rule, scheme, 1e-6, q, p, x, 0.3e-3))
            assert np.max(np.abs(a - b)) <= 1e-13 * np.max(np.abs(b)), (name, scheme)
    args = dict(dt=netlist.dt, steps=netlist.steps, discretization="midpoint")
    one = dv.simulate(sparse, netlist.q0, netlist.p0, solver=dv.NewtonSolver(), **args)
    two = dv.simulate(dense, netlist.q0, netlist.p0, solver=dv.NewtonSolver(), **args)
    _assert_same(one, two, rtol=1e-12)


# 16 s, in `-m slow` (the default suite's time on CI): a run in several blocks equals the
# whole by default in tests/test_fast_paths.py (test_affine_fallback_midway_in_a_chunked_...)
@pytest.mark.slow
def test_short_blocks_give_the_same_run(monkeypatch):
    """A large circuit's run goes in shorter blocks (its buffers bounded): with blocks
    of 8 steps (the last one partial, saves every 5 steps across their ends) the sparse
    run is Newton's to 1e-10."""
    from diracvi.solvers import sparse_affine

    monkeypatch.setattr(sparse_affine, "BLOCK_BYTES", 1)
    netlist = spice.read(ladder(12, steps=60))
    sparse = _run(netlist, SparseAffineSolver(), save_every=5)
    newton = _run(netlist, dv.NewtonSolver(), save_every=5)
    assert sparse.solver == SPARSE
    _assert_same(sparse, newton)
    np.testing.assert_allclose(
        sparse.constraint_violation, newton.constraint_violation, rtol=0, atol=1e-12
    )


@pytest.mark.slow  # (9 s at load 5: the jitted dense Jacobian)
def test_the_structural_pattern_holds_every_entry_and_its_seeds_separate_them():
    """The pattern (``solvers/sparse_pattern.py``) against the dense Jacobian of the step
    residual and momentum line (``jax.jacfwd``, at a random point and time) of a circuit
    with parts of several layouts (sources, a current source, coupled inductors): every
    non-zero is a structural entry, and no two columns of one seed share a row, so the
    compressed JVPs give every entry alone."""
    from diracvi.discretization.rules import get_rule
    from diracvi.solvers import sparse_affine
    from diracvi.solvers.sparse_pattern import structural_pattern

    deck = ladder(4).replace(".tran", "I2 n2 0 SIN(0 1m 2k)\nV3 n3 x DC 1\nR7 x 0 5\n"
                             "L8 n1 y 2m\nL9 y 0 3m\nK1 L8 L9 0.5\n.tran")  # fmt: skip
    system = spice.read(deck).system._packed()
    rule = get_rule("midpoint")
    seeds, seed_of, row_of, col_of = structural_pattern(system, rule)
    w = np.random.default_rng(3).normal(size=seeds.shape[1])

    def stacked(u):
        r, pm, _ = sparse_affine._parts(system, rule, "plus", 1e-6, u, 0.37)
        return jax.numpy.concatenate([r, pm])

    dense = np.asarray(jax.jit(jax.jacfwd(stacked))(w))
    rows, cols = np.nonzero(dense)
    assert len(rows) > 0
    structural = set(zip(row_of.tolist(), col_of.tolist(), strict=True))
    assert set(zip(rows.tolist(), cols.tolist(), strict=True)) <= structural
    # a seed's columns touch disjoint rows (per the pattern): the compression is lossless
    pairs = set(zip(seed_of.tolist(), row_of.tolist(), strict=True))
    assert len(pairs) == len(structural)
    assert np.all(seeds.sum(axis=0) == 1.0)  # every column in exactly one seed
