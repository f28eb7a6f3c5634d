"""ngspice's R line beyond ``Rname n+ n- value``: the semiconductor-resistor ``.model``
(RSH, NARROW, SHORT, DEFW, L, R), the instance's L, W, M, SCALE and the temperature
factor (TC1, TC2, TCE against TNOM, DTEMP), each resistance checked against ngspice's
operating point of the same deck, and the formula's own cases by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.spice._resistor import effective

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

# one 1 V source, each resistor in series with its own 0 V ammeter
DECK = """resistor forms
Vin 1 0 DC 1
VA 1 2 DC 0
RA 2 0 rsheet L=11u W=2.5u
VB 1 3 DC 0
RB 3 0 rsheet
VC 1 4 DC 0
RC 4 0 2k m=4 scale=3
VD 1 5 DC 0
RD 5 0 rtc L=20u W=4u dtemp=30
VE 1 6 DC 0
RE 6 0 1k rexp temp=77
VF 1 7 DC 0
RF 7 0 ronly
VG 1 8 DC 0
RG 8 0 rsheet L=11u W=2.5u tc1=1e-3 dtemp=-20
.model rsheet R RSH=1000 NARROW=0.2u SHORT=0.5u
.model rtc R RSH=50 TC1=2e-3 TC2=1e-5 TNOM=20 DEFW=3u
.model rexp R TCE=0.5
.model ronly R R=3.3k
.tran 1u 10u
.end
"""
AMMETERS = {"a": "va", "b": "vb", "c": "vc", "d": "vd", "e": "ve", "f": "vf", "g": "vg"}


def test_resistances_by_the_formula():
    rsh = {"rsh": 1000.0, "narrow": 0.2e-6, "short": 0.5e-6}
    assert effective(None, rsh, {"l": 11e-6, "w": 2.5e-6}) == pytest.approx(1000 * 10e-6 / 2.1e-6)
    assert effective(None, rsh, {}) == pytest.approx(1000 * 9e-6 / 9.6e-6)  # L, DEFW = 10 µm
    assert effective(2e3, {}, {"m": 4.0, "scale": 3.0}) == pytest.approx(1.5e3)
    tc = {"rsh": 50.0, "tc1": 2e-3, "tc2": 1e-5, "tnom": 20.0, "defw": 3e-6}
    d = 27.0 + 30.0 - 20.0
    assert effective(None, tc, {"l": 20e-6, "w": 4e-6, "dtemp": 30.0}) == pytest.approx(
        250.0 * (1 + 2e-3 * d + 1e-5 * d * d)
    )
    assert effective(1e3, {"tce": 0.5}, {"temp": 77.0}) == pytest.approx(1e3 * 1.01**25)
    assert effective(None, {"r": 3.3e3}, {}) == 3.3e3
    # W = 2·NARROW: ngspice's conductance is 0
    assert math.isinf(effective(None, {"rsh": 1e3, "narrow": 1e-6}, {"l": 11e-6, "w": 2e-6}))


@needs_ngspice
def test_each_resistor_form_carries_ngspices_current():
    ref = ng.operating_point(DECK)
    result = spice.run(DECK)
    for label, ammeter in AMMETERS.items():
        mine = result[f"i({ammeter})"][-1]
        assert mine == pytest.approx(ref[f"i({ammeter})"], rel=1e-9), label


def test_an_open_resistor_is_left_out_and_model_mistakes_name_the_line():
    open_deck = DECK.replace("W=2.5u tc1", "W=0.4u tc1")  # W = 2·NARROW
    netlist = spice.read(open_deck)
    assert any("RG: W = 2·NARROW" in n and "open circuit" in n for n in netlist.notes)
    assert np.all(spice.run(open_deck)["i(vg)"] == 0.0)
    bad = DECK.replace("rsheet\nVC", "rbad\nVC").replace(".tran", ".model rbad R FOO=2\n.tran")
    with pytest.raises(spice.NetlistError, match=r"line 6: .*'rbad'.*sets \['foo'\]"):
        spice.read(bad)
    with pytest.raises(spice.NetlistError, match=r"line 8: .*unsupported parameters \['x'\]"):
        spice.read(DECK.replace("m=4", "x=4"))
    with pytest.raises(spice.NetlistError, match=r"line 8: RC m=-4: it must be positive"):
        spice.read(DECK.replace("m=4", "m=-4"))
