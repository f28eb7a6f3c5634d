"""Growing coordinates stepped from zero in each variable step's gauge
(``diracvi.driver.rebase``; docs/circuits.md, "Time steps")."""

from __future__ import annotations

import numpy as np

from diracvi import spice
from diracvi.driver.rebase import rebase_map

MIXED = """charges, fluxes, a capacitor and a ddt position
V1 p 0 15
E1 m 0 p 0 1
R1 m 0 1k
C1 m 0 1n
L1 m x 1m
R2 x 0 1
B1 y 0 V=ddt(v(p))
R3 y 0 1k
.tran 1u 1m
.end
"""


def test_the_rebased_coordinates_are_those_the_lagrangian_reads_only_linearly():
    """Branch charges of sources, resistors and the inductor (cyclic: ``a = 0``) and the
    sensing fluxes (``L = w ṡ``: ``a = e_s``) are rebased; the capacitor's charge (its
    energy is quadratic in it) and the ``ddt`` position (held by a quadratic term) are
    not; ``G`` holds exactly the ``∂²L/∂ṡ∂w = 1`` of each sensing pair."""
    net = spice.read(MIXED)
    coords = list(net.system.coords)
    mask, gauge = rebase_map(net.system, net.q0)
    rebased = {c for c, k in zip(coords, mask, strict=True) if k}
    assert rebased == set(coords) - {"C1.q", "B1.y0"}
    pairs = {(coords[i], coords[j]): gauge[i, j] for i, j in np.argwhere(gauge != 0.0)}
    assert pairs == {("E1.s", "E1.w"): 1.0, ("B1.s0", "B1.w0"): 1.0}
