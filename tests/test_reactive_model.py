"""ngspice's C and L lines beyond ``Xname n+ n- value``: their ``.model`` cards (the
capacitor's CAP or CJ/CJSW geometry, the inductor's IND), the instance's M and SCALE, and
the temperature factor ``1 + TC1·Δ + TC2·Δ²`` (instance over model, Δ from the model's
TNOM, TEMP or DTEMP), each element's charging checked against ngspice's transient of the
same deck, and the formulas' own cases by hand."""

from __future__ import annotations

import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.spice._reactive import EPS_SIO2, capacitance, factor

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

# each C or L charged from one step through its own resistor: every time constant is
# about 1 ms, and each depends on the element's effective value alone
DECK = """capacitor and inductor forms
V1 1 0 PULSE(0 1 0 1u 1u 1 2)
R1 1 2 1k
C1 2 0 1u tc1=2e-3 tc2=1e-5 temp=80
R2 1 3 1k
C2 3 0 cmod 1u dtemp=30
R3 1 4 1Meg
C3 4 0 cgeo w=3m l=2m m=2 scale=1.5
R4 1 5 1
L1 5 0 1m tc1=-3e-3 temp=0
R5 1 6 1
L2 6 0 lmod m=2
R6 1 7 1k
C4 7 0 cmod tc1=0
.model cmod C (cap=0.5u tc1=1e-3 tc2=2e-6 tnom=20)
.model cgeo C (cj=1e-4 cjsw=1e-9 narrow=1u short=2u)
.model lmod L (ind=2m tc1=5e-3 tnom=10)
.tran 10u 5m
.end
"""
PROBES = ("v(2)", "v(3)", "v(4)", "v(7)", "i(L1)", "i(L2)")


def test_values_by_the_formulas():
    # instance TC1/TC2 at TEMP = 80 °C from TNOM 27 °C
    assert factor({"tc1": 2e-3, "tc2": 1e-5}, {}, 80.0, 27.0) == pytest.approx(
        1 + 2e-3 * 53 + 1e-5 * 53**2
    )
    # the model's TNOM, and an instance TC1 = 0 over the model's TC1 (TC2 stays the model's)
    model = {"tc1": 1e-3, "tc2": 2e-6, "tnom": 20.0}
    assert factor({}, model, 57.0, 27.0) == pytest.approx(1 + 1e-3 * 37 + 2e-6 * 37**2)
    assert factor({"tc1": 0.0}, model, 27.0, 27.0) == pytest.approx(1 + 2e-6 * 49)
    # geometry: CJ·(W − NARROW)·(L − SHORT) + 2·CJSW·((L − SHORT) + (W − NARROW))
    geo = {"cj": 1e-4, "cjsw": 1e-9, "narrow": 1e-6, "short": 2e-6}
    w, length = 3e-3 - 1e-6, 2e-3 - 2e-6
    assert capacitance(None, geo, {"w": 3e-3, "l": 2e-3}) == pytest.approx(
        1e-4 * w * length + 2e-9 * (w + length)
    )
    # no L on the line: ngspice's length is 0 (it reads no DEFL there); W is DEFW (10 µm)
    assert capacitance(None, {"cjsw": 1e-9}, {}) == pytest.approx(2e-9 * 10e-6)
    # CJ from THICK (SiO2) and DEL as NARROW = SHORT = 2·DEL
    assert capacitance(None, {"thick": 1e-8, "del": 1e-7}, {"w": 2e-6, "l": 3e-6}) == (
        pytest.approx(EPS_SIO2 / 1e-8 * 1.8e-6 * 2.8e-6)
    )
    assert capacitance(1e-6, {"cap": 2e-6}, {}) == 1e-6  # the line's value first
    assert capacitance(None, {"cap": 2e-6, "cj": 1.0}, {"w": 1.0, "l": 1.0}) == 2e-6


@needs_ngspice
def test_each_element_charges_as_in_ngspice():
    """Every probe follows ngspice's fine transient to 2e-4 of its peak; with the
    temperature factors dropped (a broken reader) C1 alone would be 13 % off."""
    t, ref = ng.fine_transient(DECK, PROBES)
    result = spice.run(DECK)
    inside = t > 0.0
    for name in PROBES:
        mine = result.at(t[inside])[name]
        peak = np.max(np.abs(ref[name]))
        assert np.max(np.abs(mine - ref[name][inside])) <= 2e-4 * peak, name


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (("tc1=0\n", "tc1=0 foo=1\n"), r"line 14: unsupported parameters \['foo'\]"),
        (("ind=2m", "ind=2m nt=10"), r"line 12: .*'lmod'.*\['nt'\].*geometric inductance"),
        (("cap=0.5u", "cap=0.5u bad=1"), r"line 6: .*'cmod'.*sets \['bad'\]"),
        (("C4 7 0 cmod", "C4 7 0 lmod"), r"line 14: model 'lmod' .* is a L model, not a C"),
    ],
)
def test_mistakes_name_the_line(change, match):
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(DECK.replace(*change))
