"""Jacobs–Yoshimura proposition: (D_{Δ1} ⊕ D_{Δ2}) ⊠ D_int = D_{(Δ1⊕Δ2)∩Σ} (paper §2.2),
on the paper's torn examples and on random instances; non-clean points are refused.

White-box: reads internals of ``diracvi.dirac._structure``."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from _dirac_cases import random_instance, rlc_torn, spring_chain_torn
from conftest import examples
from diracvi import ModelError
from diracvi.dirac import (
    RedundantFormsWarning,
    direct_sum,
    induced,
    interaction,
    interconnection,
    is_clean,
    tensor,
)
from diracvi.dirac._structure import combined_forms

pytestmark = pytest.mark.filterwarnings("ignore::diracvi.dirac.RedundantFormsWarning")


def _both_sides(inst, q):
    lhs = interconnection(inst.forms, inst.sigma, q, dims=inst.dims)
    rhs = induced(combined_forms(inst.forms, inst.sigma, inst.dims), q)
    return lhs, rhs


@pytest.mark.parametrize("make", [spring_chain_torn, rlc_torn], ids=["springs", "rlc"])
def test_paper_examples(make):
    inst = make()
    q = np.linspace(0.1, 0.9, inst.n)
    lhs, rhs = _both_sides(inst, q)
    assert lhs.is_dirac() and rhs.is_dirac()
    assert lhs.gap(rhs) < 1e-12
    # the interaction matters: without it the product is the bare direct sum, which differs
    parts = [induced(f) for f in inst.forms]
    assert direct_sum(*parts).gap(rhs) > 0.1


def test_spring_chain_by_hand():
    # Δ = {v : v_q2 = v_q2bar}; an element built by hand from eq. (DiracStructCoord)
    inst = spring_chain_torn()
    lhs, _ = _both_sides(inst, np.zeros(4))
    v_q = np.array([1.0, 2.0, 2.0, 3.0])
    v_p = np.array([0.5, -1.0, 0.25, 2.0])
    alpha_q = -v_p + 7.0 * np.array([0.0, 1.0, -1.0, 0.0])  # + λ (dq2 − dq2bar)
    assert lhs.contains(np.concatenate([v_q, v_p, alpha_q, v_q]))
    v_bad = np.array([1.0, 2.0, 2.5, 3.0])  # violates the interconnection constraint
    assert not lhs.contains(np.concatenate([v_bad, v_p, alpha_q, v_bad]))


def test_rlc_by_hand():
    # Δ = ker{(1,−1,−1,0,0), (0,0,0,−1,1), (0,0,1,−1,0)}: v_S1 = v_S2 = v_C = v_R − v_L
    inst = rlc_torn()
    lhs, _ = _both_sides(inst, np.zeros(5))
    v_q = np.array([3.0, 1.0, 2.0, 2.0, 2.0])
    v_p = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    mult = np.array([1.5, -0.5, 2.0]) @ np.array(
        [[1.0, -1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, -1.0, 1.0], [0.0, 0.0, 1.0, -1.0, 0.0]]
    )
    assert lhs.contains(np.concatenate([v_q, v_p, -v_p + mult, v_q]))
    assert not lhs.contains(np.concatenate([v_q, v_p, -v_p + mult + [0, 0, 0, 0, 0.1], v_q]))


@examples(30)
@given(
    seed=st.integers(0, 2**31 - 1),
    dims=st.tuples(st.integers(1, 4), st.integers(1, 4)),
    data=st.data(),
    varying=st.booleans(),
)
def test_random_instances(seed, dims, data, varying):
    rows = [data.draw(st.integers(0, d), label=f"m{i}") for i, d in enumerate(dims)]
    sigma_rows = data.draw(st.integers(1, 3), label="l")
    inst = random_instance(seed, dims, rows, sigma_rows, varying)
    q = np.random.default_rng(seed + 1).standard_normal(inst.n)
    combined = combined_forms(inst.forms, inst.sigma, inst.dims)
    assume(is_clean(combined, q))
    lhs, rhs = _both_sides(inst, q)
    assert lhs.is_dirac() and rhs.is_dirac()
    assert lhs.gap(rhs) < 1e-9
    # the explicit ⊠ of the pieces, evaluated by hand, agrees too
    bounds = np.cumsum([0, *inst.dims])
    parts = [
        induced(f, q[a:b], n=d) if callable(f) else induced(f)
        for f, a, b, d in zip(inst.forms, bounds[:-1], bounds[1:], inst.dims, strict=True)
    ]
    sig = interaction(inst.sigma, q) if callable(inst.sigma) else interaction(inst.sigma)
    assert tensor(direct_sum(*parts), sig).gap(rhs) < 1e-9


def _not_clean_instance():
    # Q1 = (x1, x2) with Δ1° = span{dx1}; Q2 = (y); Σ° = span{dx1 + y dx2}:
    # the combined rank is 2 for y ≠ 0 and drops to 1 at y = 0.
    return [np.array([[1.0, 0.0]]), None], (
        lambda q: q[2] * np.array([[0.0, 1.0, 0.0]]) + np.array([[1.0, 0.0, 0.0]])
    )


def test_non_clean_intersection_is_refused():
    forms, sigma = _not_clean_instance()
    with pytest.raises(ModelError, match=r"not a clean"):
        interconnection(forms, sigma, np.array([0.3, -0.2, 0.0]), dims=(2, 1))
    # away from y = 0 the intersection is clean and the proposition holds
    q = np.array([0.3, -0.2, 0.5])
    lhs = interconnection(forms, sigma, q, dims=(2, 1))
    assert lhs.gap(induced(combined_forms(forms, sigma, [2, 1]), q)) < 1e-12
    # and a single rank-dropping distribution is refused by induced() as well
    with pytest.raises(ModelError, match="rank 1 at q"):
        induced(lambda q: np.array([[q[0], 0.0], [0.0, 1.0]]), np.array([0.0, 0.0]))


def test_redundant_forms_are_flagged_not_refused():
    # dq2 − dq2bar given twice: constant rank 1, so clean, but redundant
    sigma = np.array([[0.0, 1.0, -1.0, 0.0], [0.0, 2.0, -2.0, 0.0]])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        lhs = interconnection([None, None], sigma, np.zeros(4), dims=(2, 2))
    assert any(issubclass(w.category, RedundantFormsWarning) for w in caught)
    assert lhs == induced(sigma[:1])
