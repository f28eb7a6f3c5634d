"""White-box: ``J_x⁻¹`` by condensing the parts' own unknowns (``diracvi.solvers.condensed``).

The Schur complement onto the kept unknowns is an exact identity, so a solve equals a
dense LU solve of the whole matrix to round-off (relative to ``‖J_x⁻¹‖ ‖rhs‖``), for
parts of several layouts, with singular and ill-conditioned own blocks left in the
factored system, and for one or many right-hand sides.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from diracvi.solvers.condensed import SingularStep, condense, own_unknowns


def _interconnection(rng, layouts, rows_count, singular=()):
    """A step Jacobian of the parts' pattern: part ``i`` has ``layouts[i] = (coords,
    own multipliers)``; its own block is dense (zero for ``i`` in ``singular``, or of
    rank one for a negative index), its unknowns meet two random interaction rows."""
    coords = np.array([c for c, _ in layouts])
    mus = np.array([m for _, m in layouts])
    n, own = int(coords.sum()), int(mus.sum())
    offsets = np.concatenate([[0], np.cumsum(coords)])
    mu_start = n + np.concatenate([[0], np.cumsum(mus)[:-1]])
    size = n + own + rows_count
    a = np.zeros((size, size))
    for i, (c, m) in enumerate(layouts):
        idx = np.concatenate([offsets[i] + np.arange(c), mu_start[i] + np.arange(m)])
        block = rng.standard_normal((idx.size, idx.size)) + 3 * np.eye(idx.size)
        if i in singular:
            block[:] = 0.0
        elif -i - 1 in singular:  # rank one: condition number ∞ in exact arithmetic
            u = rng.standard_normal(idx.size)
            block = np.outer(u, u)
        a[np.ix_(idx, idx)] = block
        for b in rng.choice(rows_count, size=2, replace=False):
            row = n + own + b
            a[idx, row] = rng.standard_normal(idx.size)  # the node's multiplier in the part
            a[row, idx] = rng.standard_normal(idx.size)  # the part's unknowns in the KCL row
    # every interaction row meets some part (else S is singular by construction)
    for b in range(rows_count):
        row = n + own + b
        if not a[row, : n + own].any():
            a[row, 0] = a[0, row] = 1.0
    groups = own_unknowns(offsets, mu_start, mus)
    return a, groups


# kept in the factored system: none; two zero blocks (a source's); a rank-one 2 × 2 block
@pytest.mark.parametrize(("singular", "kept_parts"), [((), ()), ((0, 3), (0, 3)), ((-8,), (7,))])
def test_condensed_solve_equals_dense_solve(singular, kept_parts):
    rng = np.random.default_rng(7)
    layouts = [(1, 0)] * 6 + [(2, 0)] * 3 + [(2, 1)] * 4 + [(1, 2)] * 2
    a, groups = _interconnection(rng, layouts, rows_count=9, singular=singular)
    solver = condense(sp.csc_matrix(a), groups)
    assert solver.cond.size + solver.kept.size == a.shape[0]
    own = sum(index.size for _, index in groups)
    assert solver.cond.size == own - sum(sum(layouts[i]) for i in kept_parts)
    scale = np.linalg.norm(np.linalg.inv(a), 2)
    for rhs in (rng.standard_normal(a.shape[0]), rng.standard_normal((a.shape[0], 3))):
        got = solver.solve(rhs)
        want = np.linalg.solve(a, rhs)
        assert got.shape == rhs.shape
        assert np.max(np.abs(got - want)) <= 1e-13 * scale * np.max(np.abs(rhs))


def test_singular_jacobian_is_reported():
    rng = np.random.default_rng(3)
    a, groups = _interconnection(rng, [(1, 0)] * 4, rows_count=3)
    a[-1] = 0.0  # a KCL row of zeros
    with pytest.raises(SingularStep):
        condense(sp.csc_matrix(a), groups)


def test_ladder_map_solves_with_the_node_count(monkeypatch):
    """The sparse map of a 20-stage ladder netlist: its ``lu`` keeps the 41 nodes'
    multipliers and the source's increment (a zero own block) and condenses the 60 R, L,
    C branches; its solve equals SuperLU of the whole ``J_x`` to round-off."""
    import scipy.sparse.linalg as spla

    import diracvi as dv
    from diracvi import spice
    from diracvi.bench.ladders import ladder
    from diracvi.solvers import sparse_affine

    built = []
    original = sparse_affine.build

    def build(*a, **k):
        built.append(original(*a, **k))
        return built[-1]

    monkeypatch.setattr(sparse_affine, "build", build)
    netlist = spice.read(ladder(20, steps=4))
    traj = dv.simulate(
        netlist.system, netlist.q0, netlist.p0, dt=netlist.dt, steps=netlist.steps,
        discretization="midpoint", solver=sparse_affine.SparseAffineSolver(),
    )  # fmt: skip
    assert traj.solver.startswith("sparse affine")
    lu = built[-1].lu
    assert (lu.kept.size, lu.cond.size) == (41 + 1, 60)
    whole = spla.splu(built[-1].jx.tocsc())
    rng = np.random.default_rng(5)
    for rhs in (rng.standard_normal(lu.size), rng.standard_normal((lu.size, 2))):
        want = whole.solve(rhs)
        assert np.max(np.abs(lu.solve(rhs) - want)) <= 1e-12 * np.max(np.abs(want))


# a third run of the ladder (13 s); the condensed solve itself is checked by default
@pytest.mark.slow
def test_offsets_of_every_row_give_the_same_run(monkeypatch):
    """A driven ladder with the offsets taken from the whole residual at zero (as for
    more than ``MAX_DRIVERS`` time-dependent parts: every entry of ``r₀``, ``P₀`` is a
    column of the augmented state) steps as with the source's own rows, and as Newton."""
    import diracvi as dv
    from diracvi import spice
    from diracvi.bench.ladders import ladder
    from diracvi.solvers import sparse_affine

    text = ladder(12, steps=42)

    def run(solver):  # (a model read afresh: a warm call would reuse the plan's map)
        netlist = spice.read(text)
        return dv.simulate(
            netlist.system, netlist.q0, netlist.p0, solver=solver, dt=netlist.dt,
            steps=netlist.steps, discretization="midpoint", save_every=3,
        )  # fmt: skip

    own = run(sparse_affine.SparseAffineSolver())
    monkeypatch.setattr(sparse_affine, "MAX_DRIVERS", 0)
    every = run(sparse_affine.SparseAffineSolver())
    newton = run(dv.NewtonSolver())
    assert own.solver == every.solver and own.solver.startswith("sparse affine")
    for name in ("q", "p", "multipliers", "constraint_residual"):
        a, b, c = (np.asarray(getattr(t, name)) for t in (own, every, newton))
        scale = max(float(np.max(np.abs(c))), 1e-300)
        assert np.max(np.abs(a - b)) <= 1e-12 * scale, name
        if name != "constraint_residual":  # (round-off of different solvers)
            assert np.max(np.abs(a - c)) <= 1e-10 * scale, name


@pytest.mark.slow
def test_small_steps_keep_the_condensed_solve_accurate():
    """A 6-stage ladder's step at h = TSTEP/16 (a size the variable-step path takes): its
    rows span L/h = 1.6e4 to h/C = 0.06. Condensed on the equilibrated ``J_x`` the solve
    equals SuperLU of the whole ``J_x`` to 1e-13 relative (formed on the raw scales it
    was off by 3e-11)."""
    import scipy.sparse.linalg as spla

    from diracvi import spice
    from diracvi.bench.ladders import ladder
    from diracvi.discretization.rules import get_rule
    from diracvi.solvers.sparse_affine import build

    netlist = spice.read(ladder(6, steps=100))
    system = netlist.system._packed()
    q0, p0 = np.asarray(netlist.q0), np.asarray(netlist.p0)
    found = build(system, get_rule("midpoint"), "plus", 1e-6 / 16, q0, p0, 0.0)
    rhs = np.random.default_rng(0).standard_normal(found.size)
    want = spla.splu(found.jx.tocsc()).solve(rhs)
    assert np.max(np.abs(found.lu.solve(rhs) - want)) <= 1e-13 * np.max(np.abs(want))
