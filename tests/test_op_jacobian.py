"""The operating point's Jacobian read through its pattern (``spice/_op_jacobian.py``): the
colouring's products give every entry exactly, a hub row read by a VJP included; a row
non-finite at a probe says nothing there; and the point found with the compressed
Jacobian is the dense Jacobian's."""

from __future__ import annotations

import numpy as np
import pytest

from diracvi.spice import _op_jacobian, read
from diracvi.spice import _operating_point as op_module
from diracvi.spice._operating_point import operating_point


def _sparse_with_hubs(rng, size=300):
    """A random sparse matrix (≈3 entries a row, a nonzero diagonal) with a full row and
    a full column, as a supply node's KCL row and multiplier."""
    jac = np.zeros((size, size))
    for i in range(size):
        cols = rng.choice(size, 3, replace=False)
        jac[i, cols] = rng.standard_normal(3)
        jac[i, i] = 1.0 + rng.random()
    jac[7, :] = rng.standard_normal(size)
    jac[:, 11] = rng.standard_normal(size)
    return jac


def test_the_coloured_products_give_every_entry_exactly(monkeypatch):
    """``assemble`` of ``J s_c`` and ``e_iᵀ J`` (the plan's seeds and cotangents) is ``J``
    bit for bit: each coloured entry is the one nonzero term of its product, the hub row
    its own VJP; and far fewer products than columns."""
    monkeypatch.setattr(_op_jacobian, "MIN_SIZE", 0)
    rng = np.random.default_rng(3)
    jac = _sparse_with_hubs(rng)
    found = _op_jacobian.plan(jac != 0.0)
    assert found is not None
    assert 7 in found.dense and found.products < 40
    jvps = found.seeds() @ jac.T  # (colours, rows): row c is J s_c
    vjps = found.cotangents() @ jac
    i, j, values = found.assemble(jvps, vjps)
    rebuilt = np.zeros_like(jac)
    rebuilt[i, j] = values
    np.testing.assert_array_equal(rebuilt, jac)


def test_no_two_columns_of_a_colour_meet_in_a_sparse_row(monkeypatch):
    monkeypatch.setattr(_op_jacobian, "MIN_SIZE", 0)
    rng = np.random.default_rng(4)
    mask = _sparse_with_hubs(rng) != 0.0
    found = _op_jacobian.plan(mask)
    sparse_rows = np.setdiff1d(np.arange(mask.shape[0]), found.dense)
    for i in sparse_rows:
        colours = found.colour[mask[i]]
        assert np.all(colours >= 0) and len(set(colours)) == len(colours)


def test_a_row_is_read_where_it_is_finite_and_full_where_it_never_is():
    first = np.array([[1.0, 0.0, 0.0], [np.nan, 0.0, 0.0], [np.inf, 0.0, 0.0]])
    second = np.array([[0.0, 2.0, 0.0], [0.0, 0.0, 3.0], [np.nan, 0.0, 0.0]])
    mask = _op_jacobian.pattern([first, second])
    np.testing.assert_array_equal(
        mask, [[True, True, False], [False, False, True], [True, True, True]]
    )


def test_small_or_dense_systems_keep_the_dense_jacobian():
    assert _op_jacobian.plan(np.eye(50, dtype=bool)) is None  # below MIN_SIZE
    assert _op_jacobian.plan(np.ones((300, 300), bool)) is None  # every row a hub


DIODES = """diode ladder
V1 in 0 DC 5
R1 in 1 1k
D1 1 2 dmod
R2 2 0 2k
D2 2 3 dmod
R3 3 0 3k
C1 3 0 1n
D3 1 4 dmod
R4 4 0 500
.model dmod D(IS=1e-14 N=1.2 RS=2 CJO=1p)
.tran 1u 10u
.end
"""


@pytest.mark.slow  # two operating-point programs compiled: 103 s at a load of ~8
def test_the_point_with_the_compressed_jacobian_is_the_dense_ones(monkeypatch):
    """A diode ladder's point (plain Newton, junction limiting) with the Jacobian read by
    colours and solved by SuperLU (the size and share thresholds lowered so that this
    small circuit takes that path) is the dense path's to round-off."""
    dense = operating_point(read(DIODES))
    monkeypatch.setattr(_op_jacobian, "MIN_SIZE", 0)
    monkeypatch.setattr(_op_jacobian, "SHARE", 10.0)
    monkeypatch.setattr(_op_jacobian, "DENSE_ROW", 3)  # some rows read by VJPs too
    calls = []
    program = op_module._compressed
    monkeypatch.setattr(op_module, "_compressed", lambda *a: calls.append(1) or program(*a))
    compressed = operating_point(read(DIODES))
    assert calls  # (the path taken)
    assert compressed.method == dense.method
    for node, value in dense.voltages.items():
        assert compressed.voltages[node] == pytest.approx(value, rel=1e-12, abs=1e-15), node
    np.testing.assert_allclose(compressed.q0, dense.q0, rtol=1e-12, atol=1e-24)
