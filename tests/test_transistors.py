"""Transistors: the level-1 MOSFET (Shichman–Hodges) and the Gummel–Poon BJT — their
currents against the closed forms in every region (independent NumPy formulas written
here from ngspice's manual), four circuits against live ngspice runs, gradients, and
the netlist lines with their errors (docs/circuits.md, "Transistors")."""

from __future__ import annotations

import re

import jax
import numpy as np
import pytest

import _ngspice as ng
import diracvi as dv
from _midpoint_nodes import MidpointNodes
from diracvi import components as cp
from diracvi import spice
from diracvi.spice import waveforms

VT = 1.38064852e-23 * 300.15 / 1.6021766208e-19  # kT/q at 27 °C (ngspice's constants)
GMIN = 1e-12
# the transistors' exponentials need a fresh Jacobian every Newton iteration: the first
# step starts every junction voltage at 0 V and must climb to ~0.65 V without SPICE's
# junction limiting (the reused Jacobian stalls there)
SOLVER = dv.NewtonSolver(reuse_jacobian=False)


def _dc(circuit, steps=3, dt=1e-6):
    built = circuit.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=dt, steps=steps, discretization="midpoint",
        solver=SOLVER,
    )  # fmt: skip
    return built, traj, waveforms(built, traj)


# ------------------------------------------------------------------ MOSFET closed forms
def _shichman_hodges(vgs, vds, vbs, *, sign, vto, kp, w, l, gamma, phi, lam):  # noqa: E741
    """The drain current into the drain (ngspice level 1, written out independently):
    NMOS-oriented voltages ``type·V``, source/drain swapped for V_DS < 0."""
    gs, ds, bs = sign * vgs, sign * vds, sign * vbs
    mode = 1.0
    if ds < 0:
        gs, bs, ds, mode = gs - ds, bs - ds, -ds, -1.0
    if bs <= 0:
        s = np.sqrt(phi - bs)
    else:
        s = max(0.0, np.sqrt(phi) - bs / (2 * np.sqrt(phi)))
    vth = sign * vto + gamma * (s - np.sqrt(phi))
    vov = gs - vth
    beta = kp * w / l * (1 + lam * ds)
    if vov <= 0:
        i = 0.0
    elif vov <= ds:
        i = beta * vov**2 / 2
    else:
        i = beta * ds * (vov - ds / 2)
    return sign * mode * i


def _junction(v, i_s):  # ngspice's MOSFET bulk junction, with GMIN
    return (-i_s if v <= -3 * VT else i_s * np.expm1(v / VT)) + GMIN * v


MOS = dict(vto=0.8, kp=60e-6, w=12e-6, l=2e-6, gamma=0.45, phi=0.7, lam=0.03)


@pytest.mark.parametrize("kind", ["nmos", "pmos"])
@pytest.mark.parametrize(
    ("vgs", "vds", "vbs", "region"),
    [
        (0.5, 2.0, 0.0, "cutoff"),
        (2.5, 0.4, 0.0, "linear"),
        (2.5, 3.0, 0.0, "saturation"),
        (2.5, 3.0, -1.5, "saturation, body effect"),
        (2.5, 0.4, 0.2, "linear, forward body bias"),
        (2.5, -0.6, 0.0, "reverse (source/drain swapped)"),
    ],
)
def test_mosfet_drain_current_is_shichman_hodges_in_every_region(kind, vgs, vds, vbs, region):
    """Voltage sources on gate, drain and bulk (source grounded): ``i(VD)`` is minus the
    drain-terminal current — the channel's Shichman–Hodges current minus the bulk–drain
    junction's — to round-off (the circuit is resistive: the midpoint step is exact)."""
    sign = 1.0 if kind == "nmos" else -1.0
    vgs, vds, vbs = sign * vgs, sign * vds, sign * vbs
    p = MOS | {"vto": sign * MOS["vto"]}
    c = cp.Circuit("mos")
    c.add(cp.VoltageSource(vgs, name="VG"), p="g", n="0")
    c.add(cp.VoltageSource(vds, name="VD"), p="d", n="0")
    c.add(cp.VoltageSource(vbs, name="VB"), p="b", n="0")
    c.add(
        cp.MOSFET(kind, p["vto"], p["kp"], p["lam"], p["w"], p["l"], p["gamma"], p["phi"],
                  name="M1"),
        d="d", g="g", s="0", b="b",
    )  # fmt: skip
    _, _, wv = _dc(c)
    channel = _shichman_hodges(vgs, vds, vbs, sign=sign, **p)
    bulk_drain = sign * _junction(sign * (vbs - vds), 1e-14)
    expected = channel - bulk_drain  # into the drain terminal
    got = -wv["i(VD)"][1:-1]
    assert np.max(np.abs(got - expected)) <= 1e-12 * max(abs(expected), 1e-6), region
    if region != "cutoff":
        assert abs(channel) > 1e-6  # it conducts (a cutoff by mistake fails)
    # the gate draws no current; the bulk only its two junctions' (IS and GMIN)
    assert np.max(np.abs(wv["i(VG)"][1:-1])) <= 1e-18
    bulk = bulk_drain + sign * _junction(sign * vbs, 1e-14)
    assert np.max(np.abs(-wv["i(VB)"][1:-1] - bulk)) <= 1e-12 * max(abs(bulk), 1e-6)


# ------------------------------------------------------------------ BJT closed forms
BJT = dict(is_=2e-15, bf=80.0, br=3.0, nf=1.05, nr=1.1, vaf=60.0, var=20.0, ikf=0.02,
           ikr=0.01, ise=5e-14, ne=1.6, isc=1e-14, nc=1.9)  # fmt: skip


def _gummel_poon(vbe, vbc, sign):
    """(I_C, I_B) into collector and base (ngspice's Gummel–Poon, written out here)."""
    p = BJT
    be, bc = sign * vbe, sign * vbc

    def pn(v, i_s, n):  # below −3 n V_T ngspice continues with −I_S (1 + (3 n V_T/(e V))³)
        nvt = n * VT
        return (
            i_s * np.expm1(v / nvt) if v >= -3 * nvt else -i_s * (1 + (3 * nvt / (np.e * v)) ** 3)
        )

    ibe = pn(be, p["is_"], p["nf"])
    ibc = pn(bc, p["is_"], p["nr"])
    iben = pn(be, p["ise"], p["ne"]) + GMIN * be
    ibcn = pn(bc, p["isc"], p["nc"]) + GMIN * bc
    q1 = 1 / (1 - bc / p["vaf"] - be / p["var"])
    qb = q1 * (1 + np.sqrt(1 + 4 * (ibe / p["ikf"] + ibc / p["ikr"]))) / 2
    ic = (ibe - ibc) / qb - ibc / p["br"] - ibcn
    ib = ibe / p["bf"] + iben + ibc / p["br"] + ibcn
    return sign * ic, sign * ib


@pytest.mark.parametrize("kind", ["npn", "pnp"])
@pytest.mark.parametrize(
    ("vbe", "vce"),
    [(0.68, 3.0), (0.75, 5.0), (0.8, 0.1), (-0.3, 2.0)],  # active ×2, saturation, cutoff
)
def test_bjt_currents_are_gummel_poon(kind, vbe, vce):
    """``V_BE`` and ``V_CE`` from sources: the collector and base currents equal the
    Gummel–Poon formulas (Early effect, high injection, leakage terms, GMIN)."""
    sign = 1.0 if kind == "npn" else -1.0
    vbe, vce = sign * vbe, sign * vce
    c = cp.Circuit("bjt")
    c.add(cp.VoltageSource(vbe, name="VB"), p="b", n="0")
    c.add(cp.VoltageSource(vce, name="VC"), p="c", n="0")
    c.add(cp.BJT(kind, **BJT, name="Q1"), c="c", b="b", e="0", s="0")
    _, _, wv = _dc(c)
    ic, ib = _gummel_poon(vbe, vbe - vce, sign)
    # the substrate's GMIN leak (substrate grounded; to the collector for an NPN's
    # vertical layout, to the base for a PNP's lateral one) is part of the terminal current
    ic_term = ic + (GMIN * vce if kind == "npn" else 0.0)
    ib_term = ib + (GMIN * vbe if kind == "pnp" else 0.0)
    got_c, got_b = -wv["i(VC)"][1:-1], -wv["i(VB)"][1:-1]
    assert np.max(np.abs(got_c - ic_term)) <= 1e-11 * abs(ic_term) + 1e-20
    assert np.max(np.abs(got_b - ib_term)) <= 1e-11 * abs(ib_term) + 1e-20
    if vbe * sign > 0.7 and vce * sign > 1:
        assert 20 < ic / ib < 80  # forward active, beta rolled off by ISE and IKF


# 9 s, in `-m slow` (CI time): series resistances of a diode (RS) agree with ngspice by
# default (tests/test_nonlinear_circuits.py, "series resistance")
@pytest.mark.slow
def test_bjt_series_resistances_drop_their_currents():
    """RB, RC, RE as internal nodes: the terminal currents solve the Gummel–Poon law at
    the internal junction voltages ``V_B'E' = V_BE − R_B I_B − R_E I_E`` (checked by
    evaluating the formulas there)."""
    rb, rc, re_ = 200.0, 20.0, 5.0
    c = cp.Circuit("bjt")
    c.add(cp.VoltageSource(0.75, name="VB"), p="b", n="0")
    c.add(cp.VoltageSource(3.0, name="VC"), p="c", n="0")
    c.add(cp.BJT("npn", **BJT, rb=rb, rc=rc, re=re_, name="Q1"), c="c", b="b", e="0", s="0")
    _, _, wv = _dc(c)
    ic, ib = -wv["i(VC)"][1], -wv["i(VB)"][1]
    ie = ic + ib
    vbe = 0.75 - rb * ib - re_ * ie
    vbc = 0.75 - rb * ib - (3.0 - rc * ic)
    want_c, want_b = _gummel_poon(vbe, vbc, 1.0)
    assert abs(ic - want_c - GMIN * (3.0 - rc * ic)) <= 1e-9 * abs(ic)
    assert abs(ib - want_b) <= 1e-9 * abs(ib)
    assert rb * ib + re_ * ie > 1e-3  # the resistances matter here


# ------------------------------------------------------------------ ngspice
def _with_operating_point(netlist: str, nodes) -> tuple[str, str]:
    """The netlist with ``.ic`` at ngspice's own DC operating point (a zero-length
    transient's t = 0), so that both simulators integrate the same initial value problem:
    ngspice starts from its operating point, diracvi's capacitors and junction charges from
    these voltages. Returns (for diracvi, for ngspice): ngspice's deck leaves out the
    nodes a voltage source holds (an ``.ic`` there makes ngspice 39's MOSFET overlap
    charges jump at its first step, though the source fixes the node anyway)."""
    short = re.sub(r"^\.tran\s.*$", ".tran 1p 1p", netlist, flags=re.M | re.I)
    _, v = ng.ngspice(short, tuple(f"v({n})" for n in nodes), tmax=1e-13)
    held = {line.split()[1] for line in netlist.splitlines()[1:] if line[:1].lower() == "v"}

    def deck(names):
        ic = " ".join(f"v({n})={v[f'v({n})'][0]:.15g}" for n in names)
        return netlist.replace(".tran", f".ic {ic}\n.tran", 1)

    # diracvi's deck with UIC: the .ic values ARE the operating point (diracvi's own
    # operating point does not yet solve transistors' junction charges)
    mine = re.sub(r"^(\.tran\s.*)$", r"\1 uic", deck(nodes), flags=re.M | re.I)
    return mine, deck([n for n in nodes if n not in held])


CIRCUITS = {
    "cmos-inverter": (
        """CMOS inverter driven by a pulse
vdd vdd 0 5
vin in 0 PULSE(0 5 10n 2n 2n 20n 50n)
mp out in vdd vdd pch L=1u W=20u
mn out in 0 0 nch L=1u W=10u
cl out 0 100f
.model nch NMOS (LEVEL=1 VTO=0.7 KP=110u GAMMA=0.4 LAMBDA=0.04 PHI=0.7)
.model pch PMOS (LEVEL=1 VTO=-0.7 KP=50u GAMMA=0.57 LAMBDA=0.05 PHI=0.8)
.tran 0.1n 60n
.end
""",
        ("out",),
        ("v(out)",),
        (),
    ),
    "nmos-common-source": (
        """NMOS common-source amplifier with a resistor load
vdd vdd 0 10
vin g 0 SIN(2 0.2 20k)
rd vdd d 20k
cl d 0 200p
m1 d g 0 0 nch L=2u W=20u
.model nch NMOS (LEVEL=1 VTO=1 KP=50u LAMBDA=0.02 GAMMA=0.5 PHI=0.65)
.tran 0.5u 100u
.end
""",
        ("d",),
        ("v(d)",),
        (),
    ),
    "bjt-common-emitter": (
        """BJT common-emitter amplifier with emitter degeneration
vcc vcc 0 12
vin in 0 SIN(0 50m 10k)
cin in b 10u
r1 vcc b 47k
r2 b 0 10k
rc vcc c 4.7k
re e 0 1k
cout c out 1u
rl out 0 100k
q1 c b e qn
.model qn NPN (IS=1e-14 BF=120 VAF=80 IKF=0.05 ISE=1e-15 NE=1.6 BR=2 RB=50 RC=5 RE=0.5)
.tran 2u 300u
.end
""",
        ("b", "c", "e", "out"),
        ("v(c)", "v(b)", "v(e)", "v(out)"),
        (),
    ),
    "bjt-rtl-inverter": (
        """RTL inverter driven by a pulse
vcc vcc 0 5
vin in 0 PULSE(0 5 0.5u 50n 50n 1u 2u)
rb in b 10k
q1 c b 0 qn
rc vcc c 1k
cl c 0 100p
.model qn NPN (IS=1e-15 BF=100 BR=1 VAF=100)
.tran 2.5n 3u
.end
""",
        ("c", "b"),
        ("v(c)", "v(b)"),
        # v(b) follows the source's corners at once (the transistor is off): midpoint's
        # node voltage is the mean over the two half steps around t_k, off by
        # h·|Δslope|/4 within a step of a kink; those instants are left out for it
        (0.5e-6, 0.55e-6, 1.55e-6, 1.6e-6, 2.5e-6, 2.55e-6),
    ),
    "bjt-rtl-inverter-charges": (
        """RTL inverter with junction and diffusion charges
vcc vcc 0 5
vin in 0 PULSE(0 5 0.5u 50n 50n 1u 2u)
rb in b 10k
q1 c b 0 qn
rc vcc c 1k
cl c 0 20p
.model qn NPN (IS=1e-15 BF=100 BR=1 CJE=2p VJE=0.7 MJE=0.35 CJC=1p VJC=0.6 MJC=0.4
+ TF=0.3n TR=10n FC=0.5 RB=100)
.tran 2.5n 3u
.end
""",
        ("c", "b", "in", "vcc"),
        ("v(c)", "v(b)"),
        (0.5e-6, 0.55e-6, 1.55e-6, 1.6e-6, 2.5e-6, 2.55e-6),
    ),
    "pnp-common-emitter": (
        """PNP common-emitter amplifier from a negative supply
vee vee 0 -12
vin in 0 SIN(0 50m 10k)
cin in b 10u
r1 vee b 47k
r2 b 0 10k
rc vee c 4.7k
re e 0 1k
cout c out 1u
rl out 0 100k
q1 c b e qp
.model qp PNP (IS=5e-15 BF=80 VAF=60 IKF=0.03 ISE=1e-15 NE=1.5 BR=3 CJC=2p)
.tran 2u 300u
.end
""",
        ("b", "c", "e", "out"),
        ("v(c)", "v(b)", "v(e)", "v(out)"),
        (),
    ),
    "cmos-inverter-overlap": (
        """CMOS inverter with overlap capacitances
vdd vdd 0 5
vin in 0 PULSE(0 5 10n 2n 2n 20n 50n)
mp out in vdd vdd pch L=1u W=20u
mn out in 0 0 nch L=1u W=10u
cl out 0 20f
.model nch NMOS (LEVEL=1 VTO=0.7 KP=110u GAMMA=0.4 LAMBDA=0.04 PHI=0.7 CGSO=0.4n CGDO=0.4n
+ CGBO=0.2n)
.model pch PMOS (LEVEL=1 VTO=-0.7 KP=50u GAMMA=0.57 LAMBDA=0.05 PHI=0.8 CGSO=0.4n CGDO=0.4n
+ CGBO=0.2n)
.tran 0.1n 60n
.end
""",
        ("out", "in", "vdd"),
        ("v(out)",),
        (),
    ),
}


_SLOW_CIRCUITS = {
    "pnp-common-emitter",
    "bjt-rtl-inverter",
    "bjt-rtl-inverter-charges",
    "cmos-inverter-overlap",
}


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
@pytest.mark.parametrize(
    "name",
    # the PNP stage (~45 s), the RTL inverters and the overlap-capacitance inverter in
    # `pytest -m slow` (the default suite's time on CI): by default one CMOS inverter, one
    # NMOS and one BJT stage; the charge port by its power balance below
    [n if n not in _SLOW_CIRCUITS else pytest.param(n, marks=pytest.mark.slow) for n in CIRCUITS],
)
def test_transistor_circuits_agree_with_ngspice(name):
    """Each circuit against a fine ngspice run (max step TSTOP/40000, from its DC
    operating point), diracvi midpoint at TSTEP/20: ≤ 1e-3 of each probe's peak."""
    netlist, nodes, probes, corners = CIRCUITS[name]
    netlist, reference = _with_operating_point(netlist, nodes)
    read = spice.read(netlist)
    t, ref = ng.ngspice(reference, probes, tmax=read.stop / 40000)
    h = read.dt / 20
    result = spice.run(read, dt=h, solver=SOLVER)
    for probe in probes:
        mine = np.interp(t, result.time, result[probe])
        keep = t > 0
        if probe == "v(b)":
            for corner in corners:
                keep &= np.abs(t - corner) > 2 * h
        peak = np.max(np.abs(ref[probe]))
        err = np.max(np.abs(mine - ref[probe])[keep]) / peak
        assert err <= 1e-3, (name, probe, err)
        assert np.ptp(ref[probe]) > 0.02 * peak  # the probe moves


# ------------------------------------------------------------------ gradients
def _cs_stage(kp, steps=40, h=1e-6):
    c = cp.Circuit("cs")
    c.add(cp.VoltageSource(10.0, name="VDD"), p="vdd", n="0")
    c.add(cp.VoltageSource(cp.Sine(2.0, 0.2, 20e3), name="VIN"), p="g", n="0")
    c.add(cp.Resistor(20e3, name="RD"), p="vdd", n="d")
    c.add(cp.Capacitor(200e-12, name="CL", v0=4.5), p="d", n="0")
    c.add(cp.MOSFET("nmos", 1.0, kp, 0.02, 20e-6, 2e-6, name="M1"), d="d", g="g", s="0", b="0")
    built = c.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=h, steps=steps, discretization="midpoint",
        solver=SOLVER,
    )  # fmt: skip
    return traj.q[-1, built.system.coords.index("CL.q")]


def _ce_stage(bf, steps=40, h=1e-6):
    c = cp.Circuit("ce")
    c.add(cp.VoltageSource(12.0, name="VCC"), p="vcc", n="0")
    c.add(cp.VoltageSource(cp.Sine(1.0, 0.05, 10e3), name="VB"), p="b", n="0")
    c.add(cp.Resistor(4.7e3, name="RC"), p="vcc", n="c")
    c.add(cp.Capacitor(1e-9, name="C1", v0=6.0), p="c", n="0")
    c.add(cp.Resistor(1e3, name="RE"), p="e", n="0")
    c.add(cp.BJT("npn", is_=1e-14, bf=bf, vaf=80.0, rb=100.0, name="Q1"), c="c", b="b", e="e",
          s="0")  # fmt: skip
    built = c.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=h, steps=steps, discretization="midpoint",
        solver=SOLVER,
    )  # fmt: skip
    return traj.q[-1, built.system.coords.index("C1.q")]


@pytest.mark.parametrize(
    ("loss", "x", "eps"),
    [(_cs_stage, 50e-6, 1e-9), pytest.param(_ce_stage, 120.0, 1e-3, marks=pytest.mark.slow)],
    ids=["KP", "BF"],
)
def test_gradient_to_kp_and_bf_matches_central_differences(loss, x, eps):
    """``jax.grad`` of a load capacitor's final charge with respect to KP (MOSFET stage)
    and BF (BJT stage, where RB makes the base current matter) equals central
    differences."""
    grad = float(jax.grad(loss)(x))
    fd = (float(loss(x + eps)) - float(loss(x - eps))) / (2 * eps)
    assert abs(grad - fd) <= 1e-5 * abs(fd), (grad, fd)
    assert abs(fd) > 0


# ------------------------------------------------------------------ netlists
BASE = "title\nvdd 1 0 5\nvg 2 0 2\nr1 1 3 1k\n"


def test_netlist_lines_build_the_parts_with_ngspice_names_and_defaults():
    netlist = spice.read(
        BASE
        + "m1 3 2 0 0 nch L=2u W=10u AD=1p\n"
        + "q1 1 2 4 qp 2\nr2 4 0 1k\n"
        + ".model nch NMOS (LEVEL=1 VT0=0.9 KP=40u KF=1e-25)\n"
        + ".model qp PNP (BF=50 VA=30)\n.tran 1u 10u\n.end\n"
    )
    parts = {p.name: p for p in netlist.circuit.parts}
    assert dict(parts["m1"].parameters) == pytest.approx(
        {"kp": 40e-6, "vto": 0.9, "lambda": 0.0, "gamma": 0.0, "phi": 0.6}
    )
    assert dict(parts["q1"].parameters) == pytest.approx({"is": 2e-16, "bf": 50.0, "br": 1.0})
    assert any("KF ignored" in n for n in netlist.notes)
    assert netlist.discretizations == ("midpoint",)  # the left-point step is singular
    with pytest.raises(dv.UnsolvableStepError, match=r"q1\.w"):
        spice.run(netlist, discretization="retraction", steps=3, solver=SOLVER)


@pytest.mark.parametrize(
    ("lines", "match"),
    [
        (
            "m1 3 2 0 0 nch\n.model nch NMOS (LEVEL=9 VTO=1)",
            r"line 5: model 'nch' \(line 6\): NMOS level 9 \(MOS9\) is not supported; diracvi "
            r"has levels 1 \(Shichman–Hodges\), 2 \(Grove–Frohman\), 3 \(semi-empirical\), "
            r"6 \(Sakurai–Newton\), 8/49 \(BSIM3v3\) and 14/54 \(BSIM4\)",
        ),
        (
            "m1 3 2 0 0 nch\n.model nch NMOS (LEVEL=14 VERSION=4.8)",
            r"line 5: .*NMOS level 14 \(BSIM4v4\.8\) is not supported",
        ),
        (
            "m1 3 2 0 0 nch\n.model nch NMOS (TOX=1e-8 NSUB=1e9)",
            r"line 5: .*NSUB=1e\+09.*intrinsic",
        ),
        # (levels 1, 2, 3, 6 read TNOM: tests/test_temperature.py; BSIM3 runs at its own)
        (
            "m1 3 2 0 0 nch\n.model nch NMOS (LEVEL=8 TNOM=50)",
            r"line 5: element 'm1': BSIM3 has no temperature update .*TNOM 50",
        ),
        ("m1 3 2 0 0 nch\n.model nch NMOS (MJ=2.2 CBD=1p)", r"line 5: .*mj=2\.2.*\[0, 2\)"),
        (
            "m1 3 2 0 vd\n.model vd VDMOS (VTO=2 RQ=1)",
            r"line 5: model 'vd' \(line 6\): VDMOS parameter RQ=1 is not supported",
        ),
        ("m1 3 2 0 0 nch", r"line 5: model 'nch' is not defined"),
        (
            "m1 3 2 0 0 qn\n.model qn NPN",
            r"line 5: model 'qn' \(line 6\) is a NPN .*needs NMOS/PMOS",
        ),
        ("q1 3 2 0 qn\n.model qn NPN (NKF=0.6)", r"line 5: model 'qn' \(line 6\): .*NKF"),
        ("q1 3 2 0 qn\n.model qn NPN (TF=1n PTF=30)", r"line 5: model 'qn' .*PTF=30.*excess"),
        ("q1 3 2 0 qn\n.model qn NPN (SUBS=-1)", r"line 5: model 'qn' .*SUBS=-1.*collector"),
        ("q1 3 2 0 zz\n.model qn NPN", r"line 5: element 'q1': no defined model"),
        ("m1 3 2 0 0 nch W=1u FOO=2\n.model nch NMOS", r"line 5: .*FOO is not supported"),
    ],
)
def test_netlist_errors_name_the_line_and_the_reason(lines, match):
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(BASE + lines + "\n.tran 1u 10u\n.end\n")


# ------------------------------------------------------------------ junction charges
def test_junction_coenergies_differentiate_to_ngspices_charges():
    """``d C*/dV = Q(V)`` (the momentum of the flux-form Lagrangian is the junction
    charge), ``dQ/dV = C_J (1 − V/V_J)^{−M}`` below ``FC·V_J`` and ngspice's linear
    continuation ``C_J/F2 (F3 + M V/V_J)`` above; the diffusion co-energy gives ``τ I``."""
    from diracvi.components._junction import (
        depletion_charge,
        depletion_coenergy,
        diffusion_coenergy,
        pn_current,
    )

    cj, vj, m, fc = 2e-12, 0.7, 0.35, 0.5
    f2, f3 = (1 - fc) ** (1 + m), 1 - fc * (1 + m)
    for v in (-3.0, -0.4, 0.0, 0.2, 0.34, 0.36, 0.6, 1.2):
        q = float(depletion_charge(v, cj, vj, m, fc))
        assert float(jax.grad(depletion_coenergy)(v, cj, vj, m, fc)) == pytest.approx(
            q, rel=1e-12, abs=1e-27
        )
        cap = float(jax.grad(depletion_charge)(v, cj, vj, m, fc))
        want = cj * (1 - v / vj) ** -m if v < fc * vj else cj / f2 * (f3 + m * v / vj)
        assert cap == pytest.approx(want, rel=1e-12)
        if v < fc * vj:  # ngspice's closed form of the charge itself
            assert q == pytest.approx(cj * vj * (1 - (1 - v / vj) ** (1 - m)) / (1 - m), rel=1e-12)
    for v in (-0.05, 0.3, 0.7, 1.5):
        tau_i = 3e-10 * float(pn_current(v, 1e-15, 1.0))
        got = float(jax.grad(diffusion_coenergy)(v, 3e-10, 1e-15, 1.0))
        assert got == pytest.approx(tau_i, rel=1e-10, abs=1e-30)


# ------------------------------------------------------------------ power balance
def test_discrete_power_balance_of_a_mosfet_stage_accounts_for_every_watt():
    r"""Midpoint, at each interior node ``t_k`` (node voltages ``−λ_k/h``, node currents
    ``ī = (Δq_{k−1} + Δq_k)/2h``): the supply's work = Δ(capacitor energy) + the
    resistor's ``R ī² h`` + the transistor's ``Σ_b V_b ī_b h``, where the transistor's
    branch currents come from the Shichman–Hodges and junction formulas at the step
    voltages ``Δw/h`` (``ī_b = (i(V_{k−½}) + i(V_{k+½}))/2`` exactly, from its flux lines)."""
    net = CIRCUITS["nmos-common-source"][0].replace(".tran", ".ic v(d)=4.5\n.tran", 1)
    result = spice.run(net, dt=0.25e-6, steps=400, solver=SOLVER)
    traj = result.trajectory
    h, k = float(traj.dt), slice(1, -1)

    nodes = MidpointNodes(traj)
    coord, node_current = nodes.coord, nodes.node_current

    def step_volts(name):
        return np.diff(coord(name)) / h

    vd, vg = result["v(d)"][k], result["v(g)"][k]
    p = dict(sign=1.0, vto=1.0, kp=50e-6, w=20e-6, l=2e-6, gamma=0.5, phi=0.65, lam=0.02)
    vds, vgs, vbs = step_volts("m1.w"), step_volts("m1.wg"), step_volts("m1.wbs")
    vbd = step_volts("m1.wbd")
    i_ch = np.array([_shichman_hodges(a, b, c, **p) for a, b, c in zip(vgs, vds, vbs, strict=True)])
    i_bd = np.array([_junction(v, 1e-14) for v in vbd])
    i_bs = np.array([_junction(v, 1e-14) for v in vbs])

    def at_nodes(i):
        return (i[:-1] + i[1:]) / 2

    supply = -10.0 * node_current("vdd.q") * h
    q = coord("cl.q")
    qbar = (q[:-1] + q[1:]) / 2
    stored = np.diff(qbar**2 / (2 * 200e-12))
    dissipated = 20e3 * node_current("rd.q") ** 2 * h
    transistor = (vd * at_nodes(i_ch) - vd * at_nodes(i_bd) + 0.0 * at_nodes(i_bs)) * h
    assert np.max(np.abs(node_current("vin.q"))) == 0.0  # the gate draws nothing
    assert np.max(np.abs(node_current("m1.q") - at_nodes(i_ch))) <= 1e-12 * np.max(np.abs(i_ch))
    terms = (supply, stored, dissipated, transistor)
    scale = max(np.max(np.abs(x)) for x in terms)
    residual = supply - stored - dissipated - transistor
    assert np.max(np.abs(residual)) <= 1e-10 * scale, np.max(np.abs(residual)) / scale
    for x in terms:
        assert np.max(np.abs(x)) > 1e-2 * scale  # every term is a sizeable share
    assert np.all(vg > 1.7)


# ------------------------------------------------------------------ the charge port
PORTED = dict(
    is_=1e-15, bf=100.0, vaf=50.0, ikf=0.02, tf=1e-9, xtf=2.0, vtf=3.0, itf=0.01,
    cje=2e-12, cjc=1e-12, cjs=1e-12,
)  # fmt: skip


def _pn(v, i_s):
    """``I_S (e^{V/V_T} − 1)``, ngspice's ``−I_S (1 + (3 V_T/(e V))³)`` below ``−3 V_T``."""
    v = np.asarray(v, dtype=float)
    low = v < -3 * VT
    safe = np.where(low, v, -1.0)
    return np.where(low, -i_s * (1 + (3 * VT / (np.e * safe)) ** 3), i_s * np.expm1(v / VT))


def _forward_charge(vbe, vbc, p):
    """ngspice's B-E diffusion charge, written out here from its manual and bjtload:
    ``TF·I_be (1 + XTF e^{V_BC/(1.44 VTF)} (I_be/(I_be + ITF))²)/q_b`` for ``V_BE > 0``."""
    ibe = _pn(vbe, p["is_"])
    if vbe <= 0:  # diracvi's one formula differs here by ≤ TF·I_S·|1 − (1 + arg)/q_b|
        return p["tf"] * float(ibe)
    q1 = 1 / (1 - vbc / p["vaf"])
    qb = q1 * (1 + np.sqrt(1 + 4 * ibe / p["ikf"])) / 2
    arg = p["xtf"] * np.exp(vbc / (1.44 * p["vtf"])) * (ibe / (ibe + p["itf"])) ** 2
    return p["tf"] * ibe * (1 + arg) / qb


def test_the_forward_diffusion_charge_is_no_lagrangians_momentum():
    """Gummel–Poon's ``Q_F(V_BE, V_BC)`` depends on ``V_BC`` while the B-C charge does not
    depend on ``V_BE``: the charges' Jacobian is not symmetric, so no co-energy has them as
    gradient. Such a part carries them in a charge port (its momentum ``∂L/∂v + Q``);
    with ``q_b ≡ 1`` and ``XTF = 0`` the charge ``TF·I_be`` stays in the Lagrangian."""
    from diracvi.components.bjt import forward_diffusion_charge

    ported = cp.BJT("npn", **PORTED, name="Q1")
    assert isinstance(ported, cp.ChargePortPart)
    plain = cp.BJT("npn", is_=1e-15, tf=1e-9, cje=2e-12, name="Q2")
    assert not isinstance(plain, cp.ChargePortPart)
    p = dict(PORTED, is_=1e-15)
    table = {"is": 1e-15, "nf": 1.0, "nr": 1.0, "ova": 1 / 50, "ovb": 0.0, "oik": 50.0,
             "oikr": 0.0, "tf": 1e-9, "xtf": 2.0, "ovtf": 1 / 4.32, "itf": 0.01}  # fmt: skip
    for vbe, vbc in ((0.7, -2.0), (0.75, 0.3), (-0.2, -1.0), (0.6, -8.0)):
        got = float(forward_diffusion_charge(vbe, vbc, table))
        tol = 1e-12 * abs(_forward_charge(vbe, vbc, p)) + (10 * 1e-9 * 1e-15 if vbe <= 0 else 0)
        assert abs(got - _forward_charge(vbe, vbc, p)) <= tol
    d_vbc = float(jax.grad(forward_diffusion_charge, argnums=1)(0.72, -2.0, table))
    assert abs(d_vbc) > 1e-14  # ∂Q_F/∂V_BC ≠ 0 = ∂Q_BC/∂V_BE (Q_BC = TR·I_bc + depletion)
    # the momentum of the w_be line is the depletion charge plus type·Q_F
    q, v = np.zeros(ported.n), np.zeros(ported.n)
    i, j = ported.coords.index("wbe"), ported.coords.index("wbc")
    v[i], v[j] = 0.72, -2.0
    from diracvi.components._junction import depletion_charge

    want = float(depletion_charge(0.72, 2e-12, 0.75, 0.33, 0.5)) + _forward_charge(0.72, -2.0, p)
    assert float(ported.momentum(q, v)[i]) == pytest.approx(want, rel=1e-12)
    with pytest.raises(dv.ModelError, match="charge port"):
        c = cp.Circuit("ce")
        c.add(cp.VoltageSource(5.0, name="V1"), p="c", n="0")
        c.add(cp.VoltageSource(0.7, name="V2"), p="b", n="0")
        c.add(cp.BJT("npn", **PORTED, name="Q1"), c="c", b="b", e="0", s="0")
        built = c.build()
        dv.simulate(built.system, built.q0, built.p0, dt=1e-9, steps=2,
                    discretization="lobatto", solver=SOLVER)  # fmt: skip


@pytest.mark.slow  # a BJT circuit compiled: seconds
def test_the_charge_port_refusal_suggests_a_rule_that_runs():
    """The message's suggested discretization, applied, runs the same circuit."""
    import re

    c = cp.Circuit("ce")
    c.add(cp.VoltageSource(5.0, name="V1"), p="c", n="0")
    c.add(cp.VoltageSource(0.7, name="V2"), p="b", n="0")
    c.add(cp.BJT("npn", **PORTED, name="Q1"), c="c", b="b", e="0", s="0")
    built = c.build()
    run = dict(dt=1e-9, steps=2, solver=SOLVER)
    with pytest.raises(dv.ModelError, match="charge port") as err:
        dv.simulate(built.system, built.q0, built.p0, discretization="lobatto", **run)
    rule = re.search(r"use discretization='(\w+)'", str(err.value))
    assert rule, err.value
    traj = dv.simulate(built.system, built.q0, built.p0, discretization=rule.group(1), **run)
    assert traj.status == 0 and np.all(np.isfinite(traj.q))


PORT_STAGE = """NPN stage whose B-E diffusion charge goes through the charge port
vcc vcc 0 5
vin in 0 SIN(0.8 0.15 20meg)
rb in b 1k
rc vcc c 2k
cl c 0 1p
q1 c b 0 qn
.model qn NPN (IS=1e-15 BF=100 VAF=50 IKF=20m TF=1n XTF=2 VTF=3 ITF=10m CJE=2p CJC=1p
+ CJS=1p)
.ic v(c)=4 v(b)=0.75
.tran 0.5n 200n
.end
"""


def test_discrete_power_balance_with_the_charge_port_accounts_for_every_watt():
    r"""Midpoint, at each interior node ``t_k``: the sources' work = Δ(load capacitor's
    energy) + ``R ī² h`` + the transistor's conduction ``Σ_b V_b ī_b,cond h`` + its
    Lagrangian junction charges ``Σ_b V_b ΔQ_b`` + **the charge port's work**
    ``V_BE ΔQ_F``. Every branch current comes from its law at the step voltages
    ``V_{k±½} = Δw/h`` (independent NumPy formulas), the port's ``ΔQ_F = Q_F(V_{k+½}) −
    Q_F(V_{k−½})``: the balance closes to round-off, with the port a sizeable share."""
    from diracvi.components._junction import depletion_charge

    result = spice.run(PORT_STAGE, dt=0.1e-9, steps=1000, solver=SOLVER)
    traj = result.trajectory
    h, k = float(traj.dt), slice(1, -1)

    nodes = MidpointNodes(traj)
    coord, node_current = nodes.coord, nodes.node_current

    def at_nodes(x):  # the two steps' values around each interior node, averaged
        return (x[:-1] + x[1:]) / 2

    step = {b: np.diff(coord(f"q1.w{b}")) / h for b in ("be", "bc", "ce", "sub")}
    vb, vc = result["v(b)"][k], result["v(c)"][k]
    node_v = {"be": vb, "bc": vb - vc, "ce": vc, "sub": -vc}
    for b, v in node_v.items():  # the flux lines: V(t_k) = (V_{k−½} + V_{k+½})/2 exactly
        assert np.max(np.abs(at_nodes(step[b]) - v)) <= 1e-9 * np.max(np.abs(v)) + 1e-12
    p = dict(PORTED)

    def pn(v):
        return _pn(v, p["is_"])

    vbe, vbc = step["be"], step["bc"]
    q1 = 1 / (1 - vbc / p["vaf"])
    qb = q1 * (1 + np.sqrt(1 + 4 * pn(vbe) / p["ikf"])) / 2
    cond = {
        "be": pn(vbe) / p["bf"] + GMIN * vbe,
        "bc": pn(vbc) / 1.0 + GMIN * vbc,
        "ce": (pn(vbe) - pn(vbc)) / qb,
        "sub": GMIN * step["sub"],
    }
    lagrangian_q = {
        "be": np.asarray(depletion_charge(vbe, 2e-12, 0.75, 0.33, 0.5)),
        "bc": np.asarray(depletion_charge(vbc, 1e-12, 0.75, 0.33, 0.5)),
        "sub": np.asarray(depletion_charge(step["sub"], 1e-12, 0.75, 0.0, 0.0)),
    }
    q_f = np.array([_forward_charge(a, b, p) for a, b in zip(vbe, vbc, strict=True)])

    sources = (
        -(result["v(vcc)"][k] * node_current("vcc.q") + result["v(in)"][k] * node_current("vin.q"))
        * h
    )
    q = coord("cl.q")
    stored = np.diff(((q[:-1] + q[1:]) / 2) ** 2 / (2 * 1e-12))
    dissipated = (1e3 * node_current("rb.q") ** 2 + 2e3 * node_current("rc.q") ** 2) * h
    conduction = sum(node_v[b] * at_nodes(cond[b]) * h for b in cond)
    junctions = sum(node_v[b] * np.diff(lagrangian_q[b]) for b in lagrangian_q)
    port = node_v["be"] * np.diff(q_f)
    # each branch's node current is its law: conduction + its charges' change
    for b in ("be", "bc", "sub"):
        law = (
            at_nodes(cond[b]) + (np.diff(lagrangian_q[b]) + (np.diff(q_f) if b == "be" else 0)) / h
        )
        assert np.max(np.abs(node_current(f"q1.q{b}") - law)) <= 1e-9 * np.max(np.abs(law))
    terms = (sources, stored, dissipated, conduction, junctions, port)
    scale = max(np.max(np.abs(x)) for x in terms)
    residual = sources - stored - dissipated - conduction - junctions - port
    assert np.max(np.abs(residual)) <= 1e-10 * scale, np.max(np.abs(residual)) / scale
    assert np.max(np.abs(port)) > 1e-2 * scale  # the port does a sizeable share
    assert np.max(np.abs(junctions)) > 1e-3 * scale


def _ported_stage(tf, bf=100.0, steps=30, h=0.5e-9):
    c = cp.Circuit("ported")
    c.add(cp.VoltageSource(5.0, name="VCC"), p="vcc", n="0")
    c.add(cp.VoltageSource(cp.Sine(0.8, 0.15, 20e6), name="VIN"), p="in", n="0")
    c.add(cp.Resistor(1e3, name="RB"), p="in", n="b")
    c.add(cp.Resistor(2e3, name="RC"), p="vcc", n="c")
    c.add(cp.Capacitor(1e-12, name="CL", v0=4.0), p="c", n="0")
    ported = dict(PORTED, tf=tf, bf=bf)
    c.add(cp.BJT("npn", **ported, v0=(0.75, -3.25), name="Q1"), c="c", b="b", e="0", s="0")
    built = c.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=h, steps=steps, discretization="midpoint",
        solver=SOLVER,
    )  # fmt: skip
    return traj.q[-1, built.system.coords.index("CL.q")]


@pytest.mark.slow
@pytest.mark.parametrize(("arg", "x", "eps"), [("tf", 1e-9, 1e-12), ("bf", 100.0, 1e-2)])
def test_gradient_through_the_charge_port_matches_central_differences(arg, x, eps):
    """``jax.grad`` of the load's final charge with respect to TF (which sits only in the
    charge port here) and BF, on the stage whose B-E diffusion charge is ported."""

    def loss(value):
        return _ported_stage(**({"tf": 1e-9} | {arg: value}))

    grad = float(jax.grad(loss)(x))
    fd = (float(loss(x + eps)) - float(loss(x - eps))) / (2 * eps)
    assert abs(grad - fd) <= 1e-5 * abs(fd), (grad, fd)
    assert abs(fd) > 0
