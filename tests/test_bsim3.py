"""BSIM3v3 (ngspice's ``bsim3`` at VERSION 3.3.0 and ``bsim3v32`` at 3.2.x, LEVEL 8 or 49):
its static currents against ngspice's ``.dc`` sweeps in every region, both polarities,
the corpus deck's 180 nm cards and cards that turn on the other branches (mobMod 2 and 3,
RDSW with A1/A2, poly depletion, the substrate current, binning in both units); its
terminal charges (capMod 2 and 3, the three partitions, overlaps with CGSL/CGDL, the
junction charges) against ngspice's own ``@m[qg]``, ``[qb]``, ``[qd]``; a CMOS inverter's
transient; the refusals; gradients in card parameters."""

from __future__ import annotations

import itertools
import re
import subprocess
import tempfile
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import _ngspice as ng
import diracvi as dv
import test_mosfet_level6 as level6
from diracvi import components as cp
from diracvi import spice
from test_mosfet_level6 import _excess, needs_ngspice, terminal_currents

NAND = Path(__file__).parent / "data" / "netlists" / "es_cmos_nand"


def _card(lib: str) -> str:
    """The parameters of the corpus deck's ``.model`` card in ``lib`` (continuation lines
    joined; LEVEL dropped, the sweep deck sets it), as written: the PMOS card's stray
    ``+`` inside a line stays, which ngspice ignores (with a warning) and diracvi notes."""
    text = re.sub(r"\n\+", " ", (NAND / lib).read_text())
    body = re.search(r"\((.*)\)", text, re.S).group(1)
    return " ".join(body.split()).replace("LEVEL=8 ", "")


CMOSN, CMOSP = _card("NMOS-180nm.lib"), _card("PMOS-180nm.lib")
# the branches the 180 nm cards leave off: mobMod 2, RDSW with A1 > 0 and A2 < 1 (V_dsat's
# general root), PRWG/PRWB, poly depletion (NGATE), the substrate current, KETA, DWG/DWB,
# PVAG, PDIBLCB, CDSCD, CIT, B0/B1, AGS; K1/K2 from GAMMA1/GAMMA2/VBX (mobMod 3, A1 < 0);
# BINUNIT 2 with LINT/WINT/LL/WW, XL/XW
FULL = ("MOBMOD=2 TOX=8e-9 NCH=3e17 NSUB=1e17 VTH0=0.5 RDSW=300 A1=0.1 A2=0.8 PRWG=0.1 "
        "PRWB=-0.05 NGATE=3e19 ALPHA0=1e-6 BETA0=20 KETA=-0.05 DWG=-5e-9 DWB=4e-9 PVAG=0.5 "
        "PDIBLCB=-0.2 CDSCD=1e-4 CIT=1e-4 B0=1e-7 B1=1e-8 AGS=0.2")  # fmt: skip
GAMMAS = ("MOBMOD=3 TOX=5e-9 GAMMA1=0.6 GAMMA2=0.4 VBX=-1.5 XT=1e-7 K3=20 K3B=1 W0=1e-6 "
          "DVT0W=0.5 DVT1W=4e6 DVT2W=-0.02 A1=-0.01 A2=0.9 RDSW=200 LVTH0=0.01 WU0=1e-3 "
          "PUA=1e-12 VERSION=3.2.4")  # fmt: skip
BINUNIT2 = ("K1=0.6 TOX=6e-9 U0=120 UA=1e-9 UB=1e-18 UC=-1e-10 ETA0=0.1 ETAB=-0.1 "
            "LINT=2e-8 WINT=1e-8 LL=1e-15 LLN=1.2 WW=-1e-15 XL=1e-8 XW=-1e-8 BINUNIT=2 "
            "LKETA=1e-8")  # fmt: skip
NO_RSH = "NRD=0 NRS=0"  # the 180 nm cards' RSH as series resistors: not in a bare sweep
SLOW = pytest.mark.slow
# (kind, level, card, instance, V_BS)
CARDS = [
    ("NMOS", 8, CMOSN, f"L=0.5u W=1u {NO_RSH}", -0.5),
    ("PMOS", 8, CMOSP, f"L=0.5u W=2.5u {NO_RSH}", -0.5),
    ("NMOS", 49, FULL, "L=0.35u W=3u", -0.5),
    pytest.param("NMOS", 49, "", "", -1.0, marks=SLOW),  # ngspice's defaults
    pytest.param("PMOS", 49, "", "L=1u W=10u M=2", 0.3, marks=SLOW),  # M: every stamp ×2
    pytest.param("NMOS", 8, GAMMAS, "L=0.25u W=2u", 0.3, marks=SLOW),
    pytest.param("PMOS", 49, BINUNIT2, "L=0.4u W=4u", -0.3, marks=SLOW),
]  # fmt: skip


def _sweep(kind, level, card, instance, vb):
    return level6._sweep(kind, card, instance, vb, level6.sweep_deck(level))


@needs_ngspice
@pytest.mark.parametrize(("kind", "level", "card", "instance", "vb"), CARDS)
def test_static_currents_are_ngspices_in_every_region(kind, level, card, instance, vb):
    """Drain and bulk currents over a (V_DS, V_GS) grid at a reverse or forward V_BS —
    subthreshold, linear, saturation, the inverse mode — equal ngspice's ``.dc`` to 1e-9
    relative or 1e-12 A (measured: 6e-11 relative at worst, most cards 1e-14)."""
    out, part = _sweep(kind, level, card, instance, vb)
    mine = terminal_currents(part, out["v(g)"], out["v(d)"], out["v(b)"])
    assert _excess(mine, out) <= 0.0
    s = -1.0 if kind == "PMOS" else 1.0
    i_d = s * mine[0]
    assert np.count_nonzero(i_d > 1e-6) >= 100 and np.count_nonzero(i_d < -1e-6) >= 10
    assert np.count_nonzero((np.abs(i_d) < 1e-9) & (np.abs(i_d) > 1e-16)) >= 10  # subthreshold


@needs_ngspice
@SLOW  # a compiled sweep per parameter
def test_every_term_of_the_180nm_card_moves_the_currents():
    """The NMOS sweep above with one card parameter at a time set to ngspice's default
    (each a term of V_th, n, V_gsteff, μ, A_bulk, V_dsat, R_ds, V_A or the binning)
    misses ngspice's currents of the full card by far more than the 1e-9 tolerance: the
    comparison sees each term. (PSCBE1/PSCBE2 are not among them: at this card's
    PSCBE1 = 8e10 V/m the substrate-current-induced body effect stays off, V_ASCBE above
    10³⁰ V; the card's CDSC and DELTA are ngspice's defaults.)"""
    out, _ = _sweep("NMOS", 8, CMOSN, f"L=0.5u W=1u {NO_RSH}", -0.5)
    for name in ("PCLM", "PDIBLC2", "PVAG", "ETA0", "DVT0", "K3", "NLX", "UA", "UB",
                 "UC", "RDSW", "PRWG", "NFACTOR", "VOFF", "A0", "AGS", "KETA", "VSAT",
                 "PVTH0", "PU0", "LKETA", "WINT"):  # fmt: skip
        card = re.sub(rf"\b{name}=\S+", "", CMOSN)
        assert card != CMOSN, name
        net = level6.sweep_deck(8).format(kind="NMOS", card=card, instance=f"L=0.5u W=1u {NO_RSH}",
                                          vb=-0.5)  # fmt: skip
        part = ng.netlist_part(net, "m1")
        mine = terminal_currents(part, out["v(g)"], out["v(d)"], out["v(b)"])
        worst = np.max(np.abs(mine[0] + out["i(vd)"]) / (np.abs(out["i(vd)"]) + 1e-9))
        assert worst > 1e-6, (name, worst)  # a thousand times the tolerance


def _charges_deck(model, instance, biases, card):
    lines = ["charges", card]
    for k, (vg, vd, vb) in enumerate(biases):
        lines += [f"vg{k} g{k} 0 {vg}", f"vd{k} d{k} 0 {vd}", f"vb{k} b{k} 0 {vb}",
                  f"m{k} d{k} g{k} 0 b{k} {model} {instance}"]  # fmt: skip
    return "\n".join([*lines, ".tran 1p 2p", ".end"]) + "\n"


def _ngspice_charges(net, n):
    """ngspice's terminal charges ``@m[qg]``, ``[qb]``, ``[qd]`` (NMOS-oriented: its
    state, gate with overlaps, bulk and drain with their junctions) of ``m0 … m{n−1}``
    after a 2 ps transient at constant bias."""
    body = net.rpartition(".end")[0]
    probes = " ".join(f"@m{k}[qg] @m{k}[qb] @m{k}[qd]" for k in range(n))
    deck = body + f".control\nset numdgt=15\nrun\nprint {probes}\n.endc\n.end\n"
    with tempfile.TemporaryDirectory() as tmp:
        Path(tmp, "d.cir").write_text(deck)
        out = subprocess.run(
            ["ngspice", "-b", "d.cir"], cwd=tmp, capture_output=True, text=True, timeout=120
        ).stdout
    found = {
        (int(k), q): float(x) for k, q, x in re.findall(r"@m(\d+)\[(q[gbd])\]\s*=\s*(\S+)", out)
    }
    return np.array([[found[(k, q)] for q in ("qg", "qb", "qd")] for k in range(n)])


def _part_charges(parts, biases):
    """Each part's ``(Q_G, Q_B, Q_D)`` from its charge port at the true bias
    ``(V_GS, V_DS, V_BS)``: the gate line's, the two bulk lines' sum, the channel's less
    the drain junction's."""
    out = []
    for part, (vg, vd, vb) in zip(parts, biases, strict=True):
        idx = {c: j for j, c in enumerate(part.coords)}
        v = jnp.zeros(len(part.coords)).at[idx["wg"]].set(vg).at[idx["w"]].set(vd)
        v = v.at[idx["wbs"]].set(vb).at[idx["wbd"]].set(vb - vd)
        q = part.charge(jnp.zeros(len(part.coords)), v)
        out.append([q[idx["wg"]], q[idx["wbs"]] + q[idx["wbd"]], q[idx["w"]] - q[idx["wbd"]]])
    return np.array(out)


LIBS = f".include {NAND / 'NMOS-180nm.lib'}\n.include {NAND / 'PMOS-180nm.lib'}"
JUNCTIONS = "AD=1p AS=1p PD=3u PS=3u"
# (kind, model, instance, card lines)
CHARGE_CARDS = [
    ("n", "CMOSN", f"W=1u L=0.18u {NO_RSH} {JUNCTIONS}", LIBS),  # capMod 2, 50/50, v3.2
    ("p", "CMOSP", f"W=1u L=0.18u {NO_RSH} {JUNCTIONS}", LIBS),
    # capMod 3 (the default), 40/60, CGSL/CGDL, DLC, gate-side walls, poly depletion
    ("n", "mm", "W=2u L=0.35u AD=1p AS=2p PD=1u PS=6u",
     ".model mm nmos (level=49 tox=6e-9 capmod=3 xpart=0 cgsl=1e-10 cgdl=2e-10 ckappa=0.8 "
     "dlc=2e-8 cjswg=4e-10 mjswg=0.4 pbswg=0.9 ngate=5e19 rdsw=100)"),
    # capMod 2, 0/100, VERSION 3.2.2, K1/K2 given
    ("p", "mm", "W=2u L=0.35u AD=1p AS=2p PD=1u PS=6u",
     ".model mm pmos (level=49 tox=6e-9 capmod=2 xpart=1 cgsl=1e-10 ckappa=0.8 "
     "version=3.2.2 k1=0.5 k2=0.01)"),
]  # fmt: skip


@needs_ngspice
@pytest.mark.parametrize(("kind", "model", "instance", "card"), CHARGE_CARDS)
def test_terminal_charges_are_ngspices(kind, model, instance, card):
    """Gate, bulk and drain charges at 90 biases (accumulation to strong inversion, both
    modes, the bulk reverse and forward) equal ngspice's to 1e-9 of the largest
    (measured: 1e-15)."""
    s = 1.0 if kind == "n" else -1.0
    grid = itertools.product([-1.0, 0.0, 0.3, 0.6, 1.0, 1.8], [-0.5, 0.0, 0.05, 0.4, 1.8],
                             [-1.0, 0.0, 0.2])  # fmt: skip
    biases = [(s * g, s * d, s * b) for g, d, b in grid]
    net = _charges_deck(model, instance, biases, card)
    ref = s * _ngspice_charges(net, len(biases))
    parts = {p.name: p for p in spice.read(net).circuit.parts}
    mine = _part_charges([parts[f"m{k}"] for k in range(len(biases))], biases)
    scale = np.max(np.abs(ref))
    assert np.max(np.abs(mine - ref)) <= 1e-9 * scale
    assert scale > 1e-15


INVERTER = f"""bsim3 inverter
{LIBS}
vdd vdd 0 1.8
vin g 0 pulse(0 1.8 0.1n 0.2n 0.2n 1n 2.4n)
mp out g vdd vdd CMOSP W=2.5u L=0.18u {JUNCTIONS}
mn out g 0 0 CMOSN W=1u L=0.18u AD=0.5p AS=0.5p PD=2u PS=2u
cl out 0 5f
.tran 5p 1.2n
.end
"""


@needs_ngspice
def _fixed_step_error(netlist, dt, signal="v(out)"):
    """``max |diracvi − ngspice| / peak`` of ``signal``: diracvi's midpoint run at the fixed
    step ``dt`` (Newton with a fresh Jacobian each iteration) against a fine ngspice run
    (TMAX = TSTOP/20000, tolerances far below the defaults), read at ngspice's points."""
    read = spice.read(netlist)
    fine = ".options reltol=1e-6 abstol=1e-14 vntol=1e-10 chgtol=1e-17"
    t, ref = ng.ngspice(netlist, (signal,), tmax=read.stop / 20000, options=fine)
    result = spice.run(read, dt=dt, solver=dv.NewtonSolver(reuse_jacobian=False))
    mine = np.interp(t, result.time, result[signal])
    return float(np.max(np.abs(mine - ref[signal])) / np.max(np.abs(ref[signal])))


@SLOW  # a fine ngspice run and a 1200-step diracvi transient
def test_cmos_inverter_transient_is_ngspices():
    """The 180 nm cards' inverter (capMod 2 charges, junction charges, RSH's series
    resistors) through a rising and a falling edge, midpoint at a fixed 1 ps: ``v(out)``
    within 1e-3 of its peak of a fine ngspice run."""
    assert _fixed_step_error(INVERTER, 1e-12) <= 1e-3


def test_bsim3_cards_refuse_what_is_not_built_and_note_what_ngspice_ignores():
    base = "t\nvd d 0 1\nvg g 0 1\nm1 d g 0 0 mm {}\n.model mm NMOS (LEVEL=49 {})\n.end\n"
    read = spice.read(base.format("", "KF=1e-25 NOIA=1e20 TOX=5e-9 VTH0=0.45"))
    assert "KF ignored" in " ".join(read.notes) and "NOIA ignored" in " ".join(read.notes)
    # the card's TOX and VTH0 read, ngspice's L = W = 5 µm: the device built directly
    part = read.circuit.parts[-1]
    direct = cp.BSIM3("nmos", w=5e-6, l=5e-6, name="m1", model={"tox": 5e-9, "vth0": 0.45})
    q, v = np.zeros(len(part.coords)), np.linspace(-1.0, 2.0, len(part.coords))
    assert np.array_equal(part.force(q, v), direct.force(q, v))
    assert np.array_equal(part.charge(q, v), direct.charge(q, v))
    card = r"line 4: model 'mm' \(line 5\): "
    hot = r"BSIM3 has no temperature update in diracvi yet; the device would run at 27 °C"
    for bad, match in (("CAPMOD=1", card + r"NMOS BSIM3 CAPMOD=1 is not supported"),
                       ("CAPMOD=0", card + r"NMOS BSIM3 CAPMOD=0 is not supported"),
                       ("NQSMOD=1", card + r"NMOS BSIM3 NQSMOD=1 is not supported"),
                       ("ACM=2", card + r"NMOS BSIM3 ACM=2 is not supported"),
                       ("VERSION=3.1", card + r"BSIM3 VERSION=3.1 is not supported"),
                       ("LAMBDA=0.02", card + r"parameter 'lambda' is not a BSIM3"),
                       ("TNOM=50", hot + r" with the card's TNOM 50 °C")):  # fmt: skip
        with pytest.raises(spice.NetlistError, match=match):
            spice.read(base.format("", bad))
    with pytest.raises(spice.NetlistError, match=r"parameter GEO is not supported on BSIM3"):
        spice.read(base.format("GEO=1", ""))
    with pytest.raises(spice.NetlistError, match=r"effective channel L_eff = -2e-08 m"):
        spice.read(base.format("L=0.1u", "LINT=6e-8"))
    # a device at its card's TNOM runs (the model is evaluated at TNOM)
    spice.read(base.format("", "TNOM=50").replace(".end", ".options temp=50\n.end"))


@pytest.mark.slow  # a compiled gradient per parameter
def test_gradients_reach_the_card_parameters():
    """``jax.grad`` of the drain current in card parameters (traced values in the
    ``model`` dict) equals central differences, in saturation and the linear region."""
    base = {"tox": 4.1e-9, "nch": 2.35e17, "vth0": 0.38, "k1": 0.58, "k2": 4.8e-3,
            "u0": 280.0, "ua": -1.2e-9, "ub": 2.2e-18, "rdsw": 105.0, "pclm": 0.8,
            "eta0": 3e-3, "voff": -0.095, "pvag": 3.9e-3}  # fmt: skip

    def drain(x, arg, vgs, vds):
        part = cp.BSIM3("nmos", w=1e-6, l=0.5e-6, model=base | {arg: x}, name="m")
        idx = {c: j for j, c in enumerate(part.coords)}
        v = jnp.zeros(len(part.coords)).at[idx["wg"]].set(vgs).at[idx["w"]].set(vds)
        return -part.force(jnp.zeros(len(part.coords)), v)[idx["w"]]

    for arg in ("vth0", "u0", "rdsw", "pclm", "eta0"):
        x = base[arg]
        for vgs, vds in ((1.5, 1.8), (1.2, 0.1)):
            grad = float(jax.grad(drain)(x, arg, vgs, vds))
            h = 1e-5 * abs(x)
            diff = float(drain(x + h, arg, vgs, vds) - drain(x - h, arg, vgs, vds)) / (2 * h)
            assert grad == pytest.approx(diff, rel=1e-5), (arg, vgs, vds)
            assert grad != 0.0
