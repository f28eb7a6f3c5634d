"""The level-1 MOSFET beyond its drain current: the process parameters (TOX, U0, NSUB, NSS,
TPG), RD/RS, Meyer's gate capacitances and the bulk junction capacitances — against
ngspice's operating point, an independent transcription of ngspice's ``DEVqmeyer``, a
fine ngspice transient, the discrete power balance, and gradients (docs/circuits.md,
"Transistors")."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import _ngspice as ng
import diracvi as dv
from _midpoint_nodes import MidpointNodes
from diracvi import spice
from diracvi.components.mosfet import meyer_capacitances

SOLVER = dv.NewtonSolver(reuse_jacobian=False)

# ------------------------------------------------------------------ process parameters
BIAS = """process parameters
vg g 0 {vg}
vd d 0 {vd}
vb b 0 {vb}
m1 d g 0 b mod L=4u W=20u
.model mod {kind} (LEVEL=1 {card})
.tran 1n 10n
.end
"""

CARDS = [
    ("NMOS", "TOX=50n U0=550 NSUB=4e15", 3.0, 2.0, -1.0),
    ("NMOS", "TOX=30n NSUB=1e16 NSS=2e10 TPG=0 LAMBDA=0.02 RD=200 RS=100", 2.5, 0.3, 0.0),
    ("NMOS", "TOX=20n U0=400 NSUB=3e16 TPG=-1 PHI=0.8", 3.5, 4.0, -2.0),
    ("PMOS", "TOX=40n U0=250 NSUB=2e15 NSS=1e10", -3.0, -2.0, 1.0),
    ("PMOS", "TOX=25n NSUB=5e15 TPG=1 GAMMA=0.3 RSH=40 RD=20", -4.0, -0.5, 0.0),
]


@pytest.mark.slow  # ~30 s a card (an operating point compiles per circuit)
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
@pytest.mark.parametrize(("kind", "card", "vg", "vd", "vb"), CARDS)
def test_process_parameters_give_ngspices_drain_current(kind, card, vg, vd, vb):
    """KP, PHI, GAMMA and VTO derived from the process (where the card leaves them out),
    and the drain/source resistances (RD, or RSH·NRD with NRD = 1): the drain source's
    current at diracvi's operating point equals ngspice's ``.op`` to 1e-9."""
    net = BIAS.format(vg=vg, vd=vd, vb=vb, kind=kind, card=card)
    ref = ng.operating_point(net)["i(vd)"]
    got = spice.operating_point(net)["i(vd)"]
    assert abs(got - ref) <= 1e-9 * abs(ref), (got, ref)
    assert abs(ref) > 1e-6  # the device conducts


def test_process_parameters_are_ngspices_formulas():
    """The derivation against the formulas written out here (SI units, 27 °C)."""
    from diracvi.components._mos1 import process_parameters

    eps0, q, vt = 8.854214871e-12, 1.6021766208e-19, 1.38064852e-23 * 300.15 / 1.6021766208e-19
    tox, u0, nsub, nss = 30e-9, 450.0, 2e16, 4e10
    cox = 3.9 * eps0 / tox
    eg = 1.16 - 7.02e-4 * 300.15**2 / (300.15 + 1108)
    for sign, tpg in ((1.0, 1), (1.0, 0), (-1.0, -1)):
        got = process_parameters(sign, {"tox": tox, "u0": u0, "nsub": nsub, "nss": nss,
                                        "tpg": tpg}, "test")  # fmt: skip
        phi = 2 * vt * np.log(nsub * 1e6 / 1.45e16)
        gamma = np.sqrt(2 * 11.7 * eps0 * q * nsub * 1e6) / cox
        gate = 3.2 if tpg == 0 else 3.25 + eg / 2 - sign * tpg * eg / 2
        vfb = gate - (3.25 + eg / 2 + sign * phi / 2) - nss * 1e4 * q / cox
        want = {"kp": u0 * 1e-4 * cox, "phi": phi, "gamma": gamma, "cox": cox,
                "vto": vfb + sign * (gamma * np.sqrt(phi) + phi)}  # fmt: skip
        for key, value in want.items():
            assert got[key] == pytest.approx(value, rel=1e-12), (sign, tpg, key)
    given = process_parameters(1.0, {"tox": tox, "kp": 1e-4, "vto": 0.5, "nsub": nsub}, "t")
    assert (given["kp"], given["vto"]) == (1e-4, 0.5)  # given values win
    assert process_parameters(1.0, {"nsub": nsub}, "t")["phi"] == 0.6  # no TOX: no derivation


# ------------------------------------------------------------------ Meyer
def _devqmeyer(vgs, vgd, von, vdsat, phi, cox):
    """ngspice's DEVqmeyer (half capacitances), transcribed region by region."""
    vgst = vgs - von
    vdsat = max(vdsat, 0.025)
    if vgst <= -phi:
        return 0.0, 0.0, cox / 2
    if vgst <= -phi / 2:
        return 0.0, 0.0, -vgst * cox / (2 * phi)
    vds = vgs - vgd
    if vgst <= 0:
        cgb = -vgst * cox / (2 * phi)
        cgs = vgst * cox / (1.5 * phi) + cox / 3
        if vds >= vdsat:
            return cgs, 0.0, cgb
        d2 = (2 * vdsat - vds) ** 2
        return cgs * (1 - (vdsat - vds) ** 2 / d2), cgs * (1 - vdsat**2 / d2), cgb
    if vdsat <= vds:
        return cox / 3, 0.0, 0.0
    d2 = (2 * vdsat - vds) ** 2
    return cox * (1 - (vdsat - vds) ** 2 / d2) / 3, cox * (1 - vdsat**2 / d2) / 3, 0.0


# the PMOS in `-m slow` (the default suite's time on CI): the same law with signs flipped,
# whose signs tests/test_transistors.py's CMOS inverter checks against ngspice by default
@pytest.mark.parametrize("kind", ["nmos", pytest.param("pmos", marks=pytest.mark.slow)])
def test_meyer_capacitances_are_ngspices_in_every_region(kind):
    """Twice DEVqmeyer in each region and both modes (source/drain swapped for V_DS < 0,
    ``von`` from V_BS or V_BD, ``vdsat = max(V_GST, 0)``), to 1e-12 away from the C¹
    rounding of the region corners."""
    sign = 1.0 if kind == "nmos" else -1.0
    p = dict(vto=0.8, gamma=0.5, phi=0.7, cox=3e-14)
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(400):
        vs, vd, vb = 0.0, rng.uniform(-3, 3), rng.uniform(-2, 0.3)
        vg = rng.uniform(-1.5, 4.0)
        forward = vd >= vs
        src, drn = (vs, vd) if forward else (vd, vs)
        bs = vb - src
        s = (
            np.sqrt(p["phi"] - bs)
            if bs <= 0
            else max(0, np.sqrt(p["phi"]) - bs / (2 * np.sqrt(p["phi"])))
        )
        von = p["vto"] + p["gamma"] * (s - np.sqrt(p["phi"]))
        vgst, vdsat = vg - src - von, max(vg - src - von, 0.0)
        vds = drn - src
        corners = (-p["phi"], -p["phi"] / 2, 0.0)
        if min(abs(vgst - c) for c in corners) < 0.02 or abs(vds - max(vdsat, 0.025)) < 0.05:
            continue
        if abs(vd - vs) < 1e-3:
            continue
        hs, hd, hb = _devqmeyer(vg - src, vg - drn, von, vdsat, p["phi"], p["cox"])
        want = (hs, hd, hb) if forward else (hd, hs, hb)
        got = meyer_capacitances(
            sign * (vg - vs), sign * (vg - vd), sign * (vg - vb), kind=kind, vto=sign * p["vto"],
            gamma=p["gamma"], phi=p["phi"], cox=p["cox"],
        )  # fmt: skip
        for g, w in zip(got, want, strict=True):
            assert float(g) == pytest.approx(2 * w, rel=1e-12, abs=1e-12 * p["cox"])
        region = (
            "acc" if vgst <= -p["phi"] else "dep" if vgst <= 0 else "sat" if vds >= vdsat else "lin"
        )
        seen.add((region, forward))
    assert len(seen) == 8  # every region in both modes was checked


MEYER_INVERTER = """CMOS inverter with Meyer's capacitances, RD/RS and bulk junction capacitances
vdd vdd 0 5
vin a 0 PULSE(0 5 10n 2n 2n 20n 50n)
rin a g 2k
mp out g vdd vdd pch L=1u W=20u
mn out g 0 0 nch L=1u W=10u
cl out 0 20f
.model nch NMOS (LEVEL=1 VTO=0.7 KP=110u GAMMA=0.4 LAMBDA=0.04 PHI=0.7 TOX=20n CGSO=0.2n
+ CGDO=0.2n RD=20 RS=10 CBD=5f CBS=5f PB=0.9 MJ=0.4)
.model pch PMOS (LEVEL=1 VTO=-0.7 KP=50u GAMMA=0.57 LAMBDA=0.05 PHI=0.8 TOX=20n CGSO=0.2n
+ CGDO=0.2n RD=30 RS=15 CBD=8f CBS=8f)
.tran 0.1n 60n
.end
"""


@pytest.mark.slow
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_meyer_inverter_agrees_with_ngspice():
    """The inverter above, from diracvi's own operating point (no UIC), midpoint at a fixed
    5 ps: ``v(out)`` and the gate ``v(g)`` within 1e-3 of their peaks of a fine ngspice
    run. Without them (TOX dropped) the gate is off by far more."""
    read = spice.read(MEYER_INVERTER)
    t, ref = ng.ngspice(MEYER_INVERTER, ("v(out)", "v(g)"), tmax=read.stop / 40000)
    result = spice.run(read, dt=5e-12, solver=SOLVER)
    for probe in ("v(out)", "v(g)"):
        mine = np.interp(t, result.time, result[probe])
        err = np.max(np.abs(mine - ref[probe])) / np.max(np.abs(ref[probe]))
        assert err <= 1e-3, (probe, err)
    plain = spice.run(MEYER_INVERTER.replace("TOX=20n ", ""), dt=5e-12, solver=SOLVER)
    err = np.max(np.abs(np.interp(t, plain.time, plain["v(g)"]) - ref["v(g)"])) / 5.0
    assert err > 1e-2, err


FINE_ENOUGH = ".options reltol=1e-6 abstol=1e-14 vntol=1e-10 chgtol=1e-17"


@pytest.mark.slow
@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_meyer_inverter_under_variable_steps_agrees_with_ngspice():
    """The inverter above over its first edge under diracvi's own variable steps (no
    ``dt``): ``v(out)``, ``v(g)`` and the input current within 1e-3 of their peaks of a
    fine ngspice run (docs/circuits.md, "Variable steps with Meyer's capacitances"; on
    2026-11-25 this run stopped at the edge)."""
    deck = MEYER_INVERTER.replace(".tran 0.1n 60n", ".tran 0.1n 25n")
    read = spice.read(deck)
    probes = ("v(out)", "v(g)", "i(vin)")
    # reltol 1e-6: at ngspice's finest settings (reltol 1e-7) its run stops at the edge
    # ("timestep too small") and returns only the part before it
    t, ref = ng.ngspice(deck, probes, tmax=read.stop / 20000, options=FINE_ENOUGH)
    assert t[-1] >= read.stop * (1 - 1e-9), t[-1]
    result = spice.run(read)
    assert result.trajectory.status == 0
    mine = result.at(t)
    for probe in probes:
        err = np.max(np.abs(mine[probe] - ref[probe])) / np.max(np.abs(ref[probe]))
        assert err <= 1e-3, (probe, err)


# ------------------------------------------------------------------ power balance
STAGE = """NMOS stage, gate through a resistor
vdd vdd 0 10
vin a 0 SIN(2 1 5meg)
rg a g 5k
rd vdd d 20k
cl d 0 200f
m1 d g 0 0 nch L=2u W=20u
.model nch NMOS (LEVEL=1 VTO=1 KP=50u LAMBDA=0.02 GAMMA=0.5 PHI=0.65 TOX=25n)
.tran 1n 400n
.end
"""


@pytest.mark.slow  # ~50 s
def test_discrete_power_balance_with_meyer_capacitances_accounts_for_every_watt():
    r"""Midpoint at fixed step, at each interior node ``t_k`` (node voltages from the
    multipliers, branch currents ``ī = (Δq_{k−1} + Δq_k)/2h``): the sources' work =
    Δ(load energy) + both resistors' ``R ī² h`` + the channel's and junctions' work + the
    work into Meyer's ports ``Σ_x V_x ī_x h``, ``ī_x`` the mean of the two steps' currents
    ``C_x(ȳ) Δy_x/h`` (Meyer's law at the step's mean voltages). Residual ≤ 1e-10 of the
    largest term; Meyer's term is a sizeable share."""
    result = spice.run(STAGE, dt=0.5e-9, solver=SOLVER)
    traj = result.trajectory
    h, k = float(traj.dt), slice(1, -1)

    nodes = MidpointNodes(traj)
    coord, node_current = nodes.coord, nodes.node_current

    def at_nodes(i):
        return (i[:-1] + i[1:]) / 2

    tau = 1e-12  # diracvi.components.mosfet.TAU
    y = {x: coord(f"m1.y{x}") / tau for x in ("gs", "gd", "gb")}
    ybar = {x: (v[:-1] + v[1:]) / 2 for x, v in y.items()}
    cox = 3.9 * 8.854214871e-12 / 25e-9 * 20e-6 * 2e-6  # ε_ox/TOX · W · L
    caps = meyer_capacitances(
        ybar["gs"], ybar["gd"], ybar["gb"], kind="nmos", vto=1.0, gamma=0.5, phi=0.65, cox=cox
    )
    meyer = {x: at_nodes(np.asarray(c) * np.diff(y[x]) / h) for x, c in zip(y, caps, strict=True)}
    v = {n: result[f"v({n})"][k] for n in ("a", "g", "d")}
    volts = {"gs": v["g"], "gd": v["g"] - v["d"], "gb": v["g"]}
    # Meyer's law to 1e-9: ȳ = V is read back from τ·V through Newton at ε‖w‖/h
    assert np.max(np.abs(node_current("m1.sg") - meyer["gs"])) <= 1e-9 * np.max(np.abs(meyer["gs"]))
    supply = -(10.0 * node_current("vdd.q") + v["a"] * node_current("vin.q")) * h
    q = coord("cl.q")
    qbar = (q[:-1] + q[1:]) / 2
    stored = np.diff(qbar**2 / (2 * 200e-15))
    dissipated = (20e3 * node_current("rd.q") ** 2 + 5e3 * node_current("rg.q") ** 2) * h
    device = v["d"] * (node_current("m1.q") - node_current("m1.qbd")) * h
    gate = sum(volts[x] * meyer[x] for x in meyer) * h
    terms = (supply, stored, dissipated, device, gate)
    scale = max(np.max(np.abs(x)) for x in terms)
    residual = supply - stored - dissipated - device - gate
    assert np.max(np.abs(residual)) <= 1e-10 * scale, np.max(np.abs(residual)) / scale
    # Meyer's work is small beside the supply's here, but 10⁶ times the residual: the
    # balance fails by far if it is left out
    assert np.max(np.abs(gate)) > 1e6 * np.max(np.abs(residual))


# ------------------------------------------------------------------ gradients
def _stage_output(kp, vto, steps=60):
    from diracvi import components as cp

    c = cp.Circuit("cs")
    c.add(cp.VoltageSource(10.0, name="VDD"), p="vdd", n="0")
    c.add(cp.VoltageSource(cp.Sine(2.0, 0.5, 20e6), name="VIN"), p="a", n="0")
    c.add(cp.Resistor(5e3, name="RG"), p="a", n="g")
    c.add(cp.Resistor(20e3, name="RD"), p="vdd", n="d")
    c.add(cp.Capacitor(200e-15, name="CL", v0=4.5), p="d", n="0")
    c.add(cp.MOSFET("nmos", vto, kp, 0.02, 20e-6, 2e-6, 0.5, 0.65, cox=1.38e-3, rd=50.0,
                    cbd=5e-15, v0=(2.0, 2.0 - 4.5, 2.0), name="M1"),
          d="d", g="g", s="0", b="0")  # fmt: skip
    built = c.build()
    traj = dv.simulate(built.system, built.q0, built.p0, dt=1e-9, steps=steps,
                       discretization="midpoint", solver=SOLVER)  # fmt: skip
    return traj.q[-1, built.system.coords.index("CL.q")]


@pytest.mark.slow  # ~90 s each
@pytest.mark.parametrize(("arg", "eps"), [(0, 1e-9), (1, 1e-6)], ids=["KP", "VTO"])
def test_gradient_to_kp_and_vto_through_meyer_matches_central_differences(arg, eps):
    x = [50e-6, 1.0]
    grad = float(jax.grad(_stage_output, argnums=arg)(*x))
    up, down = list(x), list(x)
    up[arg] += eps
    down[arg] -= eps
    fd = (float(_stage_output(*up)) - float(_stage_output(*down))) / (2 * eps)
    assert abs(grad - fd) <= 1e-5 * abs(fd), (grad, fd)
    assert abs(fd) > 0
