"""Linear controlled sources E (VCVS), F (CCCS), G (VCCS), H (CCVS): closed forms, live
ngspice, the per-step discrete power balance, gradients, netlist lines and their errors
(docs/circuits.md, "Controlled sources in the Lagrange–Dirac structure")."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import _ngspice as ng
import diracvi as dv
from diracvi import components as cp
from diracvi import spice
from diracvi.spice import waveforms


def _run(circuit, dt, steps, discretization="midpoint"):
    built = circuit.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=dt, steps=steps, discretization=discretization
    )
    return built, traj, waveforms(built, traj)


# ------------------------------------------------------------------ closed forms
def test_inverting_amplifier_gain_is_the_closed_form_at_every_node():
    """E as an op-amp of gain A: ``v_out = −(R2/R1) v_in / (1 + (1 + R2/R1)/A)``; the
    circuit is resistive, so midpoint's node voltages are exact (round-off)."""
    r1, r2, gain = 1e3, 10e3, 999e3
    c = cp.Circuit("inverting")
    c.add(cp.VoltageSource(cp.Sine(0, 1, 1e3), name="V1"), p="in", n="0")
    c.add(cp.Resistor(r1, name="R1"), p="in", n="m")
    c.add(cp.Resistor(r2, name="R2"), p="m", n="out")
    c.add(cp.VCVS(gain, name="E1"), p="out", n="0", cp="0", cn="m")
    _, _, w = _run(c, 1e-5, 200)
    expected = -(r2 / r1) * w["v(in)"] / (1 + (1 + r2 / r1) / gain)
    assert np.max(np.abs(w["v(out)"] - expected)) <= 1e-12 * np.max(np.abs(expected))
    assert np.max(np.abs(w["v(out)"])) > 9.9  # it amplifies (and inverts: a sign flip fails)


def test_integrator_ramp_for_a_dc_input_is_the_finite_gain_closed_form():
    """The op-amp integrator (R into the inverting node m, C from m to out, E of gain A):
    ``v_m = V (1 − e^{−t/τ})``, ``τ = RC(1 + A)``, ``v_out = −A v_m`` — the ideal ramp
    ``−V t/RC`` to first order in ``t/τ``."""
    v, r, cap, gain = 1.0, 1e3, 1e-6, 999e3
    c = cp.Circuit("integrator")
    c.add(cp.VoltageSource(v, name="V1"), p="in", n="0")
    c.add(cp.Resistor(r, name="R1"), p="in", n="m")
    c.add(cp.Capacitor(cap, name="C1"), p="m", n="out")
    c.add(cp.VCVS(gain, name="E1"), p="out", n="0", cp="0", cn="m")
    _, traj, w = _run(c, 1e-5, 100)
    tau = r * cap * (1 + gain)
    exact = -gain * v * -np.expm1(-traj.t / tau)
    inner = slice(1, -1)  # the end nodes are extrapolated (diracvi.spice._probe)
    err = np.max(np.abs(w["v(out)"][inner] - exact[inner]))
    assert err <= 1e-9 * np.max(np.abs(exact))
    ramp = -v * traj.t / (r * cap)
    assert np.max(np.abs(exact - ramp)) <= 1e-5 * np.max(np.abs(ramp))  # it integrates


def test_vccs_into_an_rc_is_the_exponential():
    """G with ``gm·V`` out of node ``out`` (SPICE: from n+ through the source to n−) into
    R ∥ C: ``v_out = −gm R V (1 − e^{−t/RC})``, second order in h."""
    v, gm, r, cap = 1.0, 2e-3, 1e3, 1e-6
    errors = []
    for h in (1e-5, 5e-6):
        c = cp.Circuit("vccs")
        c.add(cp.VoltageSource(v, name="V1"), p="a", n="0")
        c.add(cp.Resistor(1e3, name="Ra"), p="a", n="0")
        c.add(cp.VCCS(gm, name="G1"), p="out", n="0", cp="a", cn="0")
        c.add(cp.Resistor(r, name="R1"), p="out", n="0")
        c.add(cp.Capacitor(cap, name="C1"), p="out", n="0")
        _, traj, w = _run(c, h, round(2e-3 / h))
        exact = -gm * r * v * -np.expm1(-traj.t / (r * cap))
        inner = slice(1, -1)
        errors.append(np.max(np.abs(w["v(out)"][inner] - exact[inner])) / (gm * r * v))
    assert errors[0] <= 3e-5, errors
    assert 3.5 <= errors[0] / errors[1] <= 4.5, errors  # second order


def test_cccs_current_mirror_and_ccvs_transresistance_are_exact():
    """F copies β times the current of a 0 V source (SPICE's ammeter: into its + node):
    ``v_out = V_cc − R2 β V1/R1``; H gives ``v_h = r · i(Vs)``."""
    beta, rt, r1, r2, vcc = 3.0, 2e3, 1e3, 500.0, 5.0
    c = cp.Circuit("mirror")
    c.add(cp.VoltageSource(cp.Sine(0.5, 0.5, 1e3), name="V1"), p="a", n="0")
    c.add(cp.Resistor(r1, name="R1"), p="a", n="b")
    c.add(cp.VoltageSource(0.0, name="Vs"), p="b", n="0")
    c.add(cp.VoltageSource(vcc, name="Vcc"), p="vcc", n="0")
    c.add(cp.Resistor(r2, name="R2"), p="vcc", n="out")
    c.add(cp.CCCS(beta, control="Vs", name="F1"), p="out", n="0")
    c.add(cp.CCVS(rt, control="Vs", name="H1"), p="h", n="0")
    c.add(cp.Resistor(1e3, name="R3"), p="h", n="0")
    _, _, w = _run(c, 1e-5, 100)
    inner = slice(1, -1)
    i_ref = w["v(a)"] / r1
    assert np.max(np.abs(w["i(Vs)"][inner] - i_ref[inner])) <= 1e-13
    assert np.max(np.abs(w["i(F1)"][inner] - beta * i_ref[inner])) <= 1e-13
    assert np.max(np.abs(w["v(out)"][inner] - (vcc - r2 * beta * i_ref)[inner])) <= 1e-11
    assert np.max(np.abs(w["v(h)"][inner] - rt * i_ref[inner])) <= 1e-11
    assert np.max(np.abs(w["v(h)"])) > 1.9


# ------------------------------------------------------------------ ngspice
NETLISTS = {
    "E": (  # the op-amp integrator, flat (e1 3 0 0 2 999k)
        """op-amp integrator from a VCVS
v1 1 0 SIN(0 1 1k)
r1 1 2 1k
c1 2 3 100n
e1 3 0 0 2 999k
.tran 1u 2m uic
.end
""",
        # v(2), the virtual ground (a few µV), is what tells the sign of the gain: with
        # the opposite sign the loop is unstable, but only at τ = RC(A − 1) ≈ 100 s, so
        # v(3) and i(v1) are almost unchanged over 2 ms
        ("v(3)", "v(2)", "i(v1)"),
    ),
    "E-subckt": (  # the acceptance case: the E source inside a subcircuit
        """op-amp integrator, the amplifier a subcircuit
.subckt opamp inp inn out
e1 out 0 inp inn 999k
.ends opamp
v1 1 0 SIN(0 1 1k)
r1 1 2 1k
c1 2 3 100n
x1 0 2 3 opamp
.tran 1u 2m uic
.end
""",
        ("v(3)", "v(2)", "i(v1)"),
    ),
    "G": (
        """VCCS transconductance stage into an RC
v1 a 0 SIN(0 1 1k)
ra a 0 1k
g1 out 0 a 0 2m
r1 out 0 1k
c1 out 0 1u
.tran 1u 2m uic
.end
""",
        ("v(out)",),
    ),
    "F": (
        """CCCS current mirror into an RC
v1 a 0 SIN(0 1 1k)
r1 a b 1k
vs b 0 0
f1 out 0 vs 3
r2 out 0 500
c2 out 0 1u
.tran 1u 2m uic
.end
""",
        ("v(out)", "i(vs)"),
    ),
    "H": (
        """CCVS transresistance stage into an RL
v1 a 0 SIN(0 1 1k)
r1 a b 1k
vs b 0 0
h1 out 0 vs 2k
r2 out x 1k
l1 x 0 50m
.tran 1u 2m uic
.end
""",
        ("v(out)", "v(x)"),
    ),
}


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
# E (flat), G and H in `-m slow` (6 s each; the default suite's time on CI): by default the
# E source in a subcircuit and F against ngspice, and G and H against closed forms
# (test_vccs_into_an_rc_is_the_exponential, test_cccs_current_mirror_and_ccvs_...)
@pytest.mark.parametrize(
    "kind",
    [
        k if k in ("E-subckt", "F") else pytest.param(k, marks=pytest.mark.slow)
        for k in sorted(NETLISTS)
    ],
)
def test_controlled_sources_agree_with_ngspice(kind):
    """Each source in a netlist, against a fine ngspice run (max step TSTOP/40000) at
    ngspice's own time points, for t > 0: ≤ 1e-3 of each probe's peak."""
    netlist, probes = NETLISTS[kind]
    t, ref = ng.ngspice(netlist, probes, tmax=2e-3 / 40000)
    result = spice.run(netlist, dt=1e-6)  # a fixed step: .tran's 1 µs, midpoint
    after = t > 0
    for probe in probes:
        mine = np.interp(t, result.time, result[probe])
        peak = np.max(np.abs(ref[probe]))
        err = np.max(np.abs(mine - ref[probe])[after]) / peak
        assert err <= 1e-3, (kind, probe, err)
        assert peak > 1e-6  # a probe that moves (3 µV … 3 V, 1 mA)


# ------------------------------------------------------------------ power balance
ALL_FOUR = """every controlled source, with stored energy and losses
v1 in 0 SIN(0.2 1 2k)
r1 in a 1k
vs a 0 0
e1 e 0 in 0 2
r2 e b 1k
c1 b 0 1u
g1 g 0 b 0 1m
r3 g 0 1k
l1 g 0 10m
f1 f 0 vs 3
r4 f 0 500
c2 f 0 1u
h1 h 0 vs 2k
r5 h k 1k
l2 k 0 5m
i1 0 b SIN(0 1m 3k)
.tran 2u 2m uic
.end
"""


def test_discrete_power_balance_accounts_for_every_watt():
    r"""Midpoint: at each interior node ``t_k`` the node voltages ``v = −λ_k/h`` and the
    node currents ``ī = (Δq_{k−1} + Δq_k)/2h`` give, over the step from ``t_{k−½}`` to
    ``t_{k+½}``, independent sources' work = Δ(stored energy) + dissipated + work done
    ON the controlled sources' output ports, each term from its own element law."""
    result = spice.run(ALL_FOUR, dt=2e-6)  # a fixed step (the balance is per step)
    net, traj = result.netlist, result.trajectory
    h = float(traj.dt)
    t = traj.t
    k = slice(1, -1)  # interior nodes

    def v(node):
        return np.zeros(len(t) - 2) if node == "0" else result[f"v({node})"][k]

    def charge(name):
        return traj.q[:, traj.coords.index(net.assembly.currents[name])]

    def node_current(name):
        dq = np.diff(charge(name))
        return (dq[:-1] + dq[1:]) / (2 * h)

    def half_steps(values):  # e_{k+½} − e_{k−½} of a per-step quantity
        return np.diff(values)

    mid = t[:-1] + h / 2
    u1 = 0.2 + np.sin(2 * np.pi * 2e3 * mid)
    ui = 1e-3 * np.sin(2 * np.pi * 3e3 * mid)
    sources = -(u1[:-1] + u1[1:]) / 2 * node_current("v1") * h
    # i1 from 0 to b: its node voltage v(0) − v(b), its current fixed by its constraint
    sources -= (0.0 - v("b")) * node_current("i1") * h
    assert np.max(np.abs(node_current("i1") - (ui[:-1] + ui[1:]) / 2)) <= 1e-15
    stored = 0.0
    for name, c in (("c1", 1e-6), ("c2", 1e-6)):
        qbar = (charge(name)[:-1] + charge(name)[1:]) / 2
        stored = stored + half_steps(qbar**2 / (2 * c))
    for name, ell in (("l1", 10e-3), ("l2", 5e-3)):
        stored = stored + half_steps(0.5 * ell * (np.diff(charge(name)) / h) ** 2)
    dissipated = sum(
        r * node_current(name) ** 2 * h
        for name, r in (("r1", 1e3), ("r2", 1e3), ("r3", 1e3), ("r4", 500.0), ("r5", 1e3))
    )
    i_vs = node_current("vs")
    controlled = (
        2.0 * v("in") * node_current("e1") * h  # E: v_out = 2 v(in)
        + v("g") * 1e-3 * v("b") * h  # G: i_out = gm v(b)
        + v("f") * 3.0 * i_vs * h  # F: i_out = 3 i(vs)
        + 2e3 * i_vs * node_current("h1") * h  # H: v_out = 2k i(vs)
    )
    terms = (sources, stored, dissipated, controlled)
    scale = max(np.max(np.abs(x)) for x in terms)
    residual = sources - stored - dissipated - controlled
    assert np.max(np.abs(residual)) <= 1e-10 * scale, np.max(np.abs(residual)) / scale
    # not a balance of zeros: every kind of term is a sizeable part of the budget
    for x in terms:
        assert np.max(np.abs(x)) > 1e-2 * scale
    assert abs(np.sum(controlled)) > 1e-2 * np.sum(np.abs(sources))


# ------------------------------------------------------------------ gradients
# 11 s; gradients to every part's parameters are checked by default in tests/test_components.py
@pytest.mark.slow
def test_gradient_flows_to_a_transconductance():
    """``jax.grad`` of the RC's final charge with respect to ``gm`` (a traced part
    parameter) equals central differences and the closed form
    ``∂q_C/∂gm = −C R V (1 − e^{−T/RC})``."""
    v, r, cap, h, steps = 1.0, 1e3, 1e-6, 1e-5, 100

    def final_charge(gm):
        c = cp.Circuit("vccs")
        c.add(cp.VoltageSource(v, name="V1"), p="a", n="0")
        c.add(cp.Resistor(1e3, name="Ra"), p="a", n="0")
        c.add(cp.VCCS(gm, name="G1"), p="out", n="0", cp="a", cn="0")
        c.add(cp.Resistor(r, name="R1"), p="out", n="0")
        c.add(cp.Capacitor(cap, name="C1"), p="out", n="0")
        built = c.build()
        traj = dv.simulate(
            built.system, built.q0, built.p0, dt=h, steps=steps, discretization="midpoint"
        )
        return traj.q[-1, built.system.coords.index("C1.q")]

    gm = 2e-3
    grad = float(jax.grad(final_charge)(gm))  # built inside: gm is traced
    eps = 1e-7
    fd = (float(final_charge(gm + eps)) - float(final_charge(gm - eps))) / (2 * eps)
    assert abs(grad - fd) <= 1e-6 * abs(fd)
    exact = -cap * r * v * -np.expm1(-h * steps / (r * cap))
    assert abs(grad - exact) <= 1e-4 * abs(exact)


# ------------------------------------------------------------------ the rules
@pytest.mark.slow  # ~16 s
def test_retraction_steps_e_and_h_and_refuses_f_and_g_by_name():
    """The left-point rule: E and H step (first order); F and G are singular (their
    output flux never enters its equations), which the solvability check says before
    stepping and the netlist's rule list (``diracvi run``) reflects."""
    amp = "inverting amplifier\nv1 1 0 SIN(0 1 1k)\nr1 1 2 1k\nr2 2 3 10k\n"
    amp += "e1 3 0 0 2 999k\n.tran 1u 1m\n.end\n"
    res = spice.run(amp, discretization="retraction", dt=1e-6)
    gain = -10.0 / (1 + 11 / 999e3)
    assert np.max(np.abs(res["v(3)"] - gain * res["v(1)"])[1:-1]) <= 1e-3
    assert spice.read(amp).discretizations == ("midpoint", "retraction")
    for kind in ("F", "G"):
        netlist = spice.read(NETLISTS[kind][0])
        assert netlist.discretizations == ("midpoint",)
        with pytest.raises(dv.UnsolvableStepError, match=f"{kind.lower()}1.wo"):
            spice.run(netlist, discretization="retraction", steps=3)
    # left point: the node voltage at t_k is r times the current of the step after it
    res = spice.run(NETLISTS["H"][0], discretization="retraction", steps=50)
    traj = res.trajectory
    step_current = np.diff(traj.q[:, traj.coords.index("vs.q")]) / float(traj.dt)
    assert np.max(np.abs(res["v(out)"][:-1] - 2e3 * step_current)) <= 1e-9


# ------------------------------------------------------------------ netlists
@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("f1 3 0 VALUE={2*i(v1)}", r"line 3: .*the VALUE= and TABLE forms of F .*B source"),
        ("e1 3 0 1 2", r"line 3: expected 'Ename n\+ n- nc\+ nc- gain', got 5 fields"),
        ("f1 3 0 r1 2", r"line 3: the controlling element 'r1' must be a voltage source"),
        ("h1 3 0 vx 2", r"line 3 \(h1\): the controlling element 'vx' is not in circuit"),
        ("e1 3 0 1 0 {nope}", r"line 3: e1 gain: .*nope"),
        ("g1 3 0 1 0 1m gain=2", r"line 3: expected 'Gname n\+ n- nc\+ nc- transconductance'"),
    ],
)
def test_netlist_errors_name_the_line_and_the_form(line, match):
    body = f"title\nv1 1 0 1\n{line}\nr1 1 2 1k\nr2 3 0 1k\nr3 2 0 1k\n.tran 1u 1m\n.end\n"
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(body)


def test_topology_treats_controlled_outputs_as_sources_and_sensing_as_open():
    base = "title\nv1 1 0 1\nr1 1 0 1k\n"
    # an E output across a voltage source over-determines the loop, as two sources do
    with pytest.raises(spice.NetlistError, match=r"line 4 \(e1\) closes a loop of voltage"):
        spice.read(base + "e1 1 0 1 0 2\n")
    # a node reached only through a G output is a cut-set of current sources
    with pytest.raises(spice.NetlistError, match=r"through current sources \(line 4 \(g1\)\)"):
        spice.read(base + "g1 2 0 1 0 1m\nc1 2 3 1u\nr2 3 2 1k\n")
    # the sensing branch draws no current: a node seen only by it reaches ground through
    # nothing (SPICE's "no DC path"), which the reader refuses by name
    with pytest.raises(
        spice.NetlistError,
        match=r"nodes \['2', '4'\] reach ground only through current sources \(line 4 \(e1\)\)",
    ):
        spice.read(base + "e1 3 0 2 0 2\nr2 3 0 1k\nc1 2 4 1u\nr3 4 2 1k\n")


# 7 s, in `-m slow` (CI time): torn ≡ monolithic by default in tests/test_interconnect.py's
# theorem; the sense rows by the ngspice agreement of E and F above
@pytest.mark.slow
def test_circuit_monolithic_equals_interconnected_with_sense_rows():
    """The paper's theorem on a circuit with current control: the sense rows are
    ordinary interaction one-forms, so the monolithic system steps identically."""
    netlist = spice.read(NETLISTS["F"][0])
    run = dict(dt=1e-5, steps=50, discretization="midpoint")
    a = dv.simulate(netlist.system, netlist.q0, netlist.p0, **run)
    b = dv.simulate(netlist.system.monolithic(), netlist.q0, netlist.p0, **run)
    assert np.max(np.abs(a.q - b.q)) <= 1e-12 * max(1e-12, np.max(np.abs(a.q)))
    assert "sense(f1)" in netlist.system.interaction_names
    assert np.max(np.abs(a.multiplier("sense(f1)"))) <= 1e-12 * np.max(np.abs(a.multipliers))
