"""Negative R, L and C, as ngspice 39 accepts them (vendor op-amp macromodels shape a
pole–zero pair with one: ``C4 26 27 -39.75E-9`` in Analog Devices' OP177A): the netlist's
linear parts take any nonzero value, the components keep ``positive`` unless asked
(``negative=True``), and a circuit whose negative pieces sum with positive ones to a
stable whole follows ngspice's transient. A resistance of 0 is 1 mΩ, as ngspice 39's
``RESparam`` sets it."""

from __future__ import annotations

import numpy as np
import pytest

import _ngspice as ng
import diracvi as dv
from diracvi import components as cp
from diracvi import spice

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

# a series R–L–C loop, each element split into a negative and a positive piece in series:
# R = 1k − 400 = 600 Ω, L = 3m − 1m = 2 mH, C = (−2u)·1u/(−2u + 1u) = 2 µF (1 GΩ keeps
# node 6 off a capacitor-only cut-set for the operating point)
SPLIT = """series RLC with negative pieces
V1 1 0 PULSE(0 1 0 1u 1u 1 2)
R1 1 2 1k
R2 2 3 -400
L1 3 4 3m
L2 4 5 -1m
C1 5 6 -2u
C2 6 0 1u
R3 6 0 1e9
.tran 1u 400u
.end
"""


def test_components_refuse_a_negative_value_unless_asked():
    for build, arg in ((cp.Resistor, "resistance"), (cp.Capacitor, "capacitance"),
                       (cp.Inductor, "inductance")):  # fmt: skip
        with pytest.raises(dv.ModelError, match=f"{arg}=-2.0 must be a finite positive"):
            build(-2.0, name="x")
        part = build(-2.0, name="x", negative=True)
        assert dict(part.parameters or {}).get(arg, -2.0) == -2.0
        with pytest.raises(dv.ModelError, match=f"{arg}=0.0 must be a finite nonzero"):
            build(0.0, name="x", negative=True)


def test_a_negative_capacitor_stores_a_negative_energy():
    """``L = −q²/(2C)``: with ``C < 0`` the stored energy ``q²/(2C)`` is negative."""
    part = cp.Capacitor(-2.0, name="c", negative=True, v0=1.0)
    q0 = part.initial_q[0]
    assert q0 == -2.0  # q = C v
    assert float(part.lagrangian(np.array([q0]), np.array([0.0]))) == pytest.approx(1.0)


@needs_ngspice
def test_negative_pieces_follow_ngspice():
    """v(5), v(6) and the source current follow ngspice's fine transient to 2e-4 of
    their peaks (measured 5.6e-7 for the voltages, 5.8e-5 for the current, on the source's
    1 µs rise)."""
    t, ref = ng.fine_transient(SPLIT, ("v(5)", "v(6)", "i(V1)"))
    result = spice.run(SPLIT)
    inside = t > 0.0
    for name in ("v(5)", "v(6)", "i(V1)"):
        mine = result.at(t[inside])[name]
        peak = np.max(np.abs(ref[name]))
        assert np.max(np.abs(mine - ref[name][inside])) <= 2e-4 * peak, name


@needs_ngspice
def test_a_zero_resistance_is_a_milliohm_as_in_ngspice():
    net = "zero\nV1 1 0 DC 1\nR1 1 2 0\nR2 2 0 1\n.tran 1u 10u\n.end\n"
    assert any("a resistance of 0 is 1 mOhm" in n for n in spice.read(net).notes)
    ref = ng.operating_point(net)["i(v1)"]
    assert ref == pytest.approx(-1.0 / 1.001, rel=1e-12)
    assert spice.run(net)["i(v1)"][-1] == pytest.approx(ref, rel=1e-9)
