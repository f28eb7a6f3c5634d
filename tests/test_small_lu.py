"""The dense LU in plain operations (diracvi.solvers.small_lu)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl

from diracvi.solvers import small_lu

EPS = np.finfo(np.float64).eps


def _matrices():
    rng = np.random.default_rng(30)
    for n in (1, 2, 3, 7, 15, small_lu.SMALL):
        yield rng.normal(size=(n, n))
    # a circuit-like matrix: entries over 20 decades (a conducting and a blocking diode)
    a = rng.normal(size=(15, 15)) * 10.0 ** rng.uniform(-12, 8, size=(15, 15))
    yield a + np.diag(10.0 ** rng.uniform(-6, 4, size=15))


@pytest.mark.parametrize("a", list(_matrices()), ids=lambda a: f"n{a.shape[0]}")
def test_factors_are_lapacks_pivoting_to_round_off(a):
    """``a[perm] = L U`` within the backward error of Gaussian elimination with partial
    pivoting (Higham, Thm 9.3: ``|ΔA| ≤ γ_n |L||U|``), with the rows LAPACK's ``getrf``
    picks (the same partial pivoting: the first largest ``|a_pk|``)."""
    n = a.shape[0]
    lu, perm = (np.asarray(f) for f in jax.jit(small_lu.lu_factor)(jnp.asarray(a)))
    lower = np.tril(lu, -1) + np.eye(n)
    upper = np.triu(lu)
    gamma = n * EPS / (1 - n * EPS)
    bound = gamma * (np.abs(lower) @ np.abs(upper))
    assert np.all(np.abs(a[perm] - lower @ upper) <= bound + 1e-300)
    p, _, _ = sl.lu(a)  # a = P L U: row i of P L U is row perm[i] of a
    assert np.array_equal(perm, np.argmax(p, axis=0))


@pytest.mark.parametrize("a", list(_matrices()), ids=lambda a: f"n{a.shape[0]}")
def test_solve_is_backward_stable(a):
    """``A x = b``: the normwise backward error ``‖b − A x‖ / (‖A‖ ‖x‖ + ‖b‖)`` (∞-norms)
    within a small multiple of ``n ε`` (partial pivoting's growth on these matrices is
    small; LAPACK's own solve is held to the same bound)."""
    n = a.shape[0]
    b = np.random.default_rng(n).normal(size=n)
    x = np.asarray(jax.jit(lambda a, b: small_lu.lu_solve(small_lu.lu_factor(a), b))(a, b))
    ref = sl.lu_solve(sl.lu_factor(a), b)
    for sol in (x, ref):
        back = np.abs(b - a @ sol).max() / (
            np.abs(a).sum(axis=1).max() * np.abs(sol).max() + np.abs(b).max()
        )
        assert back <= 10 * n * EPS


def test_singular_matrix_gives_non_finite_solution():
    """An exactly singular Jacobian must reach Newton as a non-finite update (its
    ``SINGULAR`` status), as LAPACK's zero pivot does."""
    a = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]])
    x = jax.jit(lambda a: small_lu.lu_solve(small_lu.lu_factor(a), jnp.ones(3)))(a)
    assert not np.all(np.isfinite(np.asarray(x)))
