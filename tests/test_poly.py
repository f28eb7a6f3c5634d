"""SPICE2 polynomial controlled sources (E/F/G/H ``POLY(ND)``): SPICE2's coefficient order
by hand and as ngspice-39 computes it, operating points and transients against live
ngspice, exact gradients in the coefficients, and the errors (docs/circuits.md,
"Polynomial controlled sources")."""

from __future__ import annotations

import math

import jax
import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.spice._controlled import polynomial, spice2_exponents


# ------------------------------------------------------------------ the order
def test_exponent_order_is_spice2s_by_hand():
    """SPICE2's order (its user guide): p0, the linear terms, then x1², x1x2, …, x2², …"""
    assert spice2_exponents(1, 5) == [(0,), (1,), (2,), (3,), (4,)]
    assert spice2_exponents(2, 10) == [
        (0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2), (3, 0), (2, 1), (1, 2), (0, 3)
    ]  # fmt: skip
    assert spice2_exponents(3, 11) == [
        (0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1),
        (2, 0, 0), (1, 1, 0), (1, 0, 1), (0, 2, 0), (0, 1, 1), (0, 0, 2),
        (3, 0, 0),
    ]  # fmt: skip
    # every monomial of degree ≤ 4 in 3 variables once: C(3+4, 4) = 35 of them
    e = spice2_exponents(3, 35)
    assert len(set(e)) == 35 and max(sum(x) for x in e) == 4


def test_polynomial_is_the_sum_of_its_monomials():
    p = [0.5, 2.0, -1.0, 3.0, 0.25, -4.0, 1.5]
    x = np.array([1.3, -0.7])
    exact = 0.5 + 2 * 1.3 - 1 * -0.7 + 3 * 1.3**2 + 0.25 * 1.3 * -0.7 - 4 * 0.49 + 1.5 * 1.3**3
    assert float(polynomial(p, 2)(x)) == pytest.approx(exact, rel=1e-15)
    # at x = 0 its gradient is the linear coefficients (no 0·x⁻¹ of an x**0 term)
    g = jax.grad(lambda x: polynomial(p, 2)(x))(np.zeros(2))
    assert np.array_equal(np.asarray(g), [2.0, -1.0])


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_exponent_order_is_what_ngspice_computes():
    """One E source per coefficient index k ≤ 34 (unit p_k, the others 0) at
    (x1, x2, x3) = (2, 3, 5): ngspice's value 2^a 3^b 5^c names its monomial's exponents
    (prime factors), which must be ours; diracvi's operating point gives the same values."""
    lines = ["poly order", "V1 1 0 2", "V2 2 0 3", "V3 3 0 5"]
    for k in range(35):
        p = ["0"] * 35
        p[k] = "1"
        lines += [f"E{k} n{k} 0 POLY(3) 1 0 2 0 3 0 {' '.join(p[: k + 1])}", f"R{k} n{k} 0 1"]
    deck = "\n".join([*lines, ".tran 1u 1m", ".end", ""])
    ref = ng.operating_point(deck)
    ours = spice.operating_point(deck)
    for k, e in enumerate(spice2_exponents(3, 35)):
        value = ref[f"v(n{k})"]
        found = []
        for prime in (2, 3, 5):
            n = 0
            while round(value) % prime == 0 and value > 1:
                value /= prime
                n += 1
            found.append(n)
        assert value == 1.0 and tuple(found) == e, (k, ref[f"v(n{k})"])
        assert ours[f"v(n{k})"] == ref[f"v(n{k})"] == 2 ** e[0] * 3 ** e[1] * 5 ** e[2]


# ------------------------------------------------------------ against ngspice
#: every form, ND = 1, 2, 3, nonlinear coefficients, the POLY-less one-dimensional form,
#: a single coefficient (p0), IC= (read, not needed: ngspice-39 refuses
#: it, so the reference deck drops it) and a self-controlled G whose node solves a
#: quadratic: 1 mA = v/1k + 1m·v + 1m·v², v = √2 − 1
OP_DECK = """POLY forms against ngspice
V1 1 0 DC 0.7
V2 2 0 DC -0.4
V3 3 0 DC 1.3
R1 1 0 1k
R2 2 0 1k
R3 3 0 1k
Vs1 1 s1 0
Rs1 s1 0 1k
E1 e 0 POLY(2) 1 0 2 0 0.1 1.5 -2 0.3 0.7 -0.25
Vs2 e s2 0
Rs2 s2 0 2k
E2 e2 0 POLY(3) 1 0 2 0 3 0 0.2 1 -1 0.5 0.1 0.2 0.3 -0.4 0.5 0.6 -0.7 0.11 IC=0.1,0.2,0.3
Re2 e2 0 1k
E3 e3 0 2 0 0 1 0.5 -0.25
Re3 e3 0 1k
E4 e4 0 POLY(1) 1 0 0.5
Re4 e4 0 1k
G1 g 0 POLY(3) 1 0 2 0 e 0 1m 2m -1m 0.5m 0.1m 0.2m -0.3m 0.4m 0.05m 0.06m 0.01m
Rg g 0 1k
G2 g2 0 POLY(1) 3 0 0 1m 1m
Rg2 g2 0 1k
I1 0 n 1m
G3 n 0 POLY(1) n 0 0 1m 1m
Rn n 0 1k
F1 f 0 POLY(2) Vs1 Vs2 0 0.5 2 100 -50 30
Rf f 0 1k
F2 f2 0 Vs1 1e-4 1 1000
Rf2 f2 0 1k
H1 h 0 POLY(1) Vs2 0.2 1k 1e5
Rh h 0 1k
H2 h2 0 POLY(2) Vs1 Vs2 0 1k -500 1e5 2e5 -1e5 1e7
Rh2 h2 0 1k
.tran 1u 1m
.end
"""


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_operating_point_of_every_form_is_ngspices():
    ref = ng.operating_point(OP_DECK.replace(" IC=0.1,0.2,0.3", ""))
    ours = spice.operating_point(OP_DECK)
    nodes = ("e", "e2", "e3", "e4", "g", "g2", "n", "f", "f2", "h", "h2")
    for node in nodes:
        scale = max(abs(ref[f"v({node})"]), 1e-3)
        assert abs(ours[f"v({node})"] - ref[f"v({node})"]) <= 1e-10 * scale, node
        assert abs(ref[f"v({node})"]) > 1e-3, node  # each output is driven
    assert ours["v(n)"] == pytest.approx(math.sqrt(2) - 1, rel=1e-12)
    assert ours["v(e4)"] == pytest.approx(0.5, rel=1e-15)  # a single coefficient is p0
    notes = " ".join(spice.read(OP_DECK).notes)
    assert "E4: a single POLY coefficient is p0" in notes and "E2: IC=" in notes


#: E of two voltages into an RC, H of a current into an RL, G of a capacitor voltage into it
TRAN_DECK = """POLY sources in a transient
V1 1 0 SIN(0 1 1k)
V2 2 0 SIN(0.3 0.5 3k)
R1 1 0 1k
R2 2 0 1k
E1 e 0 POLY(2) 1 0 2 0 0 1 0.5 0.3 -0.6 0.2 0 0.1
Vs e a 0
R3 a b 1k
C3 b 0 100n
H1 h 0 POLY(1) Vs 0 2k 5e5
R4 h c 100
L4 c 0 10m
G1 0 d POLY(2) b 0 d 0 0 1m -2m 0.5m 0 -1m
C5 d 0 1u
R5 d 0 10k
.tran 1u 2m uic
.end
"""


@pytest.mark.slow  # a simulation (> 3 s with its compilation)
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_transient_agrees_with_ngspice():
    """Against a fine ngspice run (max step TSTOP/40000) at its own time points, t > 0:
    ≤ 1e-3 of each probe's peak (midpoint at the deck's fixed 1 µs step)."""
    probes = ("v(e)", "v(b)", "v(h)", "i(l4)", "v(d)")
    t, ref = ng.ngspice(TRAN_DECK, probes, tmax=2e-3 / 40000)
    result = spice.run(TRAN_DECK, dt=1e-6)
    for probe in probes:
        mine = np.interp(t, result.time, result[probe])
        peak = np.max(np.abs(ref[probe]))
        err = np.max(np.abs(mine - ref[probe])[t > 0]) / peak
        assert err <= 1e-3, (probe, err)
        assert peak > 1e-4, probe


def test_m_multiplies_g_and_f_and_is_ignored_on_e_and_h():
    """ngspice's rule since 2025-11 (``spice2poly``'s ``m``; ngspice-39 refuses ``M=`` on a
    POLY line, "Bad real value"): G and F with M=3 are G and F with their coefficients
    times 3; E and H ignore it, with a note."""
    lines = ["m", "V1 1 0 0.7", "R1 1 0 1k", "Vs 1 s 0", "Rs s 0 1k"]
    for letter, ctl in (("G", "1 0"), ("F", "Vs"), ("E", "1 0"), ("H", "Vs")):
        coefs = "0.1m 1m 1m" if letter in "GF" else "0.1 1k 1e5"
        tripled = "0.3m 3m 3m" if letter in "GF" else coefs
        lines += [f"{letter}1 a{letter} 0 POLY(1) {ctl} {coefs} M=3", f"Ra{letter} a{letter} 0 1k"]
        lines += [f"{letter}2 b{letter} 0 POLY(1) {ctl} {tripled}", f"Rb{letter} b{letter} 0 1k"]
    deck = "\n".join([*lines, ".tran 1u 1m", ".end", ""])
    op = spice.operating_point(deck)
    for letter in "GFEH":
        assert op[f"v(a{letter})"] == pytest.approx(op[f"v(b{letter})"], rel=1e-14), letter
        assert abs(op[f"v(a{letter})"]) > 1e-3
    notes = " ".join(spice.read(deck).notes)
    assert "E1: M= is ignored" in notes and "H1: M= is ignored" in notes


# ------------------------------------------------------------------ gradients
GRAD_DECK = """POLY coefficients as parameters
.param p1=1 p3=0.5 p4=-2
V1 1 0 DC 0.8
V2 2 0 SIN(0 1 1k)
R1 1 0 1k
R2 2 0 1k
E1 out 0 POLY(2) 1 0 2 0 0.1 {p1} 0 {p3} {p4}
R3 out 0 1k
.tran 10u 1.1m uic
.end
"""


@pytest.mark.slow  # three runs with their compilation
def test_gradient_in_a_coefficient_is_its_monomial():
    """The controls do not depend on the coefficients, so v(out) is affine in them and its
    derivative in p4 (the x1·x2 term) is the run whose coefficients are only p4 = 1 —
    exactly, to round-off."""
    grad = jax.grad(lambda c: spice.run(GRAD_DECK, dt=10e-6, params={"p4": c})["v(out)"][-1])(-2.0)
    unit = GRAD_DECK.replace("0.1 {p1} 0 {p3} {p4}", "0 0 0 0 1")
    monomial = spice.run(unit, dt=10e-6)["v(out)"][-1]
    assert abs(monomial) > 0.1  # x1·x2 ≈ 0.8·sin(2π·1.1): a real check
    assert abs(float(grad) - monomial) <= 1e-12 * abs(monomial)  # measured 1.4e-13


# ------------------------------------------------------------------ errors
@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("e1 3 0 POLY(0) 1 0 1", r"line 3: element 'e1': POLY\(0\) must have one positive"),
        ("g1 3 0 POLY(x) 1 0 1", r"line 3: element 'g1': POLY\(x\) must have one positive"),
        ("e1 3 0 POLY(2) 1 0 2 0", r"POLY\(2\) needs 2 node pairs \(4 fields\) and then at le"),
        ("f1 3 0 POLY(2) v1 r1 1 2", r"controlling elements \['r1'\] must be voltage sources"),
        ("h1 3 0 POLY(1) v1", r"POLY\(1\) needs 1 controlling voltage sources"),
        ("g1 3 0 POLY(1) 1 0 1 2 tc=1", r"unsupported parameters \['tc'\]"),
        ("e1 3 0 POLY(1) 1 0 {nope} 2", r"line 3: e1 POLY coefficient p0: .*nope"),
    ],
)
def test_netlist_errors_name_the_line_and_the_form(line, match):
    body = f"title\nv1 1 0 1\n{line}\nr1 1 2 1k\nr2 3 0 1k\nr3 2 0 1k\n.tran 1u 1m\n.end\n"
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(body)


def test_unknown_controls_are_named_all_at_once():
    body = (
        "title\nv1 1 0 1\nr1 1 0 1k\n"
        "e1 3 0 POLY(2) nowhere 0 1 elsewhere 0 1 2\n"
        "f1 4 0 POLY(2) v1 vnone 0 1 1\n"
        "r3 3 0 1k\nr4 4 0 1k\n.tran 1u 1m\n.end\n"
    )
    with pytest.raises(spice.NetlistError) as err:
        spice.read(body)
    text = str(err.value)
    assert "2 problems" in text
    assert "element 'e1': nodes ['elsewhere', 'nowhere'] are not in the circuit" in text
    assert "element 'f1': sources ['vnone'] are not elements of the circuit" in text
