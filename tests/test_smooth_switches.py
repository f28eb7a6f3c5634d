"""PSpice's smooth switches (VSWITCH on S lines, ISWITCH on W lines): their resistance
laws by hand and the operating points of ngspice-39 in its PSpice mode, which reads them
as the XSPICE code models ``pswitch`` and ``aswitch`` (``spice/_switches.py``)."""

from __future__ import annotations

import math

import jax
import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.spice._switches import smooth_law


def _r(kind, x, r_on=1e3, r_off=1e9, x_on=1.1, x_off=0.9):
    law = smooth_law(kind, r_on, r_off, x_on, x_off, control=lambda v, i: v[0],
                     port=lambda v: v[1])  # fmt: skip
    return 1.0 / float(law(np.array([x, 1.0]), (), 0.0, ()))


def test_vswitch_is_a_cubic_in_log_r_flat_at_both_ends():
    """``ln r`` runs from ``ln ROFF`` at VOFF to ``ln RON`` at VON, through the log-mean at
    the middle, held past the ends; its slope vanishes at both ends (r is C¹)."""
    assert _r("VSWITCH", 1.0) == pytest.approx(math.sqrt(1e3 * 1e9), rel=1e-14)
    assert _r("VSWITCH", 1.1) == pytest.approx(1e3, rel=1e-14)
    assert _r("VSWITCH", 5.0) == pytest.approx(1e3, rel=1e-14)
    assert _r("VSWITCH", 0.9) == pytest.approx(1e9, rel=1e-14)
    assert _r("VSWITCH", -5.0) == pytest.approx(1e9, rel=1e-14)
    # a quarter of the way: u = -1/4, ln r = ln√(RON ROFF) + L(-3/8 + 1/32), L = ln 1e-6
    quarter = math.exp(0.5 * math.log(1e12) + math.log(1e-6) * (-0.375 + 0.03125))
    assert _r("VSWITCH", 0.95) == pytest.approx(quarter, rel=1e-13)

    def log_r(x):
        law = smooth_law("VSWITCH", 1e3, 1e9, 1.1, 0.9, control=lambda v, i: v[0],
                         port=lambda v: v[1])  # fmt: skip
        return -jax.numpy.log(law(jax.numpy.stack([x, 1.0]), (), 0.0, ()))

    slope = jax.grad(log_r)
    middle = float(slope(1.0))
    assert middle == pytest.approx(1.5 * math.log(1e-6) / 0.2, rel=1e-12)
    for x in (0.9 + 1e-9, 1.1 - 1e-9):  # (3/2 − 6u²) → 0 at u = ±1/2: measured 2e-8
        assert abs(float(slope(x))) <= 1e-7 * abs(middle)


def test_iswitch_is_log_linear_and_clipped():
    assert _r("ISWITCH", 1.0) == pytest.approx(math.sqrt(1e12), rel=1e-14)
    assert _r("ISWITCH", 0.95) == pytest.approx(1e3 * 1e6**0.75, rel=1e-13)
    assert _r("ISWITCH", 2.0) == pytest.approx(1e3, rel=1e-14)
    assert _r("ISWITCH", 0.0) == pytest.approx(1e9, rel=1e-14)


#: S lines with VSWITCH controls below, inside (five points) and above the window, a
#: reversed window (VON < VOFF), the default RON, ROFF (ngspice-39 crashes, "double free",
#: on a VSWITCH card without VON or VOFF) and equal VON/VOFF (widened ±1 mV); W lines
#: with ISWITCH inside and outside the window
DECK = """smooth switches against ngspice
VDD d 0 2
V1 c1 0 0.5
V2 c2 0 1.0
V3 c3 0 1.05
V4 c4 0 1.3
V5 c5 0 0.95
V6 c6 0 0.91
V7 c7 0 1.099
S1 d o1 c1 0 SWN
R1 o1 0 1k
S2 d o2 c2 0 SWN
R2 o2 0 1k
S3 d o3 c3 0 SWN
R3 o3 0 1k
S4 d o4 c4 0 SWN
R4 o4 0 1k
S5 d o5 c5 0 SWN OFF
R5 o5 0 1k
S6 d o6 c6 0 SWN
R6 o6 0 1k
S7 d o7 c7 0 SWN
R7 o7 0 1k
S8 d o8 c3 0 SWR
R8 o8 0 1k
S9 d o9 c5 0 SWD
R9 o9 0 100k
S10 d o10 c2 0 SWE
R10 o10 0 1k
VS a 0 0
I1 0 a 1.02m
W1 d p1 VS IWN
Rp1 p1 0 1k
VS2 b 0 0
I2 0 b 0.5m
W2 d p2 VS2 IWN
Rp2 p2 0 1k
.MODEL SWN VSWITCH ( VON = 1.1 VOFF = 0.9 RON=1k  ROFF=1e12 )
.MODEL SWR VSWITCH ( VON = 0.9 VOFF = 1.1 RON=10  ROFF=1e6 )
.MODEL SWD VSWITCH ( VON = 1.2 VOFF = 0.8 )
.MODEL SWE VSWITCH ( VON = 1.0 VOFF = 1.0 RON=100 ROFF=1e7 )
.MODEL IWN ISWITCH ( ION = 1.1m IOFF = 0.9m RON=10  ROFF=1e6 )
.tran 1u 1m
.end
"""


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_operating_points_are_ngspices_in_pspice_mode():
    """ngspice-39 with ``ngbehavior=psa``; its pswitch loads each control with 1e12 Ω,
    which moves nothing here (the controls are voltage sources)."""
    ref = ng.operating_point(DECK, behavior="psa")
    ours = spice.operating_point(DECK)
    for node in [f"o{k}" for k in range(1, 11)] + ["p1", "p2"]:
        want = ref[f"v({node})"]
        assert abs(ours[f"v({node})"] - want) <= 1e-10 * max(abs(want), 1e-12), node
    # every regime is exercised: fully off (ROFF), in between, and fully on (RON)
    assert ref["v(o1)"] == pytest.approx(2e3 / (1e3 + 1e12), rel=1e-9)
    assert ref["v(o4)"] == pytest.approx(1.0, rel=1e-12)
    assert 1e-6 < ref["v(o3)"] < 0.5 and 1e-6 < ref["v(p1)"] < 1.5


@pytest.mark.parametrize(
    ("model", "match"),
    [
        ("VSWITCH(VON=1 VOFF=0 RON=1 ROFF=1k TD=1n)", r"VSWITCH model 'sx' .* sets \['td'\]"),
        ("VSWITCH(VON=1 VOFF=0 ROFF=0)", r"needs ROFF > 0 and VON ≠ VOFF"),
    ],
)
def test_bad_cards_are_named(model, match):
    deck = f"t\nV1 c 0 1\nV2 d 0 1\nS1 d o c 0 sx\nR1 o 0 1k\n.model sx {model}\n"
    deck += ".tran 1u 1m\n.end\n"
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(deck)


def test_vswitch_with_vt_is_the_classic_switch():
    """ngspice: a VSWITCH card with VT/VH is its SW switch (a state with hysteresis): the
    same operating point as the SW card, closed at V(c) = 1 > VT + VH."""
    deck = "t\nV1 c 0 1\nV2 d 0 1\nS1 d o c 0 sx\nR1 o 0 1k\n.model sx {}(VT=0.5 VH=0.1 RON=1)\n"
    deck += ".tran 1u 1m\n.end\n"
    smooth = spice.operating_point(deck.format("VSWITCH"))["v(o)"]
    assert smooth == spice.operating_point(deck.format("SW"))["v(o)"]
    assert smooth == pytest.approx(1e3 / 1001, rel=1e-9)
