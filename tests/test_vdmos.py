"""ngspice's VDMOS (``M d g s model`` with a ``VDMOS`` card): its static currents against
ngspice's ``.dc`` sweeps for both polarities, its gate–drain capacitance against
ngspice's ``DevCapVDMOS`` formula and against ngspice's transient current through it, and
the refusal of card parameters diracvi does not implement."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.components.vdmos import gate_drain_capacitance, gate_drain_charge

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

SWEEP = """vdmos sweep
vd d 0 0
vg g 0 0
m1 d g 0 q1
.model q1 VDMOS ({card})
.end
"""
CARDS = [
    ("NMOS", "VTO=1.5 KP=0.8 KSUBTHRES=0.05 SUBSHIFT=0.1 IS=1e-12 N=1.3", 1.0),
    ("PMOS", "VTO=-2 KP=2 PCHAN", -1.0),
    # channel-length modulation and mobility degradation, read at the device's own v_ds
    # and v_gs in the inverse mode too (ngspice's t0 = 1 + lambda*vds, t1 = 1 + theta*vgs)
    ("NMOS", "VTO=1.5 KP=0.8 KSUBTHRES=0.05 LAMBDA=0.03 THETA=0.05 MTRIODE=0.8", 1.0),
    ("PMOS", "VTO=-2 KP=2 LAMBDA=0.003 THETA=0.08 PCHAN", -1.0),
    # ng_inv_vdmos's card without RG and RB
    pytest.param("deck", "cgdmin=0.2p cgdmax=1p a=2 cgs=0.5p cjo=0.1p", 1.0,
                 marks=pytest.mark.slow),
]  # fmt: skip


def terminal_current(net, vgs, vds):
    """The current into the drain of ``m1`` of ``net`` (channel and body diode, no series
    resistances) from the parts' forces."""
    nodes = {p.name: (p, n) for p, n in spice.read(net).circuit._parts}
    channel, (body, pins) = nodes["m1"][0], nodes["m1:body"]
    idx = {c: j for j, c in enumerate(channel.coords)}
    anode_is_drain = pins["p"] == "d"

    def one(gs, ds):
        v = jnp.zeros(len(channel.coords)).at[idx["wg"]].set(gs).at[idx["w"]].set(ds)
        v = v.at[idx["wbd"]].set(-ds)
        f = -channel.force(jnp.zeros(len(channel.coords)), v)
        vd = ds if anode_is_drain else -ds  # the diode's anode-to-cathode voltage
        i_body = -body.force(jnp.zeros(2), jnp.array([0.0, vd]))[1]
        return f[idx["w"]] - f[idx["wbd"]] + (i_body if anode_is_drain else -i_body)

    return np.asarray(jax.jit(jax.vmap(one))(jnp.asarray(vgs), jnp.asarray(vds)))


@needs_ngspice
@pytest.mark.parametrize(("kind", "card", "s"), CARDS)
def test_static_currents_are_ngspices(kind, card, s):
    """The drain current over a (V_DS, V_GS) grid — cutoff, weak inversion, linear,
    saturation, the inverse mode with the body diode forward — equals ngspice's ``.dc``
    to 1e-9 relative + 1e-11 A (diracvi's channel part keeps level 1's G_min = 1e-12 S
    across its bulk–drain branch, a leak ngspice's VDMOS has not)."""
    net = SWEEP.format(card=card)
    out, _ = ng.device_sweep(net, "m1", (-0.6, 5, 0.1), (-1, 5, 0.25), ("v(d)", "v(g)", "i(vd)"), s)
    mine = terminal_current(net, out["v(g)"], out["v(d)"])
    excess = np.abs(mine + out["i(vd)"]) - 1e-9 * np.abs(mine) - 1e-11
    assert np.max(excess) <= 0.0
    i_d = s * mine
    assert np.count_nonzero(np.abs(i_d) < 1e-9) >= 10  # cutoff
    assert np.count_nonzero(i_d > 1e-3) >= 100 and np.count_nonzero(i_d < -1e-6) >= 10


def test_gate_drain_capacitance_is_ngspices_formula():
    """``C_GD`` equals ngspice's ``DevCapVDMOS`` closed form (tanh above 0 V, atan below,
    between CGDMIN and CGDMAX), and the port's charge is its integral: ``dQ/dV = C``
    (autodiff) and ``Q(0) = 0``."""
    cmin, cmax, a = 0.2e-12, 1e-12, 2.0
    v = np.linspace(-30.0, 30.0, 2001)
    s = (cmax - cmin) / (1.0 + math.pi / 2.0)
    y = cmax - s
    expected = np.where(v > 0.0, s * np.tanh(a * v) + y, s * np.arctan(a * v) + y)
    # one compiled function for both (eager JAX compiles every primitive on its own)
    both = jax.jit(
        lambda x: (
            gate_drain_capacitance(x, cmin, cmax, a),
            jax.grad(lambda y: jnp.sum(gate_drain_charge(y, cmin, cmax, a)))(x),
            gate_drain_charge(0.0 * x[0], cmin, cmax, a),
        )
    )
    c, dq, q0 = (np.asarray(z) for z in both(jnp.asarray(v)))
    assert np.max(np.abs(c - expected)) <= 1e-15 * cmax
    assert cmin < c.min() < cmin * 1.1 and cmax * 0.999 < c.max() <= cmax
    assert np.max(np.abs(np.asarray(dq) - expected)) <= 1e-14 * cmax
    assert float(q0) == 0.0


RAMP = """vdmos gate-drain ramp
vg g 0 pwl(0 -10 20u 10)
vd d 0 0
m1 d g 0 q1
.model q1 VDMOS (cgdmin=0.2p cgdmax=1p a=2{pchan})
.tran 10n 20u
.end
"""


@needs_ngspice
@pytest.mark.parametrize("pchan", ["", " pchan"])
def test_gate_current_under_a_ramp_is_ngspices(pchan):
    """A gate ramp of 1 V/µs from −10 V to 10 V with drain and source grounded: the gate
    current is ``C_GD(type·V_G) dV/dt`` alone (no CGS, no channel or diode current at
    ``V_DS = 0``); ngspice's transient gives it to 1e-3 of its peak away from the ramp's
    start, and diracvi's closed form agrees."""
    net = RAMP.format(pchan=pchan)
    t, values = ng.fine_transient(net, ("i(vg)",), points=2000)
    sign = -1.0 if pchan else 1.0
    vg = -10.0 + 1e6 * t
    expected = -1e6 * np.asarray(
        gate_drain_capacitance(jnp.asarray(sign * vg), 0.2e-12, 1e-12, 2.0)
    )
    late = t > 0.5e-6
    err = np.max(np.abs(values["i(vg)"][late] - expected[late]))
    assert err <= 1e-3 * np.max(np.abs(expected))


@pytest.mark.parametrize(
    ("card", "match"),
    [
        ("RQ=0.1 VQ=2", r"line 4: model 'q1' \(line 5\): VDMOS parameter RQ=0.1 is not supported"),
        ("RQ=0.1", r"VDMOS parameter RQ=0.1 is not supported"),
        ("BV=100", r"VDMOS parameter BV=100 is not supported"),
    ],
)
def test_unimplemented_parameters_are_refused_by_name(card, match):
    """A card parameter diracvi does not implement is refused at the element line, naming
    the parameter, its value and the model's line."""
    net = (
        f"refusal\nvd d 0 1\nvg g 0 1\nm1 d g 0 q1\n.model q1 VDMOS ({card})\n.tran 1n 10n\n.end\n"
    )
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(net)


@needs_ngspice
def test_names_ngspice_does_not_know_are_ignored_as_it_ignores_them():
    """ngspice 39 ignores a card name outside its VDMOS model table with a warning
    ("unrecognized parameter (vt0) - ignored": VT0 is no VDMOS alias, MTR is no name;
    it reads MTRIODE): diracvi notes them and runs what ngspice runs, VTO at its default 0.
    RTHJC (read only by the thermal instance) is noted too, a temperature coefficient is
    read (no effect at T = TNOM); RDS is a shunt from drain to source. The drain current through
    the shunt and the channel equals ngspice's operating point."""
    net = (
        "ignored names\nvd d 0 5\nvg g 0 3\nm1 d g 0 q1\n"
        ".model q1 VDMOS (VT0=2 KP=1 MTR=3 RTHJC=1 TCVTH=2m RDS=50 LAMBDA=0.02)\n"
        ".tran 1n 10n\n.end\n"
    )
    notes = spice.read(net).notes
    for word in ("VT0", "MTR", "RTHJC"):
        assert any(f"VDMOS {word} ignored" in n for n in notes), word
    assert not any("TCVTH" in n for n in notes)
    ref = ng.operating_point(net)
    assert ref["i(vd)"] == pytest.approx(-(0.5 * 9 * 1.1 + 5 / 50), rel=1e-9)
    mine = spice.run(net)["i(vd)"][-1]
    assert mine == pytest.approx(ref["i(vd)"], rel=1e-8)


PARALLEL = """vdmos m
VDD vdd 0 12
RL vdd d1 20
VG1 g1 0 4.2
M1 d1 g1 s1 nv M=3
RS1 s1 0 0.5
VD2 d2 0 -0.6
M2 d2 0 0 nv m=2.5
VG3 g3 0 -3
RL3 d3 0 50
M3 d3 g3 vdd pv M=2
.model nv VDMOS(VTO=2.5 KP=2 LAMBDA=0.01 RD=0.05 RS=0.02 RG=3 RDS=1e6 RB=0.01 IS=1e-12
+ N=1.1 CJO=1n CGS=1n CGDMIN=0.1n CGDMAX=1n A=0.5 THETA=0.05)
.model pv VDMOS(PCHAN VTO=-2 KP=1.5 RD=0.1 RS=0.05 IS=2e-12 RDS=1e5)
.tran 1u 10u
.end
"""


@needs_ngspice
def test_the_parallel_multiplier_m_is_ngspices_at_the_operating_point():
    """``M=m`` on the line scales KP, IS (the body diode, forward-biased in M2) and divides
    RD, RS, RG, RDS and RB, as ngspice's vdmosset/vdmostemp: every source's current at
    the operating point (an M ignored puts VDD's off by a factor near 3)."""
    ref = ng.operating_point(PARALLEL)
    op = spice.operating_point(spice.read(PARALLEL))
    for source in ("VDD", "VD2"):
        assert op.currents[source] == pytest.approx(ref[f"i({source.lower()})"], rel=1e-9)


def test_m_devices_in_parallel_are_one_instance_with_m():
    """With its gate capacitances (scaled by M as ngspice ≥ 40 does; ngspice 39 leaves
    them per device), an instance with ``M=2`` is two instances side by side: the same
    switching transient to round-off."""
    deck = """vdmos parallel
VDD vdd 0 10
RL vdd d 5
VG in 0 PULSE(0 8 10n 20n 20n 200n 500n)
RG in g 10
{devices}
.model nv VDMOS(VTO=2.5 KP=2 RD=0.05 RS=0.02 RG=3 IS=1e-12 CJO=1n CGS=1n CGDMIN=0.1n
+ CGDMAX=1n A=0.5)
.tran 1n 400n
.end
"""
    one = spice.run(deck.format(devices="M1 d g 0 nv M=2"), dt=1e-9)
    two = spice.run(deck.format(devices="M1 d g 0 nv\nM2 d g 0 nv"), dt=1e-9)
    for name in ("v(d)", "v(g)", "i(vdd)", "i(vg)"):
        scale = np.max(np.abs(two[name]))
        assert np.max(np.abs(one[name] - two[name])) <= 1e-9 * scale, name


def test_the_thermal_instance_is_refused_by_name():
    net = (
        "thermal\nvd d 0 1\nvg g 0 1\nm1 d g 0 tj tc q1 thermal\n.model q1 VDMOS (RTHJC=1)\n"
        ".tran 1n 10n\n.end\n"
    )
    with pytest.raises(spice.NetlistError, match=r"line 4: .*thermal nodes"):
        spice.read(net)


def test_a_node_behind_a_gate_and_a_current_source_gets_gmin():
    """crss_coss_ciss.sp's ``M2 d2 0 d2`` (drain and source one node, the gate grounded)
    fed by a VCCS: node d2 reaches ground only through the gate (capacitances, no DC
    current) and a current source, so its DC voltage is undefined and it gets ngspice's
    GMIN shunt; a node reached through a current source alone stays the cut-set error."""
    net = (
        "gate island\nvp p 0 PULSE(0 1m 10n 10n 10n 1 2)\nm2 d2 0 d2 q1\ng2 0 d2 p 0 1\n"
        ".model q1 VDMOS (CGS=1n CGDMAX=1n CGDMIN=10p)\n.tran 1n 100n\n.end\n"
    )
    notes = spice.read(net).notes
    assert any("node 'd2' has no DC path to ground" in n for n in notes)
    alone = "cut\nvp p 0 1\ng2 0 x p 0 1\ng3 x 0 p 0 1\n.tran 1n 10n\n.end\n"
    with pytest.raises(spice.NetlistError, match=r"\['x'\] reach ground only through current"):
        spice.read(alone)
