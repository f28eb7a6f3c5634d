"""The bordered-band Newton solve (solvers/bordered.py): its order, its linear algebra
against a dense solve, and a chain of CMOS inverters run by the compiled variable-step
loop with it against the dense Newton."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diracvi.errors import ModelError
from diracvi.solvers import bordered
from diracvi.solvers.banded import bandwidths


def hub_chain(size: int, seed: int = 0):
    """A random matrix: a tridiagonal chain in a shuffled order, plus a hub (full row and
    column) and a source unknown whose only equation term is the hub (so the hub alone
    cannot leave the core: the core would be structurally singular). Returns
    ``(matrix, hub, source)``."""
    rng = np.random.default_rng(seed)
    m = np.zeros((size, size))
    chain = np.arange(size - 2)
    m[chain, chain] = rng.uniform(2.0, 3.0, size - 2)
    m[chain[1:], chain[:-1]] = rng.uniform(-1.0, 1.0, size - 3)
    m[chain[:-1], chain[1:]] = rng.uniform(-1.0, 1.0, size - 3)
    hub, source = size - 2, size - 1
    m[hub, :] = rng.uniform(-1.0, 1.0, size)
    m[:, hub] = rng.uniform(-1.0, 1.0, size)
    m[source, :] = 0.0
    m[source, hub] = 1.0  # the source's equation holds the hub's unknown only
    m[hub, source] = 1.0
    m[source, source] = 0.0
    m[hub, hub] = 0.0
    shuffle = rng.permutation(size)
    back = np.argsort(shuffle)
    return m[np.ix_(shuffle, shuffle)], back[hub], back[source]


def test_structure_puts_the_hub_and_its_partner_in_the_border():
    """The shuffled chain becomes tridiagonal once the hub and the source (which the hub
    alone would leave without a pivot) are in the border."""
    m, hub, source = hub_chain(120)
    pattern = m != 0
    assert bandwidths(pattern)[0] > 100  # shuffled: no band as it stands
    perm, k, kl, ku = bordered.structure(pattern)
    assert sorted(perm) == list(range(120))
    assert k == 2 and set(perm[-k:]) == {hub, source}
    assert (kl, ku) == (1, 1)
    core = perm[:-k]
    assert bandwidths(pattern[np.ix_(core, core)]) == (1, 1)


def test_structure_keeps_a_dense_pattern_without_a_border():
    """A full pattern has no band to gain: no border, band as wide as the matrix."""
    _, k, kl, ku = bordered.structure(np.ones((30, 30), bool))
    assert k == 0 and kl + ku + 1 == 59


@pytest.mark.parametrize("seed", [0, 1])
def test_factors_solve_as_the_dense_lu(seed):
    """The Jacobian formed from kl + ku + 1 + k JVPs and k VJPs and factorized as a band
    with a border solves ``J x = b`` as ``numpy.linalg.solve`` does, to round-off; its
    magnitudes give ``|J| v``."""
    size = 90
    m, _, _ = hub_chain(size, seed)
    perm, k, kl, ku = bordered.structure(m != 0)
    layout = bordered.Layout(perm, k, kl, ku)
    rng = np.random.default_rng(seed + 10)
    x0 = rng.uniform(-1.0, 1.0, size)

    def fn(x):  # a nonlinear residual with m's pattern: J = m + diag(cos x)·[m_ii ≠ 0]
        return jnp.asarray(m) @ x + jnp.where(jnp.diag(jnp.asarray(m)) != 0, jnp.sin(x), 0.0)

    jac = np.asarray(jax.jacfwd(fn)(jnp.asarray(x0)))
    factors, norms = jax.jit(lambda x: bordered.factorize(fn, x, layout))(jnp.asarray(x0))
    b = rng.uniform(-1.0, 1.0, size)
    assert not bool(factors[-1])  # the probe passed: the block elimination solves
    x = np.asarray(bordered.solve((factors, norms), jnp.asarray(b), layout))
    exact = np.linalg.solve(jac, b)
    cond = np.linalg.cond(jac)
    assert np.max(np.abs(x - exact)) <= 1e-14 * cond * np.max(np.abs(exact))
    v = rng.uniform(0.0, 1.0, size)
    mag = np.asarray(bordered.magnitude(norms, jnp.asarray(v), layout))
    np.testing.assert_allclose(mag, np.abs(jac) @ v, rtol=1e-14, atol=0)
    # the initial state has the factors' shapes (the chord iteration carries them)
    empty = bordered.empty_factors(layout, jnp.float64)
    assert jax.tree.map(jnp.shape, empty) == jax.tree.map(jnp.shape, (factors, norms))


@pytest.mark.slow
def test_a_wide_band_keeps_the_dense_newton():
    """The corpus deck es_integrator (284 unknowns) orders as a band of 107 with a border
    of 4 — 115 tangents, more than a quarter of 284 — and keeps the dense Newton; chains
    of 2 and 4 inverters (89 and 171 unknowns) are under ``MIN_SIZE``."""
    import tomllib

    from _corpus import DATA
    from diracvi import spice
    from diracvi.discretization.rules import get_rule
    from diracvi.driver import events
    from diracvi.solvers.newton import NewtonSolver
    from test_alike_transistors import inverters

    rule = get_rule("midpoint")
    expected = tomllib.loads((DATA / "EXPECTED.toml").read_text())
    decks = [inverters(2), inverters(4), DATA / expected["es_integrator"]["file"]]
    for deck in decks:
        system = events.packed_unless_switched(spice.read(deck).system)
        solver = bordered.newton_for(system, rule, reuse_jacobian=True)
        assert type(solver) is NewtonSolver and solver.reuse_jacobian
    size = system.n + system.m
    assert size >= bordered.MIN_SIZE
    key = ("bordered", id(system), "midpoint", "plus")
    pattern = bordered.step_pattern(system, rule, "plus", key, finite_rows=True)
    _, k, kl, ku = bordered.structure(pattern)
    assert kl + ku + 1 + 2 * k > bordered.TANGENT_SHARE * size


def test_solver_rejects_an_order_of_the_wrong_size():
    from diracvi import spice
    from diracvi.discretization.equations import StepEquations
    from diracvi.discretization.rules import get_rule

    netlist = spice.read("rc\nV1 a 0 1\nR1 a b 1k\nC1 b 0 1n\n.tran 1n 10n\n.end\n")
    system = netlist.system
    eqs = StepEquations(system, get_rule("midpoint"), "plus", 1e-9, netlist.q0, netlist.p0, 0.0)
    solver = bordered.BorderedNewtonSolver(perm=(0, 1), border=0, kl=1, ku=1)
    with pytest.raises(ModelError, match="perm"):
        solver.init(eqs)


@pytest.mark.slow
def test_chain_of_inverters_steps_as_the_dense_newton(monkeypatch):
    """A chain of 6 CMOS inverters (s = 253 unknowns) is stepped by the bordered solve
    (two border unknowns: the supply's multiplier and its source's charge, band 25):
    from states along its variable-step run, each Newton step's end equals the dense
    Newton's to round-off; and the whole run agrees with a dense run inside the step
    control's tolerance (not step for step: round-off moves the next step's size, and
    with it the step count, by several per cent — see the last assertion)."""
    from diracvi import spice
    from diracvi.discretization.rules import get_rule
    from diracvi.driver import adaptive as adaptive_module
    from diracvi.driver import events
    from diracvi.driver.tries import one_step
    from diracvi.solvers.newton import NewtonSolver
    from test_alike_transistors import inverters

    deck = inverters(6, stop="0.3u")
    netlist = spice.read(deck)
    system = events.packed_unless_switched(netlist.system)
    rule = get_rule("midpoint")
    solver = bordered.newton_for(system, rule, reuse_jacobian=True)
    assert isinstance(solver, bordered.BorderedNewtonSolver)
    assert solver.border == 2 and solver.kl + solver.ku + 1 <= 64  # against s = 253 tangents
    banded_run = spice.run(deck)
    tr = banded_run.trajectory
    dense = NewtonSolver(reuse_jacobian=True)
    mu = np.zeros(system.m)

    def steps(solver):
        return jax.jit(lambda h, t, q, p: one_step(system, rule, solver, h, t, q, p, q, mu))

    pick = np.linspace(0, len(tr.h) - 1, 12).astype(int)
    with_band, with_dense = steps(solver), steps(dense)
    for i in pick:
        args = (tr.h[i], tr.t[i], tr.q[i], tr.p[i])
        a, b = with_dense(*args), with_band(*args)
        assert bool(a[3]) and bool(b[3])  # both converged
        for x, y in zip(a[:2], b[:2], strict=True):
            x, y = np.asarray(x), np.asarray(y)
            assert np.max(np.abs(x - y)) <= 1e-10 * np.max(np.abs(x)), i
    monkeypatch.setattr(adaptive_module, "newton_for", lambda system, rule, **o: dense)
    dense_run = spice.run(deck)
    for key in dense_run:
        a, b = np.asarray(dense_run[key]), np.asarray(banded_run[key])
        assert np.max(np.abs(a - b)) <= 1e-4 * max(1.0, np.max(np.abs(a))), key
    # The step count is not a function of the linear algebra up to round-off: the run's
    # first step after the pulse's edge (t = 0.2 µs, h ≈ 2.9e-12 s) reads its error from
    # increments near round-off, so a 1e-16 change of the state moves the next step by
    # 1e-8 and flips an accept or a gap check two steps later. Measured (tests' compile,
    # 2026-11-30): the dense run 1151 steps, 1211 with its solve's answer one ulp larger;
    # the bordered run 1197 at main 642313b, 1285 with one ulp, 1083 with the probe's
    # column — every pair first apart at step 44 by 1e-8 of h, by 15–75 % at step 46.
    # What the step control promises is its tolerance, asserted above; its work is
    # asserted only to round-off's measured spread (−6 % to +12 % of the dense run's),
    # doubled: a solve that made Newton or the error estimate worse would show as more.
    assert len(tr.t) == pytest.approx(len(dense_run.trajectory.t), rel=0.25)


def singular_core(size: int = 60, seed: int = 3):
    """A residual whose step Jacobian has a core singular at one point ``x0`` while the
    whole Jacobian is regular there: a shuffled tridiagonal chain plus a hub (a full row and
    column, random), where chain unknown ``j``'s equation reads the chain only through
    ``(x_j − x0_j)·(chain terms)`` — structurally there (its entries are nonzero at any
    other point), numerically zero at ``x0``. Returns ``(fn, x0, pattern, J(x0))``."""
    rng = np.random.default_rng(seed)
    chain = size - 1
    m = np.zeros((size, size))
    i = np.arange(chain)
    m[i, i] = rng.uniform(2.0, 3.0, chain)
    m[i[1:], i[:-1]] = rng.uniform(-1.0, 1.0, chain - 1)
    m[i[:-1], i[1:]] = rng.uniform(-1.0, 1.0, chain - 1)
    m[chain, :] = rng.uniform(-1.0, 1.0, size)
    m[:, chain] = rng.uniform(-1.0, 1.0, size)
    j = chain // 2
    at_x0 = m.copy()
    at_x0[j, :chain] = 0.0  # the core's row j vanishes at x0; its hub entry stays
    shuffle = rng.permutation(size)
    m, at_x0 = m[np.ix_(shuffle, shuffle)], at_x0[np.ix_(shuffle, shuffle)]
    j = int(np.argsort(shuffle)[j])
    x0 = rng.uniform(-1.0, 1.0, size)
    chain_part = jnp.asarray(m - at_x0)[j]  # row j's chain entries

    def fn(x):
        r = jnp.asarray(at_x0) @ x
        return r.at[j].add((x[j] - x0[j]) * (chain_part @ (x - x0)) + chain_part @ x0)

    # the pattern (two random points) has row j's chain entries; J(x0) has not
    return fn, jnp.asarray(x0), m != 0, at_x0


def test_a_core_singular_at_the_point_falls_back_to_the_dense_lu():
    """Where the core ``A`` is singular and ``J`` is not, the block elimination's factors
    are not finite; the probe sends the solve to a dense LU of the same ``J``, which
    solves as ``numpy.linalg.solve`` does. Without the fallback the solve is not finite
    (Newton would report the step singular)."""
    fn, x0, pattern, jac = singular_core()
    size = jac.shape[0]
    np.testing.assert_array_equal(np.asarray(jax.jacfwd(fn)(x0)), jac)
    perm, k, kl, ku = bordered.structure(pattern)
    layout = bordered.Layout(perm, k, kl, ku)
    core = perm[: size - k]
    assert k == 1 and (kl, ku) == (1, 1)  # the hub in the border, the chain banded
    assert np.linalg.matrix_rank(jac[np.ix_(core, core)]) < size - k  # A singular at x0
    cond = np.linalg.cond(jac)
    assert cond < 1e6  # J is not
    b = np.random.default_rng(7).uniform(-1.0, 1.0, size)
    exact = np.linalg.solve(jac, b)
    both = jax.jit(lambda x: bordered.factorize(fn, x, layout))(x0)
    assert bool(both[0][-1])  # the probe failed: the dense LU solves
    x = np.asarray(bordered.solve(both, jnp.asarray(b), layout))
    assert np.max(np.abs(x - exact)) <= 1e-14 * cond * np.max(np.abs(exact))
    trusted = jax.jit(lambda x: bordered.factorize(fn, x, layout, fallback=False))(x0)
    assert not np.all(np.isfinite(np.asarray(bordered.solve(trusted, jnp.asarray(b), layout))))
    # at another point the same structure solves by the block elimination
    away = x0 + 0.1
    both = jax.jit(lambda x: bordered.factorize(fn, x, layout))(away)
    assert not bool(both[0][-1])
    x = np.asarray(bordered.solve(both, jnp.asarray(b), layout))
    exact = np.linalg.solve(np.asarray(jax.jacfwd(fn)(away)), b)
    assert np.max(np.abs(x - exact)) <= 1e-14 * cond * np.max(np.abs(exact))


@pytest.mark.parametrize("fallback", [True, False])
def test_newton_from_a_singular_core_converges_with_the_fallback(fallback):
    """Newton's first Jacobian is taken at ``x0``, where the core is singular: with the
    fallback the chord iteration converges to the root as the dense Newton does; without
    it the first update is not finite and the step is reported singular."""
    from diracvi.solvers.base import SolveStatus
    from diracvi.solvers.newton import NewtonSolver, chord_newton

    fn, x0, pattern, jac = singular_core()
    perm, k, kl, ku = bordered.structure(pattern)
    layout = bordered.Layout(perm, k, kl, ku)
    root = x0 + 0.01 * jnp.asarray(np.random.default_rng(5).uniform(-1.0, 1.0, jac.shape[0]))
    target = fn(root)

    def residual(x):
        return fn(x) - target

    options = NewtonSolver(reuse_jacobian=True)

    def run(factorize, correction, empty):
        return chord_newton(
            options,
            residual,
            factorize,
            correction,
            x0,
            empty,
            jnp.asarray(False),
            jnp.asarray(1.0),
        )

    x, status, *_ = jax.jit(
        lambda: run(
            lambda x: bordered.factorize(residual, x, layout, fallback=fallback),
            lambda both, r: bordered.solve(both, -r, layout),
            bordered.empty_factors(layout, jnp.float64),
        )
    )()
    dense_x, dense_status, *_ = jax.jit(
        lambda: run(
            lambda x: jax.scipy.linalg.lu_factor(jax.jacfwd(residual)(x)),
            lambda lu, r: jax.scipy.linalg.lu_solve(lu, -r),
            jax.scipy.linalg.lu_factor(jnp.eye(jac.shape[0])),
        )
    )()
    assert int(dense_status) == SolveStatus.SUCCESS
    if fallback:
        assert int(status) == SolveStatus.SUCCESS
        np.testing.assert_allclose(np.asarray(x), np.asarray(dense_x), rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.asarray(x), np.asarray(root), rtol=0, atol=1e-13)
    else:
        assert int(status) == SolveStatus.SINGULAR


def test_the_plan_is_keyed_by_the_systems_content():
    """The plan's key is the system printed whole with its arrays by value: a netlist read
    again has the same key, one wired otherwise (the same elements and sizes) or with one
    array value changed — where a pattern could hide in values — another."""
    import equinox as eqx

    from diracvi import spice
    from diracvi.discretization.rules import get_rule

    rule = get_rule("midpoint")
    deck = "rc\nV1 a 0 1\nR1 a b 1k\nR2 b c 2k\nC1 b 0 1n\nC2 c 0 1n\n.tran 1n 10n\n.end\n"
    rewired = deck.replace("R2 b c", "R2 a c")

    def key(text):
        return bordered._content_key(spice.read(text).system, rule, "plus")

    first = key(deck)
    assert first is not None and key(deck) == first
    assert key(rewired) != first
    assert bordered._content_key(spice.read(deck).system, rule, "minus") != first
    system = spice.read(deck).system
    leaves, treedef = jax.tree.flatten(system)
    at = next(i for i, leaf in enumerate(leaves) if eqx.is_array(leaf) and leaf.size)
    leaves[at] = leaves[at] + 1  # one array value changed, nothing else
    changed = jax.tree.unflatten(treedef, leaves)
    assert bordered._content_key(changed, rule, "plus") != first


@pytest.mark.slow
def test_a_netlist_read_again_reuses_its_plan(monkeypatch):
    """``spice.run`` reads its netlist again at each call: the plan of a chain of 6
    inverters (253 unknowns) is found once and reused for the second reading, whose
    system is another object; a chain with one width changed reads its pattern again."""
    from diracvi import spice
    from diracvi.discretization.rules import get_rule
    from diracvi.driver import events
    from test_alike_transistors import inverters

    reads = []
    step_pattern = bordered.step_pattern

    def counted(*args, **kwargs):
        reads.append(args[0])
        return step_pattern(*args, **kwargs)

    monkeypatch.setattr(bordered, "step_pattern", counted)
    monkeypatch.setattr(bordered, "_PLANS", {})
    rule = get_rule("midpoint")
    deck = inverters(6)

    def plan(text):
        return bordered.plan(events.packed_unless_switched(spice.read(text).system), rule)

    first = plan(deck)
    assert first is not None and len(reads) == 1
    assert plan(deck) == first and len(reads) == 1
    wider = deck.replace("W=19u", "W=21u", 1)
    assert wider != deck
    assert plan(wider) is not None and len(reads) == 2


@pytest.mark.slow
def test_gradients_of_a_banded_circuit_take_the_fixed_step_dense_route():
    """The band plus border is the variable-step loop's solve, and that loop refuses traced
    parameters (its steps are chosen on the host) with a message naming the fix; with a
    fixed step the same circuit is traced on the dense Newton, differentiated by the
    implicit function theorem (docs/gradients.md; the gradient is traced here, not
    compiled: at 253 unknowns that takes minutes and gigabytes)."""
    from diracvi import spice
    from diracvi.discretization.rules import get_rule
    from diracvi.driver import events
    from test_alike_transistors import inverters

    deck = inverters(6, stop="40n").replace("IL n6 0 1u", "IL n6 0 {il}")
    deck = deck.replace(".tran 10n 40n", ".param il=1u\n.tran 10n 40n UIC")
    system = events.packed_unless_switched(spice.read(deck).system)
    solver = bordered.newton_for(system, get_rule("midpoint"))
    assert isinstance(solver, bordered.BorderedNewtonSolver)  # the variable steps' solve
    with pytest.raises(ModelError, match="need a fixed step"):
        jax.grad(lambda il: spice.run(deck, params={"il": il})["v(n6)"][-1])(1e-6)
    solvers = []

    def output(il):
        result = spice.run(deck, dt=4e-9, params={"il": il})
        solvers.append(result.trajectory.solver)
        return result["v(n6)"][-1]

    grad = jax.eval_shape(jax.grad(output), 1e-6)
    assert grad.shape == ()
    assert solvers[-1].startswith("NewtonSolver(") and "implicit-function" in solvers[-1]
