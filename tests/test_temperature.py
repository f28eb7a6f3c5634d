"""Circuits away from 27 °C: the circuit temperature (``.temp``, ``.options temp=``/
``tnom=``, ``TEMPER``), the instance ``TEMP=``/``DTEMP=`` and each device's temperature
update, checked against ngspice 39's operating point of the same deck at −40, 0, 91 and
125 °C and with a TNOM other than 27 °C (model card and ``.options tnom``)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import pytest

import _ngspice as ng
from diracvi import spice

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

TEMPERATURES = (-40.0, 0.0, 91.0, 125.0)


def _assert_currents_are_ngspices(deck: str, sources, *, rel: float, abs: float = 0.0):
    """Each of ``sources``' currents at diracvi's operating point of ``deck`` is
    ngspice's (``ng.operating_point``) to ``rel`` (and ``abs`` amperes)."""
    ref = ng.operating_point(deck)
    op = spice.operating_point(spice.read(deck))
    for source in sources:
        want = ref[f"i({source.lower()})"]
        assert op.currents[source] == pytest.approx(want, rel=rel, abs=abs), source


# ------------------------------------------------------------ the circuit temperature
def _resistor(extra: str) -> str:
    return f"temperature rules\nV1 1 0 1\nR1 1 0 1k tc1=0.01\n{extra}\n.tran 1u 2u\n.end\n"


def _r1(netlist) -> float:
    return next(p for p in netlist.circuit.parts if p.name == "R1")


@pytest.mark.parametrize(
    ("extra", "temp"),
    [
        ("", 27.0),
        (".temp 91", 91.0),
        (".temp=91", 91.0),
        (".options temp=50", 50.0),
        # .temp wins over .options temp wherever it stands (ngspice's inp.c)
        (".options temp=50\n.temp 91", 91.0),
        (".temp 91\n.options temp=50", 91.0),
        (".temp 0\n.temp -40", -40.0),  # the last .temp line
        (".param t0=60\n.temp {t0+5}", 65.0),
    ],
)
def test_the_circuit_temperature_follows_ngspices_rules(extra, temp):
    netlist = spice.read(_resistor(extra))
    got = 1.0 / spice.operating_point(netlist).currents["V1"] * -1.0
    assert got == pytest.approx(1e3 * (1 + 0.01 * (temp - 27.0)), rel=1e-12)


def test_tc_on_the_resistor_line_is_tc1_as_ngspice_reads_it():
    # ngspice 39, 'R2 2 0 1k tc=0.01' at '.temp 47': i = 1/1200 A
    netlist = spice.read(_resistor(".temp 47").replace("tc1=0.01", "tc=0.01"))
    assert -spice.operating_point(netlist).currents["V1"] == pytest.approx(1 / 1200, rel=1e-12)


def test_several_temperatures_on_one_line_are_refused_naming_the_fix():
    with pytest.raises(spice.NetlistError, match=r"'.temp' with 2 values.*give one"):
        spice.read(_resistor(".temp 0 91"))
    with pytest.raises(spice.NetlistError, match=r"above −273.15"):
        spice.read(_resistor(".temp -300"))


def test_temper_is_the_circuit_temperature_in_params_values_and_b_sources():
    deck = """temper
V1 1 0 1
.param rr={1000*(1+0.01*(temper-27))}
R1 1 0 {rr}
B1 2 0 V=temper
R2 2 0 1
.temp 91
.tran 1u 2u
.end
"""
    netlist = spice.read(deck)
    op = spice.operating_point(netlist)
    assert op.voltages["2"] == pytest.approx(91.0, rel=1e-12)
    assert -op.currents["V1"] == pytest.approx(1.0 / 1640.0, rel=1e-12)
    assert "temper" not in netlist.params


@needs_ngspice
@pytest.mark.parametrize("temp", [-40.0, 125.0])
def test_the_resistor_forms_carry_ngspices_current_at_other_temperatures(temp):
    from test_resistor_model import AMMETERS, DECK

    deck = DECK.replace(".tran", f".temp {temp:g}\n.options tnom=50\n.tran")
    ref = ng.operating_point(deck)
    result = spice.run(deck)
    for label, ammeter in AMMETERS.items():
        mine = result[f"i({ammeter})"][-1]
        assert mine == pytest.approx(ref[f"i({ammeter})"], rel=1e-9), label


# ---------------------------------------------------------------------------- diode
DIODES = """diode temperatures
V1 a 0 0.75
R1 a b 10
D1 b 0 dr
V2 c 0 -9
R2 c d 1k
D2 d 0 dm
V3 e 0 0.6
D3 e 0 dm dtemp=15
V4 f 0 0.6
D4 f 0 dm temp=-10
V5 g 0 0.3
D5 g 0 dn
V6 h 0 -2
D6 h 0 dm
.model dm D(IS=2e-14 N=1.3 BV=6 IBV=1m TCV=2e-3 CJO=2p VJ=0.7 M=0.4 TM1=1e-3 TM2=2e-6
+ TT=1n TTT1=3e-3 TTT2=1e-5)
.model dr D(IS=1e-15 RS=3 TRS=4e-3 TRS2=1e-5)
.model dn D(IS=5e-9 N=1.05 EG=0.69 XTI=2 TNOM=50 CJO=10p VJ=0.5 M=0.5)
{setting}
.tran 1n 10n
.end
"""
#: the diodes whose junction sees its node voltage (no series resistance)
JUNCTIONS = {"D3": "e", "D4": "f", "D5": "g", "D6": "h"}
SETTINGS = [f".temp {t:g}" for t in TEMPERATURES] + [".options temp=60 tnom=35"]


def _capacitance(part, v):
    """``C(V) = d²Φ/dV²``: the junction's charge co-energy differentiated twice."""
    q = jnp.zeros(2)
    return float(jax.grad(jax.grad(lambda x: part.lagrangian(q, jnp.array([0.0, x]))))(v))


@needs_ngspice
@pytest.mark.parametrize("setting", SETTINGS)
def test_diodes_match_ngspice_away_from_27C(setting):
    """IS (EG, XTI, N), BV (TCV), RS (TRS, TRS2), VJ, CJO, M (TM1, TM2), TT (TTT1,
    TTT2), the instance's TEMP and DTEMP, a model TNOM and ``.options tnom``: the
    currents and the junction capacitance (depletion + TT·g_D) at the operating point."""
    deck = DIODES.format(setting=setting)
    ref = ng.operating_point(deck, [f"@{d.lower()}[cd]" for d in JUNCTIONS])
    netlist = spice.read(deck)
    op = spice.operating_point(netlist)
    for source in ("V1", "V2", "V3", "V4", "V5", "V6"):
        assert op.currents[source] == pytest.approx(ref[f"i({source.lower()})"], rel=1e-9, abs=0), (
            source
        )
    assert op.voltages["d"] == pytest.approx(ref["v(d)"], rel=1e-10)  # the breakdown knee
    parts = {p.name: p for p in netlist.circuit.parts}
    for name, node in JUNCTIONS.items():
        c = _capacitance(parts[name], op.voltages[node])
        # ngspice's TT·g_D has G_MIN in g_D (1e-12 S): TT·G_MIN ≲ 2e-21 F of 1e-12
        assert c == pytest.approx(ref[f"@{name.lower()}[cd]"], rel=1e-8, abs=0), name


def test_diode_temperature_levels_other_than_0_are_refused_by_name():
    for card in ("TLEV=1", "TLEVC=1"):
        deck = DIODES.format(setting=".temp 50").replace("M=0.4 ", f"M=0.4 {card} ")
        with pytest.raises(spice.NetlistError, match=card.split("=")[0] + "=1 is not supported"):
            spice.read(deck)


def test_tbv1_is_ignored_as_ngspice_39_does():
    deck = DIODES.format(setting=".temp 50").replace("TCV=2e-3", "TCV=2e-3 TBV1=-1e-3")
    netlist = spice.read(deck)
    assert any("TBV1 ignored (ngspice 39's diode does not have" in n for n in netlist.notes)
    plain = spice.operating_point(spice.read(DIODES.format(setting=".temp 50")))
    assert spice.operating_point(netlist).voltages["d"] == plain.voltages["d"]


def test_the_diode_temperature_update_is_differentiable():
    """``jax.grad`` of ``I_S(T)`` through the update equals its closed form
    ``dI_S/dT = I_S(T) (E_g/(N V_T(T) T) + X_TI/(N T))`` (from
    ``ln I_S = const + E_g q (1/T_nom − 1/T)/(N k) + (X_TI/N) ln T``)."""
    from diracvi.components._temperature import diode, thermal_voltage

    base = {"is": 1e-14, "n": 1.3, "eg": 1.11, "xti": 3.0, "m": 0.5, "tm1": 0.0,
            "tm2": 0.0, "vj": 0.8, "cjo": 1e-12, "bv": None, "tcv": 0.0, "rs": 0.0,
            "trs": 0.0, "trs2": 0.0, "tt": 0.0, "ttt1": 0.0, "ttt2": 0.0, "tlev": 0.0,
            "tlevc": 0.0}  # fmt: skip

    def i_s(t):
        return diode(base, t, 300.15, name="d")["is"]

    t = 350.0
    closed = i_s(t) * (1.11 / (1.3 * thermal_voltage(t) * t) + 3.0 / (1.3 * t))
    assert float(jax.grad(i_s)(t)) == pytest.approx(float(closed), rel=1e-12)


@pytest.mark.parametrize("setting", [".temp 50", ".options tnom=40", " temp=60"])
def test_a_device_without_a_temperature_update_is_refused_away_from_tnom(setting):
    """BSIM3, the one device left without its temperature update, names it and the fix."""
    line = "M1 d g 0 0 nb L=1u W=10u" + (setting if setting.startswith(" ") else "")
    model = ".model nb NMOS LEVEL=8 VERSION=3.3.0"
    extra = "" if setting.startswith(" ") else setting
    deck = f"t\nVD d 0 1\nVG g 0 1\n{line}\n{model}\n{extra}\n.tran 1n 10n\n.end\n"
    with pytest.raises(spice.NetlistError, match=r"BSIM3 has no temperature update"):
        spice.read(deck)
    spice.read(deck.replace(setting, ""))  # at its TNOM it reads


# ---------------------------------------------------------------------------- BJT
BJTS = """bjt temperatures
VCC vcc 0 5
VB1 vb1 0 0.72
RB1 vb1 b1 2k
RC1 vcc c1 1k
Q1 c1 b1 0 qn
VB2 vb2 0 4.25
RB2 vb2 b2 5k
RC2 c2 0 2k
Q2 c2 b2 vcc qp dtemp=10
VB3 vb3 0 0.2
Q3 c3 vb3 0 qn temp=-20
VC3 c3 0 -0.3
VB4 vb4 0 0.69
Q4 vcc vb4 e4 qt
RE4 e4 0 100
.model qn NPN(IS=1e-15 BF=120 BR=3 VAF=60 VAR=20 IKF=20m IKR=5m ISE=1e-13 NE=1.6 ISC=1e-13 NC=1.8
+ RB=50 RC=5 RE=1 XTB=1.5 XTI=3.2 EG=1.12 CJE=1p CJC=1p TNF1=1e-4 TVAF1=1e-3 TRB1=2e-3
+ TRM1=2e-3 TRE1=3e-3 TRC1=1e-3 TIKF1=-2e-3)
.model qp PNP(IS=2e-15 BF=80 BR=2 VAF=40 ISE=5e-14 NE=1.5 RB=30 XTB=1.7 TBF1=2e-3 TNE1=1e-4 TNOM=40)
.model qt NPN(IS=3e-16 BF=200 XTB=2 EG=1.0 XTI=4 RE=2 TRE2=1e-5 TBR1=1e-3)
{setting}
.tran 1n 10n
.end
"""
BJT_SETTINGS = [*SETTINGS, ".options temp=-40 tnom=0"]


@needs_ngspice
@pytest.mark.parametrize("setting", BJT_SETTINGS)
def test_bjts_match_ngspice_away_from_27C(setting):
    """IS (EG, XTI), BF/BR (XTB; TBF1, TBR1), ISE/ISC (with NE, NC and XTB), the
    quadratic coefficients (TNF1, TNE1, TVAF1, TIKF1, TRB1 = TRM1, TRC1, TRE1, TRE2), an
    NPN and a PNP, the instance's TEMP and DTEMP, a model TNOM and ``.options tnom``:
    every source's current at the operating point."""
    deck = BJTS.format(setting=setting)
    _assert_currents_are_ngspices(deck, ("VCC", "VB1", "VB2", "VB3", "VC3", "VB4"), rel=1e-8)


def test_bjt_temperature_levels_and_unscaled_parameters_are_refused_by_name():
    for card, refusal in (
        ("TLEV=1", "TLEV=1 is not supported"),
        ("TLEVC=1", "TLEVC=1 is not supported"),
        ("TRM1=2e-3 ISS=1e-15", r"ISS at 50 °C \(TNOM 27 °C\): their temperature dep"),
        ("TRM1=2e-3 IRB=1e-3", r"IRB at 50 °C"),
    ):
        deck = BJTS.format(setting=".temp 50").replace("TRM1=2e-3", card)
        with pytest.raises(spice.NetlistError, match=refusal):
            spice.read(deck)


@needs_ngspice
def test_a_base_resistance_that_parts_from_rbm_with_temperature_matches_ngspice():
    # TRM1 = 0 against TRB1 = 2e-3: at 50 °C RB(T) ≠ RBM(T), ngspice's bias-dependent
    # base resistance RBM + (RB − RBM)/q_b (components/bjt.py)
    deck = BJTS.format(setting=".temp 50").replace("TRM1=2e-3", "TRM1=0")
    _assert_currents_are_ngspices(deck, ("VCC", "VB1", "VB2", "VB3", "VC3", "VB4"), rel=1e-8)


# ---------------------------------------------------------------------- MOSFET level 1
#: the MOSFET decks' first three stages: an NMOS with its drain load, a PMOS (DTEMP), and
#: an NMOS with a reverse-biased bulk (its junction's JS), each level's cards named nm, pm, np
MOS_STAGES = """VDD vdd 0 3
VG1 g1 0 1.6
RD1 vdd d1 2k
M1 d1 g1 0 0 nm L=2u W=20u
VG2 g2 0 1.2
RD2 d2 0 3k
M2 d2 g2 vdd vdd pm L=2u W=40u dtemp=15
VG3 g3 0 2
VB3 b3 0 0.45
M3 vdd g3 s3 b3 np L=1u W=10u AD=20p AS=20p
RS3 s3 0 1k
"""


MOSFETS = (
    "mos1 temperatures\n"
    + MOS_STAGES
    + """VG4 g4 0 1.5
M4 d4 g4 0 0 nm L=2u W=20u temp=-20
VD4 d4 0 0.2
.model nm NMOS(LEVEL=1 VTO=0.7 KP=50u GAMMA=0.5 PHI=0.65 LAMBDA=0.02 IS=1e-15 TNOM=40)
.model pm PMOS(LEVEL=1 TOX=20n NSUB=2e16 U0=250 LAMBDA=0.03)
.model np NMOS(LEVEL=1 TOX=15n NSUB=5e16 NSS=1e10 TPG=1 U0=500 JS=1e-4 CJ=1e-4 CJSW=1e-10 PB=0.9)
{setting}
.tran 1n 10n
.end
"""
)


@needs_ngspice
@pytest.mark.parametrize("setting", BJT_SETTINGS)
def test_level1_mosfets_match_ngspice_away_from_27C(setting):
    """KP (given, and from U0·C'ox), VTO through PHI (given, and from NSUB at TNOM), the
    bulk junction's JS (reverse-biased, its current ∝ JS(T)), an NMOS and a PMOS, the
    instance's TEMP and DTEMP, a model TNOM and ``.options tnom``: every source's current
    at the operating point."""
    deck = MOSFETS.format(setting=setting)
    _assert_currents_are_ngspices(deck, ("VDD", "VB3", "VD4"), rel=1e-9)


# ------------------------------------------------------------------ MOSFET levels 2 and 3
LEVELS23 = (
    "mos{level} temperatures\n"
    + MOS_STAGES
    + """VG4 g4 0 0.55
M4 d4 g4 0 0 nw L=3u W=30u
VD4 d4 0 0.8
.model nm NMOS(LEVEL={level} VTO=0.7 KP=50u GAMMA=0.5 PHI=0.65 LAMBDA=0.02 IS=1e-15 TNOM=40
+ VMAX=1e5 TOX=20n)
.model pm PMOS(LEVEL={level} TOX=20n NSUB=2e16 U0=250 VMAX=5e4)
.model np NMOS(LEVEL={level} TOX=15n NSUB=5e16 NSS=1e10 TPG=1 U0=500 JS=1e-4 CJ=1e-4
+ CJSW=1e-10 PB=0.9 XJ=0.2u)
.model nw NMOS(LEVEL={level} VTO=0.6 TOX=20n NSUB=1e16 NFS=1e11 U0=400)
{setting}
.tran 1n 10n
.end
"""
)


# one case of each level in the default suite (~25 s each: a compiled operating point),
# the rest behind the slow marker
LEVEL23_CASES = [
    pytest.param(level, setting, marks=() if (level, setting) in DEFAULT23 else pytest.mark.slow)
    for DEFAULT23 in [{(2, ".options temp=60 tnom=35"), (3, ".options temp=-40 tnom=0")}]
    for level in (2, 3)
    for setting in BJT_SETTINGS
]


@needs_ngspice
@pytest.mark.parametrize(("level", "setting"), LEVEL23_CASES)
def test_level2_and_level3_mosfets_match_ngspice_away_from_27C(level, setting):
    """mos2temp's and mos3temp's update (level 1's, :func:`mos1`) with what the laws read
    at the device's temperature: KP and VTO through PHI (given, from NSUB at TNOM, n_i at
    TNOM for level 3), the reverse-biased bulk junction with JS (level 3's cubic reverse
    branch), level 3's U0 in velocity saturation (VMAX), weak inversion's V_T (NFS), a
    PMOS with DTEMP, a model TNOM and ``.options tnom``: each source's current at the
    operating point."""
    deck = LEVELS23.format(level=level, setting=setting)
    _assert_currents_are_ngspices(deck, ("VDD", "VB3", "VD4"), rel=1e-9)


LEVEL6 = (
    "mos6 temperatures\n"
    + MOS_STAGES
    + """.model nm NMOS(LEVEL=6 VTO=0.7 KC=50u NC=1.2 KV=1.5 NV=0.8 GAMMA=0.5
+ PHI=0.65 LAMBDA=0.02 IS=1e-15 TNOM=40)
.model pm PMOS(LEVEL=6 TOX=20n NSUB=2e16 U0=250 KV=2 NV=0.6 NC=1.1 LAMBDA0=0.03)
.model np NMOS(LEVEL=6 TOX=15n NSUB=5e16 NSS=1e10 TPG=1 U0=500 JS=1e-4 CJ=1e-4
+ CJSW=1e-10 PB=0.9 GAMMA1=0.1 SIGMA=0.02)
{setting}
.tran 1n 10n
.end
"""
)


@needs_ngspice
@pytest.mark.parametrize(
    "setting",
    [pytest.param(s, marks=() if s == ".temp 125" else pytest.mark.slow) for s in SETTINGS],
)
def test_level6_mosfets_match_ngspice_away_from_27C(setting):
    """mos6temp: level 1's update with KC (T/T_nom)^{−3/2} (KV unscaled), KC given and
    from U0·C'ox, VTO from NSUB at TNOM, the reverse-biased bulk junction's JS: each
    source's current at the operating point."""
    deck = LEVEL6.format(setting=setting)
    _assert_currents_are_ngspices(deck, ("VDD", "VB3"), rel=1e-9)


# ----------------------------------------------------------------------------- VDMOS
VDMOSES = """vdmos temperatures
VDD vdd 0 12
RL vdd d1 20
VG1 g1 0 4.2
M1 d1 g1 s1 nv M=2
RS1 s1 0 0.5
VD2 d2 0 -0.6
M2 d2 0 0 nv dtemp=20
VG3 g3 0 -3
RL3 d3 0 50
M3 d3 g3 vdd pv
VG4 g4 0 2.6
VD4 d4 0 1
M4 d4 g4 0 nw temp=60
.model nv VDMOS(VTO=2.5 KP=2 LAMBDA=0.01 RD=0.05 RS=0.02 RG=3 RB=0.01 IS=1e-12 N=1.1 CJO=1n
+ TCVTH=3m MU=-1.2 TRD1=4e-3 TRD2=1e-5 TRS1=2e-3 TRB1=5e-3 XTI=2.5 EG=1.2 TNOM=40)
.model pv VDMOS(PCHAN VTO=-2 KP=1.5 RD=0.1 RS=0.05 IS=2e-12 VTOTC=2m BEX=-1.8 TEXP0=1.2)
.model nw VDMOS(VTO=2.8 KP=1 KSUBTHRES=0.15 TKSUBTHRES1=2e-3 TKSUBTHRES2=1e-6)
{setting}
.tran 1u 10u
.end
"""


@needs_ngspice
@pytest.mark.parametrize(
    "setting",
    [pytest.param(s, marks=() if s == ".temp 125" else pytest.mark.slow) for s in BJT_SETTINGS],
)
def test_vdmos_match_ngspice_away_from_27C(setting):
    """vdmostemp: KP r^MU (BEX its other name), VTO by TCVTH (VTOTC), KSUBTHRES's
    polynomial, RD by TRD1/TRD2 or TEXP0, RS, RB, the body diode's IS with EG and XTI at
    N·V_T(T) (M2's, forward-biased) and its junction; NCHAN and PCHAN, M, TEMP, DTEMP, a
    model TNOM and ``.options tnom``: each source's current at the operating point, to
    1e-9 + 1e-11 A (the channel part's G_min leak, as at 27 °C)."""
    deck = VDMOSES.format(setting=setting)
    _assert_currents_are_ngspices(deck, ("VDD", "VD2", "VD4"), rel=1e-9, abs=1e-11)


# ------------------------------------------------------------------------------ JFET
JFETS = """jfet temperatures
VDD vdd 0 10
RD1 vdd d1 1k
J1 d1 0 s1 jn
RS1 s1 0 200
VG2 g2 0 0.55
RG2 g2 gg2 10k
VD2 d2 0 5
J2 d2 gg2 0 jn2 dtemp=20
VS3 s3 0 8
RD3 d3 0 1k
VG3 g3 0 8.8
J3 d3 g3 s3 jp temp=-10
RD4 vdd d4 500
VG4 g4 0 -0.4
J4 d4 g4 0 jb 2
.model jn NJF(VTO=-2 BETA=1.3m LAMBDA=0.02 IS=1e-14 B=0.8 PB=0.9 CGS=2p CGD=1p TCV=2.5m BEX=-1.5
+ TNOM=35)
.model jn2 NJF(VTO=-1.5 BETA=1m IS=1e-15 XTI=3.5 EG=1.2 VTOTC=-3m BETATCE=-0.5)
.model jp PJF(VTO=-1.8 BETA=0.8m LAMBDA=0.01 IS=2e-14 B=1.2 XTI=2)
.model jb NJF(VTO=-1.2 BETA=2m B=0.6 PB=0.7 TCV=1m)
{setting}
.tran 1n 10n
.end
"""
JFET_CASES = [
    pytest.param(setting, marks=() if setting in DEFAULT_JFET else pytest.mark.slow)
    for DEFAULT_JFET in [{".temp 125", ".options temp=-40 tnom=0"}]
    for setting in BJT_SETTINGS
]


@needs_ngspice
@pytest.mark.parametrize("setting", JFET_CASES)
def test_jfets_match_ngspice_away_from_27C(setting):
    """jfettemp's update: IS with EG (XTI only where given), VTO by TCV or VTOTC, BETA by
    BEX or BETATCE, PB and the doping tail's factor at the card's values (B ≠ 1), the
    gate junctions at V_T(T) (J2's forward-biased gate), an NJF and a PJF, the instance's
    TEMP, DTEMP and AREA, a model TNOM and ``.options tnom``: each source's current at
    the operating point (taking the tail's factor at the updated PB and VTO puts VDD's
    4.8e-3 off at 125 °C)."""
    deck = JFETS.format(setting=setting)
    _assert_currents_are_ngspices(deck, ("VDD", "VG2", "VD2", "VS3", "VG3", "VG4"), rel=1e-9)


def test_diode_terms_without_a_temperature_update_are_refused_away_from_tnom():
    # ISR, JSW, CJSW: ngspice 39 scales them with temperature (diotemp.c), diracvi not yet
    deck = DIODES.format(setting=".temp 50").replace("M=0.4 ", "M=0.4 ISR=1n ")
    with pytest.raises(spice.NetlistError, match=r"ISR at 50 °C \(TNOM 27 °C\): their temp"):
        spice.read(deck)
