"""The once-per-plan checks of large models equal their dense definitions.

From a few hundred coordinates on, the initial-data check's complement projector
``I − B B⁺`` (``B = [W, Aᵀ]``) is formed block by block, and a clearly regular step
Jacobian is recognised by a sparse LU instead of an SVD. Both are compared here with the
dense formulas on random instances that have what models have: block-diagonal ``W`` with
massless (singular) blocks, constraint rows across blocks, singular Jacobians. The
groups of connected ports (connected components of the connection graph, by index) are
compared with a union–find over the coordinates' names.

White-box: reads internals of ``diracvi.model.consistency``,
``diracvi.solvers.solvability``."""

import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.model.consistency import _complement, _port_groups
from diracvi.solvers.solvability import check_step_jacobian, null_directions, singular_members


def _dense_complement(w, forms):
    basis = np.concatenate([w, forms.T], axis=1)
    return np.eye(w.shape[0]) - basis @ np.linalg.pinv(basis, rcond=1e-12)


def _block_mass_matrix(rng, n, massless):
    """Block diagonal, symmetric PSD; blocks of random size, ``massless`` of them with a
    null space (a part with velocity-free coordinates)."""
    w, start, index = np.zeros((n, n)), 0, 0
    while start < n:
        size = min(int(rng.integers(5, 40)), n - start)
        rank = size - int(rng.integers(1, size + 1)) if index < massless else size
        a = rng.normal(size=(size, max(rank, 0)))
        w[start : start + size, start : start + size] = a @ a.T
        start, index = start + size, index + 1
    perm = rng.permutation(n)  # blocks need not be contiguous
    return w[np.ix_(perm, perm)]


@pytest.mark.parametrize("seed", range(4))
def test_blockwise_complement_equals_the_pseudoinverse_projector(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(200, 320))
    w = _block_mass_matrix(rng, n, massless=int(rng.integers(0, 6)))
    m = int(rng.integers(0, 30))
    forms = rng.normal(size=(m, n)) * (rng.random((m, n)) < 0.05)  # sparse rows
    got, want = _complement(w, forms), _dense_complement(w, forms)
    # the dense formula's own round-off is ≈ cond(B)·ε here (up to 2e-10)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    # and exactly what it defines: a symmetric projector annihilated by W and A
    np.testing.assert_allclose(got @ got, got, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got, got.T, rtol=0, atol=1e-14)
    assert np.max(np.abs(w @ got)) <= 1e-11 * np.max(np.abs(w))
    assert np.max(np.abs(forms @ got), initial=0.0) <= 1e-11 * max(1.0, np.max(np.abs(forms)))
    # a projector whose rank is the dimension of ker W ∩ ker A
    assert round(np.trace(got)) == n - np.linalg.matrix_rank(np.concatenate([w, forms.T], 1))


def test_blockwise_complement_of_a_regular_mass_matrix_is_zero():
    rng = np.random.default_rng(7)
    w = _block_mass_matrix(rng, 250, massless=0)
    assert not np.any(_complement(w, np.zeros((0, 250))))


def _names(k):
    return [f"x{i}" for i in range(k)], [f"r{i}" for i in range(k)]


def test_a_large_regular_jacobian_passes_and_a_singular_one_is_named_as_by_the_svd():
    rng = np.random.default_rng(3)
    n = 260
    jac = _block_mass_matrix(rng, n, massless=0) + np.eye(n)
    jac[0, 100] = 0.3  # coupling rows, as interactions make
    unknowns, equations = _names(n)
    check_step_jacobian(jac, unknown_names=unknowns, equation_names=equations, where="test")
    singular = jac.copy()
    singular[17] = 2.0 * singular[42]  # two equations that clash
    with pytest.raises(dv.UnsolvableStepError, match="1 null direction") as info:
        check_step_jacobian(singular, unknown_names=unknowns, equation_names=equations, where="t")
    _, left = null_directions(singular)
    clashing = [equations[i] for i in np.nonzero(np.max(np.abs(left), axis=1) > 1e-6)[0]]
    assert set(clashing) == {"r17", "r42"}
    assert f"Dependent equations: {', '.join(clashing)}." in str(info.value)


def test_a_nearly_singular_but_regular_jacobian_is_decided_by_the_svd():
    """A pivot below the LU's clear margin sends the matrix to the SVD, which accepts a
    smallest singular value of 1e-9 (its threshold is ≈ 1e-11 · n)."""
    rng = np.random.default_rng(5)
    n = 220
    q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    s = np.ones(n)
    s[-1] = 1e-9
    jac = (q * s) @ q.T
    unknowns, equations = _names(n)
    check_step_jacobian(jac, unknown_names=unknowns, equation_names=equations, where="test")


@pytest.mark.parametrize("n", [6, 210])  # a stacked SVD; the sparse LU first, then SVDs
def test_the_batched_screen_of_a_sweep_flags_exactly_the_singular_jacobians(n):
    # a sweep screens its members' step Jacobians together: the verdict of the rank test
    # of each one alone (null_directions), a non-finite one flagged too
    rng = np.random.default_rng(n)
    jacs = np.stack([_block_mass_matrix(rng, n, massless=0) + np.eye(n) for _ in range(4)])
    jacs[1, 3] = 2.0 * jacs[1, 4]  # two equations that clash
    jacs[2, :, 0] = 0.0  # an unknown no equation fixes
    jacs[3, 2, 2] = np.nan
    assert singular_members(jacs).tolist() == [False, True, True, True]
    if n < 200:  # (large: singular_members calls null_directions itself)
        assert [null_directions(j)[0].shape[1] > 0 for j in jacs[:3]] == [False, True, True]


def _named_port_groups(system):
    """Union–find over names: a coordinate ``sub.x`` of a nested interconnection is
    joined to ``sub.y`` if ``sub`` connects ``x`` and ``y``."""

    def ports(sys, prefix=""):
        pairs = [(prefix + a, prefix + b) for a, b in getattr(sys, "ports", ())]
        for sub in getattr(sys, "subsystems", ()):
            pairs += ports(sub, f"{prefix}{sub.name}.")
        return pairs

    parent = {c: c for c in system.coords}

    def root(c):
        while parent[c] != c:
            c = parent[c]
        return c

    for a, b in ports(system):
        parent[root(a)] = root(b)
    groups = {}
    for i, c in enumerate(system.coords):
        groups.setdefault(root(c), []).append(i)
    return [g for g in groups.values() if len(g) > 1]


def test_port_groups_by_index_equal_the_union_find_over_names_also_when_nested():
    flat = problems.chain_torn(9, 3)
    s0, s1, s2 = flat.system.subsystems
    front = dv.interconnect([s0, s1], [dv.connect(f"s0.{s0.coords[-1]}", "s1.qbar")], name="f")
    nested = dv.interconnect([front, s2], [dv.connect(f"f.s1.{s1.coords[-1]}", "s2.qbar")])
    for system in (flat.system, nested, problems.get("dc-motor").system):
        got = [g.tolist() for g in _port_groups(system)]
        assert got == _named_port_groups(system)
        assert got  # each of them has connected ports
