"""Momenta that the midpoint step would carry as an undamped −1 mode (issue 28, liec_zener).

A coordinate with no velocity in ``L`` and no constraint row — a diode's flux linkage
without junction charge — has ``p = 0``; the (+) step only keeps its algebraic line as
the mean of two steps, so its round-off alternated undamped, added up, and at a floating
node held by picosiemens (two nearly-off diodes) rang the node by volts once the steps
were short. The variable-step driver holds those momenta at 0 (driver/algebraic.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from _ngspice import available, fine_transient
from diracvi import spice
from diracvi.driver.algebraic import algebraic_mask

needs_ngspice = pytest.mark.skipif(not available(), reason="ngspice is not installed")

# the liec_zener deck's circuit (tests/data/netlists/liec_zener.cir) up to 0.6 ms: past
# the first zero crossing, where node 4 floats between D1 and D2
ZENER = """zener between two diodes, to the first zero crossing
D1 4 0 diode
D2 4 2 diode
R1 2 1 1.0k
V1 1 0 SIN(0 20 1k)
.model diode d bv=10
.tran 0.001m 0.6m
.end
"""


def test_mask_is_the_fluxes_of_junctions_without_charge():
    """The flux linkage of a diode without junction charge is marked. Not marked: a diode
    with CJO (its ``w`` has a co-energy: ``p_w`` is the junction charge), every branch
    charge (each in a KCL row), a behavioural source's sensing flux (a velocity in ``L``
    through the hold term) and its ``ddt`` position ``y`` — no velocity in ``L``, no
    row, ``p = 0``, but held by ``g = ȳ/τ``, a line that reads ``y`` itself: holding its
    momentum would not damp ``y``'s own −1 mode. A planted momentum is not zero in exact
    arithmetic: that coordinate is left alone too."""
    text = ZENER.replace("D2 4 2 diode", "D2 4 2 dcap\n.model dcap d cjo=1p")
    netlist = spice.read(text.replace(".tran", "B3 5 0 v = ddt(V(1))\n.tran"))
    system = netlist.system
    coords = list(system.coords)
    assert "B3.y0" in coords
    mask = algebraic_mask(system, netlist.q0, netlist.p0)
    assert {c for c, m in zip(coords, mask, strict=True) if m} == {"D1.w"}
    p0 = np.array(netlist.p0, dtype=float)
    p0[coords.index("D1.w")] = 1e-20
    assert not algebraic_mask(system, netlist.q0, p0).any()


@pytest.mark.slow
@needs_ngspice
def test_floating_node_between_two_diodes_follows_ngspice():
    """Through the zero crossing at 0.5 ms, where node 4 floats between D1 (~1e-13 A
    forward) and D2 (reverse, ~GMIN): the run completes (it stalled at t = 0.42 ms, the
    error control chasing the alternation), every recorded step has ``p_w = 0``, and
    v(4), v(2) follow a fine ngspice run (reltol 1e-7) to 1e-3 of their peaks on its
    points (measured 8e-5 on the whole deck)."""
    result = spice.run(ZENER, internal=True)
    march = result.trajectory
    assert march.status == 0, march.message
    coords = list(result.netlist.system.coords)
    for name in ("D1.w", "D2.w"):
        assert np.all(march.p[1:, coords.index(name)] == 0.0)
    t, ref = fine_transient(ZENER, ["v(4)", "v(2)"])
    inside = t > 0.0
    for name in ("v(4)", "v(2)"):
        mine = result.at(t[inside])[name]
        peak = np.max(np.abs(ref[name]))
        assert np.max(np.abs(mine - ref[name][inside])) <= 1e-3 * peak, name
