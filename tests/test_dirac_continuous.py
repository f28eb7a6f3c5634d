"""Continuous Dirac structures at a point: D = D^⊥, eq. (DiracStructCoord) by hand,
the associated distribution and two-form, ⊕ ordering, ⊠, and failures that must fail."""

from __future__ import annotations

import numpy as np
import pytest

from diracvi import ModelError
from diracvi.dirac import (
    DiracStructure,
    direct_sum,
    induced,
    interaction,
    pairing_matrix,
    tensor,
)

RNG = np.random.default_rng(20240611)


def _rlc_forms():
    return np.array([[1.0, -1.0, -1.0]])


def test_induced_matches_eq_dirac_struct_coord_by_hand():
    # Δ = ker (1, −1, −1) on R^3 (the RLC circuit's KCL). Eq. (DiracStructCoord):
    # v_q ∈ Δ, α_p = v_q, α_q + v_p ∈ Δ° = span{(1, −1, −1)}.
    d = induced(_rlc_forms())
    v_q = np.array([2.0, 1.5, 0.5])  # 2 − 1.5 − 0.5 = 0: in Δ
    v_p = np.array([0.3, -0.7, 1.1])
    alpha_q = -v_p + 4.0 * np.array([1.0, -1.0, -1.0])
    member = np.concatenate([v_q, v_p, alpha_q, v_q])
    assert d.contains(member)
    # each condition broken on its own is detected
    assert not d.contains(np.concatenate([[2.0, 1.5, 0.6], v_p, alpha_q, [2.0, 1.5, 0.6]]))
    assert not d.contains(np.concatenate([v_q, v_p, alpha_q, v_q + np.array([0, 0.1, -0.1])]))
    assert not d.contains(np.concatenate([v_q, v_p, alpha_q + np.array([0.1, 0, 0]), v_q]))
    assert d.dim == 6 and d.is_dirac()


def test_pairing_matrix_is_the_symmetric_pairing():
    n = 2
    x, y = RNG.standard_normal(4 * n), RNG.standard_normal(4 * n)
    expected = x[2 * n :] @ y[: 2 * n] + y[2 * n :] @ x[: 2 * n]
    assert x @ pairing_matrix(n) @ y == pytest.approx(expected, rel=1e-14)


@pytest.mark.parametrize(
    "make",
    [
        lambda: induced(_rlc_forms()),
        lambda: induced(None, n=3),
        lambda: induced(np.eye(3)),  # Δ = {0}
        lambda: interaction(np.array([[0.0, 1.0, -1.0, 0.0]])),
        lambda: direct_sum(induced(_rlc_forms()), induced(np.array([[-1.0, 1.0]]))),
        lambda: tensor(
            direct_sum(induced(None, n=2), induced(None, n=2)),
            interaction(np.array([[0.0, 1.0, -1.0, 0.0]])),
        ),
        lambda: induced(lambda q: np.array([[1.0, 0.0, -np.cos(q[3]), 0.0]]), np.ones(4)),
    ],
    ids=["induced", "TQ", "zero-distribution", "interaction", "direct-sum", "tensor", "callable"],
)
def test_every_construction_is_dirac_and_equals_its_orthogonal(make):
    d = make()
    assert d.is_dirac()
    assert d.dim == 2 * d.n
    assert d.isotropy_defect() < 1e-14
    assert d.orthogonal() == d  # D = D^⊥
    # and a random element of D pairs to zero with every basis vector
    x = RNG.standard_normal(d.dim) @ d.basis
    assert np.max(np.abs(d.basis @ pairing_matrix(d.n) @ x)) < 1e-13


def test_non_isotropic_subspace_fails():
    # (v, α) with ⟨α, v⟩ = 1 ≠ 0: ⟨⟨x, x⟩⟩ = 2 ≠ 0
    x = np.array([1.0, 0.0, 1.0, 0.0])  # n = 1: v = (1, 0), α = (1, 0)
    d = DiracStructure.from_subspace(x)
    assert d.isotropy_defect() == pytest.approx(1.0)  # ⟨⟨x̂, x̂⟩⟩ = 2·½
    assert not d.is_dirac()
    assert d.orthogonal() != d
    with pytest.raises(ModelError, match="not isotropic"):
        d.two_form()


def test_non_maximal_isotropic_subspace_fails():
    # span{(v, 0)} is isotropic but 1-dimensional in a 4-dimensional V ⊕ V*
    d = DiracStructure.from_subspace(np.array([[1.0, 2.0, 0.0, 0.0]]))
    assert d.is_isotropic() and not d.is_dirac()
    perp = d.orthogonal()
    assert perp.dim == 3 and perp != d
    # D ⊂ D^⊥ strictly
    assert all(perp.contains(b) for b in d.basis)


def test_maximal_but_not_isotropic_fails():
    # 2n-dimensional graph of a symmetric (not skew) map: α = S v
    sym = np.array([[1.0, 0.5], [0.5, 2.0]])
    d = DiracStructure.from_subspace(np.concatenate([np.eye(2), sym], axis=1))
    assert d.dim == 2 and not d.is_dirac()
    # the graph of a skew map is Dirac
    skew = np.array([[0.0, 3.0], [-3.0, 0.0]])
    assert DiracStructure.from_subspace(np.concatenate([np.eye(2), skew], axis=1)).is_dirac()


def test_distribution_and_two_form_of_induced_structure_are_delta_tstarq_and_omega():
    a = _rlc_forms()
    d = induced(a)
    dist = d.distribution()  # Δ_{T*Q} = {(v_q, v_p) : v_q ∈ Δ}, dim = (n − 1) + n = 5
    assert dist.shape == (5, 6)
    assert np.allclose(a @ dist[:, :3].T, 0.0, atol=1e-14)
    w = d.two_form()
    # ω_{Δ_D} = Ω restricted to Δ_{T*Q}: Ω(u, w) = u_q·w_p − u_p·w_q
    omega = dist[:, :3] @ dist[:, 3:].T - dist[:, 3:] @ dist[:, :3].T
    assert np.allclose(w, omega, atol=1e-13)
    assert np.allclose(w, -w.T, atol=1e-13)


def test_two_form_of_interaction_structure_is_zero_on_sigma_int():
    b = np.array([[0.0, 1.0, -1.0, 0.0]])
    d = interaction(b)
    dist = d.distribution()
    assert dist.shape == (7, 8)  # Σ_int: (n − 1) + n
    assert np.max(np.abs(d.two_form())) < 1e-14


def test_two_form_is_independent_of_the_chosen_alpha():
    d = induced(_rlc_forms())
    u = d.distribution()
    omega = d.two_form(u)
    assert np.max(np.abs(omega)) > 0.5  # not the zero form
    # a bilinear, skew form: another basis C u of the same span gives C ω Cᵀ, whatever
    # covectors α_u the implementation picks for the new vectors
    c = np.random.default_rng(5).standard_normal((5, 5))
    np.testing.assert_allclose(d.two_form(c @ u), c @ omega @ c.T, atol=1e-12)
    np.testing.assert_allclose(omega, -omega.T, atol=1e-13)
    with pytest.raises(ModelError, match="not in the distribution"):
        d.two_form(np.array([[1.0, 1.0, 1.0, 0.0, 0.0, 0.0]]))  # v_q ∉ Δ


def test_direct_sum_reorders_to_q1_q2_p1_p2():
    d1, d2 = induced(_rlc_forms()), induced(np.array([[-1.0, 1.0]]))
    s = direct_sum(d1, d2)
    assert s.n == 5 and s.is_dirac()
    # an element of D1 and one of D2 …
    x1 = np.concatenate([[1.0, 0.5, 0.5], [1, 2, 3], [-1, -2, -3], [1.0, 0.5, 0.5]])
    x2 = np.concatenate(
        [[0.7, 0.7], [4, 5], np.array([-4, -5]) + 2.0 * np.array([-1, 1]), [0.7, 0.7]]
    )
    assert d1.contains(x1) and d2.contains(x2)
    # … glue as (v_q1, v_q2, v_p1, v_p2, α_q1, α_q2, α_p1, α_p2)
    glued = np.concatenate(
        [x1[0:3], x2[0:2], x1[3:6], x2[2:4], x1[6:9], x2[4:6], x1[9:12], x2[6:8]]
    )
    assert s.contains(glued)
    naive = np.concatenate([x1, x2])  # (q1, p1, …, q2, p2, …): the wrong order
    assert not s.contains(naive)
    # and ⊕ of induced = induced of ⊕ (paper §2.2)
    both = np.array([[1.0, -1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, -1.0, 1.0]])
    assert s == induced(both)


def test_tensor_definition_checked_with_explicit_beta():
    # (v, α) ∈ Da ⊠ Db iff ∃β: (v, α + β) ∈ Da and (v, −β) ∈ Db
    da = induced(None, n=2)
    db = interaction(np.array([[1.0, -1.0]]))
    prod = tensor(da, db)
    v = np.array([1.0, 1.0, 0.3, -0.2])  # v_q ∈ Σ = {v1 = v2}
    beta = np.array([2.0, -2.0, 0.0, 0.0])  # −β ∈ Σ_int°
    alpha = np.concatenate([-v[2:], v[:2]]) - beta  # α + β = (−v_p, v_q) ∈ D_TQ
    assert da.contains((v, alpha + beta)) and db.contains((v, -beta))
    assert prod.contains((v, alpha))
    assert prod.is_dirac()
    # the product with the trivial interaction (Σ = TQ) changes nothing
    assert tensor(da, interaction(None, n=2)) == da


def test_argument_errors_name_the_argument():
    with pytest.raises(ModelError, match="basis"):
        DiracStructure.from_subspace(np.ones((2, 6)))
    with pytest.raises(ModelError, match="q="):
        induced(lambda q: np.ones((1, 2)))
    with pytest.raises(ModelError, match="dim Q"):
        tensor(induced(None, n=2), induced(None, n=3))
    with pytest.raises(ModelError, match="4n"):
        induced(None, n=2).contains(np.ones(5))


def _tensor_by_definition(da, db):
    # {(v, α) | ∃β: (v, α + β) ∈ Da, (v, −β) ∈ Db} by brute force: the kernel of the two
    # membership conditions in the unknowns (v, α, β), then projected onto (v, α)
    n2 = 2 * da.n
    pa = np.eye(2 * n2) - da.basis.T @ da.basis  # annihilates Da exactly
    pb = np.eye(2 * n2) - db.basis.T @ db.basis
    eye, zero = np.eye(n2), np.zeros((n2, n2))
    to_a = np.block([[eye, zero, zero], [zero, eye, eye]])  # (v, α, β) ↦ (v, α + β)
    to_b = np.block([[eye, zero, zero], [zero, zero, -eye]])  # (v, α, β) ↦ (v, −β)
    _, s, vt = np.linalg.svd(np.concatenate([pa @ to_a, pb @ to_b]))
    kernel = vt[np.sum(s > 1e-10) :]
    return DiracStructure.from_subspace(kernel[:, : 2 * n2])


def test_tensor_equals_its_definition_where_the_shared_covector_sign_matters():
    # two induced structures with non-zero two-forms on their distributions: (v, γ) ∈ D
    # does not give (v, −γ) ∈ D, so α = γ_a + γ_b and α = γ_a − γ_b differ
    da = induced(np.array([[1.0, -1.0, 0.5]]))
    db = induced(np.array([[0.0, 1.0, 2.0]]))
    prod = tensor(da, db)
    assert prod == _tensor_by_definition(da, db)
    # Da = Db = D_TQ: (v, α + β) = (v, −β) = (v, ω♭v) forces α = 2 ω♭v
    d_tq = induced(None, n=1)
    v = np.array([0.7, -0.4])
    assert tensor(d_tq, d_tq).contains((v, 2.0 * np.array([-v[1], v[0]])))
