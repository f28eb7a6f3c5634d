"""Netlist forms met in the held-out field test (docs/circuits.md, "A held-out field
test (2026-11-30)"): each a minimal deck of the syntax, checked against ngspice 39's
reading of the same text (its ``.op``) where ngspice is installed, and against the value
its manual defines."""

from __future__ import annotations

import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.spice._expr import evaluate_constant

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

# ngspice reads the whole rest of a single-assignment .param line as its expression; a
# {name} inside stands for the parameter's value, TEMPER for the circuit temperature
PARAM_BLANKS = """unbraced .param expressions with blanks
.param fact = 2
.param tgain = 1. + (TEMPER / 27. - 1.) * {fact} + 0.5 * fact
.param g2 = 3 * 2 + 1
v1 1 0 {g2}
r1 1 0 {tgain}
.tran 1m 2m
.end
"""


def test_param_expression_with_blanks_is_the_rest_of_the_line():
    netlist = spice.read(PARAM_BLANKS)
    assert netlist.params["g2"] == 7.0  # 3*2+1, not 3
    assert netlist.params["tgain"] == 2.0  # 1 + (27/27 - 1)*2 + 0.5*2


@needs_ngspice
def test_param_expression_with_blanks_as_ngspice_reads_it():
    op = ng.operating_point(PARAM_BLANKS)  # v1 = g2 across r1 = tgain
    assert -op["i(v1)"] == pytest.approx(7.0 / 2.0, rel=1e-12)


def test_several_unbraced_assignments_are_refused_naming_the_fix():
    # ngspice 39 reads '.param a = 1 + 2, b = 3' as a = 1: no reading to copy
    with pytest.raises(spice.NetlistError) as info:
        spice.read("t\n.param a = 1 + 2, b = 3\nv1 1 0 {a}\nr1 1 0 1\n.tran 1m 2m\n.end\n")
    text = str(info.value)
    assert "line 2:" in text and "in braces" in text and ".param x={a + b}" in text


# CIDER's numerical BJT (examples/cider/bjt/invchain.cir): its card holds words
# (concmod=sg), so the type is checked before any value is read
CIDER_BJT = """numerical bjt
vcc 1 0 5
rc 1 2 1k
q1 2 1 0 qmod area = 100p
.model qmod nbjt level=1 x.mesh node=1 loc=0.0 x.mesh node=61 loc=3.0
+ mobility material=1 concmod=sg fieldmod=sg
+ doping unif n.type conc=1e17 x.l=0.0 x.h=1.0
.tran 1n 10n
.end
"""


def test_cider_model_is_refused_as_such_not_by_a_parameter():
    with pytest.raises(spice.NetlistError) as info:
        spice.read(CIDER_BJT)
    text = str(info.value)
    assert "the netlist has 1 problem:" in text
    assert "line 4: model 'qmod' (line 5) is a NBJT (CIDER's numerical device" in text
    assert "needs NPN/PNP" in text and "unknown parameter" not in text


# an SOI MOSFET has five to seven nodes before its model (tests/bsim3soifd/ring51.cir:
# 'mn1 ss ss ss ss ss n1 …'); the sixth token is a node, not a model to define
SOI = """soi mosfet
vdd dd 0 1.5
mn1 dd dd 0 0 0 n1 w=4u l=0.15u
.model n1 nmos level=55 tox=4.5e-9
.tran 1n 10n
.end
"""


def test_soi_mosfet_is_refused_by_its_level_not_as_a_missing_model():
    with pytest.raises(spice.NetlistError) as info:
        spice.read(SOI)
    text = str(info.value)
    assert "line 3: model 'n1' (line 4): NMOS level 55 is not supported" in text
    assert "is not defined" not in text


def test_five_nodes_before_a_four_node_mosfet_model_are_refused_by_count():
    with pytest.raises(spice.NetlistError) as info:
        spice.read(SOI.replace("level=55 tox=4.5e-9", "level=1"))
    assert "element 'mn1' has 5 nodes before its model 'n1'; a MOSFET of levels 1" in str(
        info.value
    )


# 'DC' with no value (examples/transient-noise/rts-1.cir: 'VW1of 21 0 DC  trnoise(…)'):
# ngspice 39 reads it as DC 0; the transient follows the function
DC_NO_VALUE = """dc keyword without a value
v1 1 0 DC  pulse(1 2 1m 1m 1m 1 2)
v2 2 0 DC
v3 3 0 DC ac 1
r1 1 0 1
r2 2 0 1
r3 3 0 1
.tran 1m 4m
.end
"""


def test_dc_keyword_without_a_value_is_zero_as_in_ngspice():
    result = spice.run(DC_NO_VALUE)
    v1, v2, v3 = (np.asarray(result.at([0.0, 4e-3])[f"v({n})"]) for n in "123")
    np.testing.assert_allclose(v1, [1.0, 2.0], rtol=1e-12)  # the PULSE at 0 and 4 ms
    assert np.all(v2 == 0.0) and np.all(v3 == 0.0)


@needs_ngspice
def test_dc_keyword_without_a_value_as_ngspice_reads_it():
    op = ng.operating_point(DC_NO_VALUE)  # the .op takes DC values: all three 0
    assert op["i(v1)"] == op["i(v2)"] == op["i(v3)"] == 0.0


def test_temper_is_the_circuit_temperature_in_b_expressions():
    # ngspice 39: 'b1 1 0 v=temper*2' on 1 ohm, .op: v(1) = 54; with '.temp 91', 182
    assert evaluate_constant("temper*2", {}) == 54.0
    netlist = spice.read("t\nb1 1 0 v=temper*2\nr1 1 0 1\n.temp 91\n.tran 1m 2m\n.end\n")
    assert spice.operating_point(netlist).voltages["1"] == pytest.approx(182.0, rel=1e-12)


def test_unsupported_models_are_refused_for_what_they_are_not_for_their_words():
    # ngspice's examples/cider/diode/diotran.cir: a CIDER diode whose card holds words
    # (concmod=ct) was refused as "unknown parameter 'ct'"; examples/Monte_Carlo/MC_ring.sp:
    # a BSIM3 card with version=3.3.0 as "cannot parse expression '3.3.0'" (BSIM3 is read
    # since 2026-11-30: its VERSION word is read as the model's revision; BSIM4's is refused)
    cider = "t\nv1 1 0 1\nd1 1 0 m_pn area=100\n.model m_pn numd level=1\n+ options defa=1p\n"
    cider += "+ doping unif n.type conc=1e16\n+ models concmod=ct\n.tran 1n 10n\n.end\n"
    with pytest.raises(spice.NetlistError) as err:
        spice.read(cider)
    assert "model 'm_pn' (line 4) is a NUMD (CIDER's numerical device simulation" in str(err.value)
    bsim = "t\nv1 1 0 1\nm1 1 1 0 0 n1 w=1u l=1u\n.model n1 nmos level=8 version=3.3.0\n"
    bsim += ".tran 1n 10n\n.end\n"
    assert type(spice.read(bsim).circuit.parts[-1]).__name__ == "ChargePortPart"
    bsim4 = bsim.replace("level=8 version=3.3.0", "level=14 version=4.8.2")
    with pytest.raises(spice.NetlistError, match=r"NMOS level 14 \(BSIM4v4\.8\.2\) is not supp"):
        spice.read(bsim4)


def test_a_bjt_of_another_level_is_refused_by_its_level_not_its_parameters():
    # ngspice's examples/vbic/DFF_Y_ECL.sp was refused for VBIC's RCI, "not known"
    deck = "t\nv1 c 0 5\nv2 b 0 0.7\nq1 c b 0 nv\n.model nv npn(level=4 rci=10 is=1e-16)\n"
    with pytest.raises(spice.NetlistError, match=r"LEVEL=4 \(VBIC\); only level 1 is supp"):
        spice.read(deck + ".tran 1n 10n\n.end\n")
