"""White-box: constant one-form rows kept sparse (``diracvi.model.sparse_rows``)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

import diracvi as dv
from diracvi.errors import ModelError
from diracvi.model.sparse_rows import SparseRows


def _random(rows=5, cols=7, seed=0):
    rng = np.random.default_rng(seed)
    dense = np.where(rng.random((rows, cols)) < 0.4, rng.standard_normal((rows, cols)), 0.0)
    return dense


def test_products_are_the_dense_matrix_ones():
    """``B v``, ``B V`` (several columns) and ``Bᵀλ`` equal the dense products to
    round-off; the dense form and the SciPy form are ``B`` exactly."""
    dense = _random()
    rows = SparseRows.from_scipy(sp.csr_matrix(dense))
    rng = np.random.default_rng(1)
    v, vv, lam = rng.standard_normal(7), rng.standard_normal((7, 3)), rng.standard_normal(5)
    np.testing.assert_allclose(rows @ v, dense @ v, rtol=0, atol=1e-15 * np.abs(dense).sum())
    np.testing.assert_allclose(rows @ vv, dense @ vv, rtol=0, atol=1e-14)
    np.testing.assert_allclose(rows.transpose_apply(lam), dense.T @ lam, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(np.asarray(rows.dense()), dense)
    np.testing.assert_array_equal(rows.to_scipy().toarray(), dense)


def test_canonical_form_compares_by_value():
    """Duplicates are summed and exact zeros dropped, so the same matrix given in any
    order of triples is equal and hashes alike; a different value is not equal."""
    a = SparseRows([0, 1, 0, 1], [2, 0, 2, 1], [1.0, -1.0, 2.0, 0.0], (2, 3))
    b = SparseRows([1, 0], [0, 2], [-1.0, 3.0], (2, 3))
    assert a == b and hash(a) == hash(b) and a.nnz == 2
    assert a != SparseRows([1, 0], [0, 2], [-1.0, 3.5], (2, 3))
    # a cancelling pair leaves no entry
    assert SparseRows([0, 0], [1, 1], [1.0, -1.0], (1, 2)).nnz == 0


def test_bad_triples_are_refused_with_the_reason():
    with pytest.raises(ModelError, match="outside it"):
        SparseRows([0, 2], [0, 0], [1.0, 1.0], (2, 2))
    with pytest.raises(ModelError, match="NaN or Inf"):
        SparseRows([0], [0], [np.nan], (1, 1))
    with pytest.raises(ModelError, match="one row and one column index per value"):
        SparseRows([0, 1], [0], [1.0], (2, 2))


def test_interaction_of_a_sparse_matrix_is_kept_sparse():
    """``Interaction(scipy.sparse)`` joins parts as the dense one does: the rows' parts
    are read from the triples, ``B`` and ``Bᵀλ`` are the dense ones, and a row whose
    columns lie in one part involves only that part."""
    a = dv.LagrangeDiracSystem(("x",), lambda q, v, t: 0.5 * v @ v - 0.5 * q @ q, name="a")
    b = dv.LagrangeDiracSystem(("y",), lambda q, v, t: 0.5 * v @ v - 0.5 * q @ q, name="b")
    c = dv.LagrangeDiracSystem(("z",), lambda q, v, t: 0.5 * v @ v - 0.5 * q @ q, name="c")
    forms = np.array([[1.0, -1.0, 0.0], [0.0, 0.0, 2.0]])
    sparse = dv.interconnect([a, b, c], [dv.Interaction(sp.csr_matrix(forms))])
    dense = dv.interconnect([a, b, c], [dv.Interaction(forms)])
    assert sparse.incidence() is not None and not sparse.interactions
    assert sparse.row_subsystems == ((0, 1), (2,)) == dense.row_subsystems
    q = np.array([0.3, -0.2, 0.5])
    np.testing.assert_array_equal(sparse.interaction_forms(q), dense.interaction_forms(q))
    lam = np.array([0.7, -1.1])
    np.testing.assert_array_equal(sparse.interaction_force(q, lam), dense.interaction_force(q, lam))
    with pytest.raises(ModelError, match="3 coordinates"):
        dv.interconnect([a, b, c], [dv.Interaction(sp.csr_matrix(np.ones((1, 2))))])
