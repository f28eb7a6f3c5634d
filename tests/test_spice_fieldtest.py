"""Netlist forms met in the held-out field test (docs/circuits.md, "A held-out field
test (2026-11-30)"): each a minimal deck of the syntax, checked against ngspice 39's
reading of the same text (its ``.op``) where ngspice is installed, and against the value
its manual defines."""

from __future__ import annotations

import pytest

import _ngspice as ng
from diracvi import spice

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
