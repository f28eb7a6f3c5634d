"""The JFET (SPICE ``J``, ngspice 39's level 1 with Parker–Skellern's ``B``): its static
currents against ngspice's ``.dc`` sweeps in every region and both polarities, each model
parameter shown to matter, a transient against a fine ngspice run, the discrete power
balance, gradients, and the J line's errors (docs/circuits.md, "Transistors")."""

from __future__ import annotations

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import _ngspice as ng
import diracvi as dv
from _midpoint_nodes import MidpointNodes
from diracvi import components as cp
from diracvi import spice
from diracvi.components.jfet import channel_current, gate_current

SOLVER = dv.NewtonSolver(reuse_jacobian=False)
needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

SWEEP = """jfet sweep
vd d 0 0
vg g 0 0
j1 d g 0 jm {instance}
.model jm {kind}({card})
.end
"""
# (kind, card, instance): B ≠ 1 (the doping tail) and LAMBDA in both; AREA and M scale
CARDS = [
    ("NJF", "VTO=-1.5 BETA=2e-3 LAMBDA=0.03 B=0.7 IS=1e-12 PB=0.9", ""),
    ("PJF", "VTO=-1.2 BETA=1e-3 LAMBDA=0.05 B=1.3 IS=3e-13 PB=0.8", "2 M=3"),
    ("NJF", "", ""),  # ngspice's defaults
]


def terminal_currents(part, vgs, vds, sign):
    """``(I_D, I_G)`` into drain and gate of a J line's part (no RD/RS; ``sign`` = ±1 for
    NJF/PJF), from its force: ``I_D = I_ch − I_gd``, ``I_G = I_gs + I_gd`` (each flux
    velocity and force is type-normalised: a PJF's branches point the other way)."""
    idx = {c: j for j, c in enumerate(part.coords)}

    def one(gs, ds):
        v = jnp.zeros(len(part.coords))
        v = v.at[idx["wgs"]].set(sign * gs).at[idx["wgd"]].set(sign * (gs - ds))
        v = v.at[idx["wch"]].set(sign * ds)
        f = -part.force(jnp.zeros(len(part.coords)), v)
        return sign * (f[idx["wch"]] - f[idx["wgd"]]), sign * (f[idx["wgs"]] + f[idx["wgd"]])

    out = jax.vmap(one)(jnp.asarray(vgs), jnp.asarray(vds))
    return tuple(np.asarray(x) for x in out)


def _sweep(kind, card, instance):
    s = -1.0 if kind == "PJF" else 1.0
    net = SWEEP.format(kind=kind, card=card, instance=instance)
    # V_DS from −1.5 V (inverse mode, its gate–drain junction forward-biased up to 0.8 V)
    # to 6 V, V_GS from −3 V (cutoff, reverse gate) to −0.7 V
    probes = ("v(d)", "v(g)", "i(vd)", "i(vg)")
    return ng.device_sweep(net, "j1", (-1.5, 6, 0.125), (-3, -0.7, 0.1), probes, s)


def _errors(mine, out):
    i_d, i_g = mine
    return (
        np.abs(i_d + out["i(vd)"]) - 1e-9 * np.abs(i_d) - 1e-12,
        np.abs(i_g + out["i(vg)"]) - 1e-9 * np.abs(i_g) - 1e-12,
    )


@needs_ngspice
@pytest.mark.parametrize(("kind", "card", "instance"), CARDS)
def test_static_currents_are_ngspices_in_every_region(kind, card, instance):
    """Drain and gate currents over a (V_DS, V_GS) grid covering cutoff, linear,
    saturation, the inverse mode and reverse and forward gate bias equal ngspice's
    ``.dc`` sweep to 1e-9 relative or 1e-12 A."""
    out, part = _sweep(kind, card, instance)
    s = -1.0 if kind == "PJF" else 1.0
    vgs, vds = out["v(g)"], out["v(d)"]
    mine = terminal_currents(part, vgs, vds, s)
    err_d, err_g = _errors(mine, out)
    assert np.max(err_d) <= 0.0 and np.max(err_g) <= 0.0, (np.max(err_d), np.max(err_g))
    vto = float(re.search(r"VTO=(\S+)", card).group(1)) if "VTO" in card else -2.0
    gs, ds = s * vgs, s * vds
    vgst = np.where(ds >= 0, gs, gs - ds) - vto
    regions = {
        "cutoff": vgst <= 0,
        "linear": (vgst > 0) & (vgst >= np.abs(ds)),
        "saturation": (vgst > 0) & (vgst < np.abs(ds)),
        "inverse": ds < 0,
        "forward gate": gs - ds > 0.3,  # gate–drain (the inverse mode's gate–source)
    }
    for region, where in regions.items():
        assert np.count_nonzero(where) >= 10, region


@needs_ngspice
def test_every_model_parameter_changes_the_currents():
    """The card of the first sweep with one parameter removed at a time (so at ngspice's
    default) gives diracvi currents that miss ngspice's of the full card far beyond the
    tolerance above: the comparison sees each parameter (PB through B's
    ``(1 − B)/(PB − VTO)``)."""
    kind, card, instance = CARDS[0]
    out, _ = _sweep(kind, card, instance)
    for drop in ("LAMBDA", "B", "BETA", "VTO", "IS", "PB"):
        net = SWEEP.format(kind=kind, card=re.sub(rf"\b{drop}=\S+", "", card), instance=instance)
        part = ng.netlist_part(net, "j1")
        err_d, err_g = _errors(terminal_currents(part, out["v(g)"], out["v(d)"], 1.0), out)
        assert max(np.max(err_d), np.max(err_g)) > 1e-6, drop


def test_channel_current_is_shichman_hodges_with_the_doping_tail():
    """The law written out here: ``B = 1`` is ``β(1 + λV)(V_GST², V(2V_GST − V))``; the
    inverse mode is the forward law with source and drain exchanged; continuity across
    the saturation edge and ``V_DS = 0``."""
    p = dict(vto=-2.0, beta=1e-3, lambda_=0.04, b=1.0, pb=1.0)
    vgs, vds = -1.0, 0.6  # V_GST = 1 > V_DS: linear
    want = 1e-3 * (1 + 0.04 * vds) * vds * (2 * 1.0 - vds)
    assert float(channel_current(vgs, vgs - vds, **p)) == pytest.approx(want, rel=1e-14)
    vds = 3.0  # saturation
    want = 1e-3 * (1 + 0.04 * vds) * 1.0
    assert float(channel_current(vgs, vgs - vds, **p)) == pytest.approx(want, rel=1e-14)
    q = dict(vto=-2.0, beta=1e-3, lambda_=0.04, b=0.6, pb=0.8)
    for gs, gd in ((-1.0, -2.5), (-0.5, -0.1), (0.2, -1.9)):
        forward = float(channel_current(gs, gd, **q))
        assert float(channel_current(gd, gs, **q)) == pytest.approx(-forward, rel=1e-14)
    bfac = 0.4 / 2.8
    gst = 1.5  # saturation with the tail: β(1+λV)V_GST²(B + b V_GST)
    got = float(channel_current(gst - 2.0, gst - 2.0 - 4.0, **q))
    assert got == pytest.approx(1e-3 * (1 + 0.16) * gst**2 * (0.6 + bfac * gst), rel=1e-14)
    edge = float(channel_current(gst - 2.0, -2.0, **q))  # V_DS = V_GST: both formulas
    below = float(channel_current(gst - 2.0, -2.0 + 1e-9, **q))
    assert below == pytest.approx(edge, rel=1e-8)
    assert float(gate_current(-1.0, 1e-14, 1e-12)) == pytest.approx(
        -1e-14 * (1 + (3 * 0.025864186 / (np.e * -1.0)) ** 3) - 1e-12, rel=1e-6
    )


@pytest.mark.slow  # ~5 s: a compiled gradient per parameter
def test_gradients_reach_beta_vto_lambda_and_b():
    """``jax.grad`` of the part's drain current in the traced model parameters equals
    central differences."""

    def drain(x, arg):
        kw = dict(vto=-1.5, beta=2e-3, lambda_=0.03, b=0.7) | {arg: x}
        part = cp.JFET("njf", kw.pop("vto"), kw.pop("beta"), kw.pop("lambda_"), b=kw["b"],
                       name="j")  # fmt: skip
        return terminal_currents_traced(part, -0.8, 2.5)

    for arg, x, eps in (("beta", 2e-3, 1e-8), ("vto", -1.5, 1e-6), ("lambda_", 0.03, 1e-6),
                        ("b", 0.7, 1e-6)):  # fmt: skip
        grad = float(jax.grad(drain)(x, arg))
        fd = (float(drain(x + eps, arg)) - float(drain(x - eps, arg))) / (2 * eps)
        assert grad == pytest.approx(fd, rel=1e-6), arg
        assert grad != 0.0


def terminal_currents_traced(part, vgs, vds):
    idx = {c: j for j, c in enumerate(part.coords)}
    v = jnp.zeros(len(part.coords))
    v = v.at[idx["wgs"]].set(vgs).at[idx["wgd"]].set(vgs - vds).at[idx["wch"]].set(vds)
    f = -part.force(jnp.zeros(len(part.coords)), v)
    return f[idx["wch"]] - f[idx["wgd"]]


@pytest.mark.parametrize(
    ("lines", "match"),
    [
        ("j1 d g 0 jm\n.model jm NJF (LEVEL=2)", r"line 4: .*LEVEL=2 .*Parker–Skellern"),
        ("j1 d g 0 jm\n.model jm NPN", r"line 4: .*NPN model; a J line needs NJF/PJF"),
        ("j1 d g jm\n.model jm NJF", r"line 4: .*model 'g' is not defined|expected 'Jname"),
    ],
)
def test_j_line_errors_name_the_line_and_the_reason(lines, match):
    net = f"t\nvd d 0 5\nvg g 0 -1\n{lines}\n.tran 1n 10n\n.end\n"
    with pytest.raises(spice.NetlistError, match=match):
        spice.read(net)


def test_noise_parameters_are_noted_and_temperature_ones_act_only_away_from_tnom():
    net = "t\nvd d 0 5\nvg g 0 -1\nj1 d g 0 jm\n.model jm PJF (KF=1e-15{})\n{}"
    net += ".tran 1n 10n\n.end\n"
    read = spice.read(net.format(" XTI=3 TCV=1m BEX=-1.5 TNOM=27", ""))
    notes = " ".join(read.notes)
    assert "KF ignored (noise only)" in notes and "XTI" not in notes
    # at T = TNOM = 27 °C the update is skipped: the part is the card's without them
    plain = spice.read(net.format("", ""))
    assert read.circuit.parts[-1].parameters == plain.circuit.parts[-1].parameters
    hot = spice.read(net.format(" XTI=3 TCV=1m BEX=-1.5", ".temp 80\n"))
    assert dict(hot.circuit.parts[-1].parameters)["vto"] == pytest.approx(-2.0 - 1e-3 * 53.0)


# ------------------------------------------------------------------ transient, power
AMPLIFIER = """JFET common-source stage with gate charges and series resistances
vdd vdd 0 {vdd}
vin in 0 SIN(0 0.4 200k)
rg in g 2k
rd vdd d 3.3k
rs s 0 470
cl d 0 10p
j1 d g s jm 2
.model jm {kind}(VTO={vto} BETA=1.2m LAMBDA=0.02 B=0.8 IS=1e-13 RD=20 RS=10 CGS=4p CGD=1.5p
+ PB=0.7 FC=0.4)
.tran 0.05u 10u
.end
"""


@pytest.mark.slow  # ~1 min each: an adaptive run compiles per circuit
@needs_ngspice
@pytest.mark.parametrize(("kind", "vdd", "vto"), [("NJF", 12, -2.2), ("PJF", -12, -1.8)])
def test_jfet_stage_agrees_with_a_fine_ngspice_transient(kind, vdd, vto):
    """diracvi's own variable steps (the deck's settings) against ngspice at a maximum
    step TSTOP/20000: ``v(d)`` and ``v(s)`` within 1e-3 of their peaks. The gate draws
    forward current on the input's peaks for neither polarity (reverse gate), while the
    junction charges move with the input."""
    net = AMPLIFIER.format(kind=kind, vdd=vdd, vto=vto)
    t, ref = ng.fine_transient(net, ("v(d)", "v(s)"))
    result = spice.run(net)
    for probe in ("v(d)", "v(s)"):
        mine = np.asarray(result.at(t)[probe])
        peak = np.max(np.abs(ref[probe]))
        assert np.max(np.abs(mine - ref[probe])) <= 1e-3 * peak, probe
        assert np.ptp(ref[probe]) > 0.05 * peak  # the stage amplifies


@pytest.mark.slow  # ~40 s
def test_discrete_power_balance_of_a_jfet_stage_accounts_for_every_watt():
    r"""Midpoint at each interior node ``t_k``: the sources' work = Δ(load capacitor's
    energy) + the resistors' ``R ī² h`` + the JFET's ``Σ_b V_b ī_b h`` (channel and both
    gate junctions, the gate forward-biased on the input's peaks) to 1e-10 of the
    largest term, with the branch currents from the formulas at the step voltages."""
    net = """jfet stage
vdd vdd 0 10
vin in 0 SIN(-0.6 1.2 50k)
rg in g 10k
rd vdd d 2k
cl d 0 100p
j1 d g 0 jm
.model jm NJF(VTO=-2 BETA=1m LAMBDA=0.03 B=0.8 IS=1e-11)
.ic v(d)=5
.tran 0.1u 40u
.end
"""
    result = spice.run(net, dt=0.1e-6, steps=400, solver=SOLVER)
    traj = result.trajectory
    h = float(traj.dt)
    nodes = MidpointNodes(traj)
    coord, node_current, at = nodes.coord, nodes.node_current, nodes.at_nodes
    vgs, vgd = nodes.step_volts("j1.wgs"), nodes.step_volts("j1.wgd")
    law = dict(vto=-2.0, beta=1e-3, lambda_=0.03, b=0.8, pb=1.0)
    i_ch = np.asarray(channel_current(vgs, vgd, **law))
    i_gs, i_gd = (np.asarray(gate_current(v, 1e-11, 1e-12)) for v in (vgs, vgd))
    vgs_n, vgd_n = at(vgs), at(vgd)
    k = slice(1, -1)
    supply = -(10.0 * node_current("vdd.q") + result["v(in)"][k] * node_current("vin.q")) * h
    q = coord("cl.q")
    qbar = (q[:-1] + q[1:]) / 2
    stored = np.diff(qbar**2 / (2 * 100e-12))
    dissipated = (10e3 * node_current("rg.q") ** 2 + 2e3 * node_current("rd.q") ** 2) * h
    device = ((vgs_n - vgd_n) * at(i_ch) + vgs_n * at(i_gs) + vgd_n * at(i_gd)) * h
    assert np.max(np.abs(node_current("j1.qch") - at(i_ch))) <= 1e-12 * np.max(np.abs(i_ch))
    terms = (supply, stored, dissipated, device)
    scale = max(np.max(np.abs(x)) for x in terms)
    residual = supply - stored - dissipated - device
    assert np.max(np.abs(residual)) <= 1e-10 * scale, np.max(np.abs(residual)) / scale
    for x in terms:
        assert np.max(np.abs(x)) > 1e-3 * scale  # every term is a sizeable share
    assert np.max(at(i_gs)) > 1e-6  # the gate conducts forward on the peaks
