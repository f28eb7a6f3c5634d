"""The elementwise forms of tiny products and maxima equal NumPy's, NaN and all.

White-box: reads internals of ``diracvi.solvers``."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from diracvi.solvers import tiny as _tiny


@pytest.mark.parametrize(
    ("a_shape", "x_shape"),
    [
        ((5, 5), (5,)),  # one matrix, one vector
        ((3, 8), (1000, 8)),  # one matrix, a vector per row (the multipliers of a run)
        ((64, 8, 8), (16, 1, 8)),  # a stack of matrices, broadcast over the starts
        ((2, 20), (20,)),  # beyond TINY: the library product
        ((4, 0), (0,)),  # no columns: zeros
    ],
)
def test_matvec_is_the_product(a_shape, x_shape):
    rng = np.random.default_rng(7)
    a, x = rng.normal(size=a_shape), rng.normal(size=x_shape)
    got = np.asarray(jax.jit(_tiny.matvec)(jnp.asarray(a), jnp.asarray(x)))
    want = np.matmul(a, x[..., None])[..., 0]
    assert got.shape == want.shape
    np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-14)


def test_matvec_under_vmap_is_the_product_per_row():
    rng = np.random.default_rng(8)
    a, xs = rng.normal(size=(5, 4)), rng.normal(size=(300, 4))
    got = np.asarray(jax.vmap(lambda x: _tiny.matvec(jnp.asarray(a), x))(jnp.asarray(xs)))
    np.testing.assert_allclose(got, xs @ a.T, rtol=1e-14, atol=1e-14)


@pytest.mark.parametrize("size", [0, 1, 5, 16, 17])
def test_max_abs_is_numpys(size):
    rng = np.random.default_rng(size)
    v = rng.normal(size=(50, size))
    if size:
        v[3, size // 2] = np.nan  # propagates, as jnp.max's reduction does
        v[4, 0] = -np.inf
    got = np.asarray(jax.jit(_tiny.max_abs)(jnp.asarray(v)))
    want = np.max(np.abs(v), axis=-1, initial=0.0)
    np.testing.assert_array_equal(got, want)  # maxima are exact
