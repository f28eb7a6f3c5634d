"""The running error bound of a computed value (``diracvi.runtime.roundoff``).

``with_bound(f, *args)`` carries ``E(z) = Σ_j |∂g/∂x_j| E(x_j) + u|z|`` through every
operation of ``f``; it must bound the value's true round-off — checked against exact
rational arithmetic on the same floating-point inputs — and add nothing for the
operations that round nothing.
"""

from __future__ import annotations

from fractions import Fraction

import jax
import jax.numpy as jnp
import numpy as np

from diracvi.runtime.config import ensure_float64
from diracvi.runtime.roundoff import UNIT, with_bound
from diracvi.spice._expr import compile_expression

ensure_float64()

#: ng_memristor's law: beta*y - ½beta(|y + Vt| - |y - Vt|), exactly 0 for |y| < Vt
BETA, VT = 2e12, 1.6
MEMRISTOR = compile_expression(
    "f1(v(a))",
    {"beta": BETA, "alpha": 0.0, "vt": VT},
    {"f1": (["y"], "beta*y+0.5*(alpha-beta)*(abs(y+Vt)-abs(y-Vt))")},
)


def _exact(y: float) -> Fraction:
    """The law in exact arithmetic on the float64 inputs (the numbers as stored)."""
    b, vt, y = Fraction(BETA), Fraction(VT), Fraction(y)
    return b * y + Fraction(-1, 2) * b * (abs(y + vt) - abs(y - vt))


def _law(y):
    return with_bound(MEMRISTOR.fn, jnp.array([y]), jnp.zeros(0), 0.0, jnp.zeros(0))


def test_the_bound_holds_where_the_terms_cancel():
    # below the threshold the law is 0 and computes to u times its ~1e12 terms; the bound
    # must cover every value's deviation from the exact one, and it is a bound of the
    # right size (not a multiple of the terms: within 2^4 of the worst deviation)
    ys = np.concatenate(
        [np.linspace(-3.0, 3.0, 4001), VT + np.linspace(-1e-9, 1e-9, 201), [0.0, VT, -VT]]
    )
    values, bounds = map(np.asarray, jax.jit(jax.vmap(_law))(jnp.asarray(ys)))
    values, bounds = values.reshape(-1), bounds.reshape(-1)
    off = np.array([abs(float(Fraction(v) - _exact(y))) for v, y in zip(values, ys, strict=True)])
    assert np.all(off <= bounds), float(np.max(off / bounds))
    inside = np.abs(ys) < VT
    assert np.max(off[inside]) > 1e-4  # the cancellation's round-off is there (measured 6.9e-4)
    assert np.max(bounds[inside]) < 16.0 * np.max(off[inside])
    # and the bound is of the terms, u times ~|beta y| + beta Vt: at y = 0.5, 3.2e12 u
    # at least (the last sum's two terms) and at most the sum over all operations
    b = float(np.asarray(_law(0.5)[1]).reshape(()))
    assert 3.2e12 * UNIT <= b <= 1.2e13 * UNIT


def test_a_sum_without_cancellation_is_bounded_by_its_partial_sums():
    # (x + y) + z: each addition rounds its result once, E = u(|x + y| + |x + y + z|)
    x, y, z = 0.1, 0.7, 1.3
    value, bound = with_bound(lambda a, b, c: (a + b) + c, x, y, z)
    assert float(value) == (x + y) + z
    assert float(bound) == UNIT * abs(x + y) + UNIT * abs((x + y) + z)


def test_operations_that_round_nothing_add_nothing():
    # a sign change, abs, a select, max, a slice: exact, so exact inputs stay exact
    def f(v):
        a = -jnp.abs(v[0])
        return jnp.where(v[1] > 0.0, jnp.maximum(a, v[1]), a)

    for v in ([0.3, -2.0], [-0.7, 5.0]):
        value, bound = with_bound(f, jnp.asarray(v))
        assert float(bound) == 0.0, (v, float(value))
    # a product of an exact input and an inexact one carries the inexact one's bound
    _, bound = with_bound(lambda a, b: a * (b + 0.1), 3.0, 0.2)
    assert float(bound) == 3.0 * UNIT * (0.2 + 0.1) + UNIT * 3.0 * (0.2 + 0.1)
