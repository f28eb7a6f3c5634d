"""Parts and the Circuit builder: equal to the hand-built paper models, physical signs,
exact resistive networks, and topology errors that name the culprit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

import diracvi as dv
from diracvi import components as cp
from diracvi.components.diode import THERMAL_VOLTAGE
from diracvi.problems import dc_motor, rlc_circuit
from diracvi.spice import waveforms


def _midpoint(built, dt, steps):
    return dv.simulate(
        built.system, built.q0, built.p0, dt=dt, steps=steps, discretization="midpoint"
    )


def paper_rlc():
    c = cp.Circuit("rlc")
    c.add(cp.Resistor(1.0, name="R"), p="0", n="n1")  # the paper's v^R = v^L + v^C
    c.add(cp.Inductor(0.75, name="L", i0=10.0), p="n1", n="0")
    c.add(cp.Capacitor(3.0, name="C"), p="n1", n="0")
    return c.build()


@pytest.mark.parametrize("rule", [pytest.param("retraction", marks=pytest.mark.slow), "midpoint"])
def test_part_built_rlc_equals_the_paper_model(rule):
    built, hand = paper_rlc(), rlc_circuit()
    assert built.system.coords == ("R.q", "L.q", "C.q")
    np.testing.assert_array_equal(built.p0, hand.p0)
    a = dv.simulate(built.system, built.q0, built.p0, dt=0.1, steps=400, discretization=rule)
    b = dv.simulate(hand.system, hand.q0, hand.p0, dt=0.1, steps=400, discretization=rule)
    assert np.max(np.abs(a.q - b.q)) <= 1e-12
    assert np.max(np.abs(a.p - b.p)) <= 1e-12
    # the node row is the paper's one-form with the opposite sign: λ = −μ
    assert np.max(np.abs(a.multiplier("KCL(n1)") + b.multiplier("KCL"))) <= 1e-12


def motor_from_parts(prm):
    c = cp.Circuit("motor")
    c.add(cp.VoltageSource(prm["V"], name="V1"), p="vp", n="0")
    c.add(cp.Resistor(prm["R"], name="R1"), p="vp", n="b")
    c.add(cp.Inductor(prm["La"], name="L1"), p="b", n="c")
    c.add(cp.EMF(prm["K"], name="emf"), p="c", n="0", flange="shaft")
    c.add(cp.Inertia(prm["J"], name="rotor"), flange="shaft")
    c.add(cp.RotationalDamper(prm["b"], name="friction"), a="shaft", b="housing")
    c.add(cp.Fixed(name="mount", rotational=True), flange="housing")
    return c.build()


# 23 s, in `-m slow` (the default suite's time on CI): part-built equals hand-built by
# default on the paper's RLC (test_part_built_rlc_equals_the_paper_model); the DC motor's
# coupling by tests/test_interconnect.py's theorem on "dc-motor"
@pytest.mark.slow
def test_part_built_dc_motor_equals_the_hand_built_one():
    hand = dc_motor()
    built = motor_from_parts(hand.parameters)
    kw = dict(dt=hand.dt, steps=hand.steps, discretization="midpoint")
    a = dv.simulate(built.system, built.q0, built.p0, **kw)
    b = dv.simulate(hand.system, hand.q0, hand.p0, **kw)
    assert np.max(np.abs(a["L1.q"] - b["armature.qL"])) <= 1e-12
    assert np.max(np.abs(a["rotor.x"] - b["rotor.theta"])) <= 1e-12
    # passive sign convention: the source's branch current is minus the loop current
    assert np.max(np.abs(a["V1.q"] + b["armature.qS"])) <= 1e-12
    assert b["rotor.theta"][-1] > 1.0  # it really turns


def test_rc_discharge_loses_energy_and_matches_the_exponential():
    c = cp.Circuit("rc")
    c.add(cp.Resistor(2.0, name="R1"), p="a", n="0")
    c.add(cp.Capacitor(0.5, name="C1", v0=1.0), p="a", n="0")
    built = c.build()
    h, n = 0.01, 300
    traj = dv.simulate(built.system, built.q0, built.p0, dt=h, steps=n, discretization="midpoint")
    w = waveforms(built, traj)
    exact = np.exp(-traj.t / 1.0)  # τ = RC = 1
    assert np.max(np.abs(w["v(a)"] - exact)) < 1e-4  # O(h²), h² = 1e-4
    # the resistor carries the discharge current out of node a (passive convention)
    assert np.max(np.abs(w["i(R1)"] - exact / 2.0)) < 1e-4
    assert np.max(np.abs(w["i(R1)"] + w["i(C1)"])) < 1e-12  # KCL
    stored = 0.5 * 0.5 * w["v(a)"] ** 2
    assert np.all(np.diff(stored) < 0.0)  # a resistor removes energy


@pytest.mark.slow
def test_resistive_network_with_transformer_and_current_source_is_exact():
    # V1 – R1 – [transformer n = 2] – R2: v_p = V n² R2 / (R1 + n² R2); I1 into R3.
    c = cp.Circuit("net")
    c.add(cp.VoltageSource(3.0, name="V1"), p="in", n="0")
    c.add(cp.Resistor(4.0, name="R1"), p="in", n="p")
    c.add(cp.IdealTransformer(2.0, name="T1"), p1="p", n1="0", p2="s", n2="0")
    c.add(cp.Resistor(1.5, name="R2"), p="s", n="0")
    c.add(cp.CurrentSource(cp.Sine(0.0, 0.25, 3.0), name="I1"), p="0", n="x")
    c.add(cp.Resistor(8.0, name="R3"), p="x", n="0")
    built = c.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=0.002, steps=300, discretization="midpoint"
    )
    w = waveforms(built, traj)
    vp = 3.0 * 4 * 1.5 / (4.0 + 4 * 1.5)
    assert np.max(np.abs(w["v(p)"] - vp)) < 1e-10
    assert np.max(np.abs(w["v(s)"] - vp / 2.0)) < 1e-10
    # transformer is lossless: primary power = secondary power delivered
    assert np.max(np.abs(w["v(p)"] * w["i(T1.1)"] + w["v(s)"] * w["i(T1.2)"])) < 1e-10
    # I1 pushes u(t) from 0 through itself into x: v(x) = 8 u(t), second order in h:
    # the averaged half-step currents are off by ≈ (ωh)²/8 relative, 4e-4 here
    u = 0.25 * np.sin(2 * np.pi * 3.0 * traj.t)
    assert np.max(np.abs(w["v(x)"] - 8.0 * u)) < 2e-3
    assert np.max(np.abs(w["i(I1)"] - u)) < 2e-4


@pytest.mark.slow  # the rectifier's ngspice comparison (test_spice.py) runs by default
def test_diode_operating_point_solves_shockley():
    # 2 V through 1 kΩ into a diode: i = IS (e^{V/VT} − 1) + gmin V, V + 1000 i = 2
    c = cp.Circuit("diode")
    c.add(cp.VoltageSource(2.0, name="V1"), p="in", n="0")
    c.add(cp.Resistor(1e3, name="R1"), p="in", n="a")
    c.add(cp.Diode(1e-14, 1.0, name="D1"), p="a", n="0")
    built = c.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=1e-3, steps=5, discretization="midpoint"
    )
    w = waveforms(built, traj)

    def kcl(v):
        return 1e-14 * np.expm1(v / THERMAL_VOLTAGE) + 1e-12 * v - (2.0 - v) / 1e3

    vd = brentq(kcl, 0.0, 1.0, xtol=1e-15)
    assert abs(w["v(a)"][3] - vd) < 1e-9
    assert abs(w["i(D1)"][3] - (2.0 - vd) / 1e3) < 1e-9


@pytest.mark.slow
def test_mass_spring_damper_from_parts_matches_the_closed_form():
    m, k, c_ = 2.0, 8.0, 0.4
    c = cp.Circuit("msd")
    c.add(cp.Fixed(name="wall"), flange="w")
    c.add(cp.Spring(k, name="k"), a="w", b="x")
    c.add(cp.Damper(c_, name="c"), a="w", b="x")
    c.add(cp.Mass(m, name="m"), flange="x")
    c.initial("x", position=0.3)
    built = c.build()
    h, n = 0.005, 800
    traj = dv.simulate(built.system, built.q0, built.p0, dt=h, steps=n, discretization="midpoint")
    x = traj["m.x"]
    gamma, wd = c_ / (2 * m), np.sqrt(k / m - (c_ / (2 * m)) ** 2)
    exact = 0.3 * np.exp(-gamma * traj.t) * (np.cos(wd * traj.t) + gamma / wd * np.sin(wd * traj.t))
    assert np.max(np.abs(x - exact)) < 1e-4
    assert np.max(np.abs(traj["wall.x"])) == 0.0  # the wall holds


@pytest.mark.slow
def test_pendulum_driven_by_a_dc_motor_settles_where_torque_balances_gravity():
    c = cp.Circuit("motor_pendulum")
    c.add(cp.VoltageSource(cp.PWL([0.0, 0.2], [0.0, 2.0]), name="V1"), p="vp", n="0")
    c.add(cp.Resistor(1.0, name="R1"), p="vp", n="b")
    c.add(cp.Inductor(0.05, name="L1"), p="b", n="c")
    c.add(cp.EMF(0.5, name="emf"), p="c", n="0", flange="shaft")
    c.add(cp.Pendulum(0.5, 0.4, name="arm"), flange="shaft")
    built = c.build()
    traj = dv.simulate(
        built.system, built.q0, built.p0, dt=2e-3, steps=2000, discretization="midpoint"
    )
    theta = traj["arm.x"]
    w = waveforms(built, traj)
    # 2 V stall the motor (back-emf K θ̇ damps the swing, τ = m ℓ² R/K² = 0.32 s) where
    # its torque K i = K V/R balances gravity m g ℓ sin θ
    assert abs(0.5 * w["i(R1)"][-1] - 1.0) < 1e-3
    assert abs(np.sin(theta[-1]) - 1.0 / (0.5 * 9.81 * 0.4)) < 1e-3


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda c: c.add(cp.Resistor(1.0, name="R1"), p="a", n="b"), "no ground"),
        (
            lambda c: (
                c.add(cp.Resistor(1.0, name="R1"), p="a", n="0"),
                c.add(cp.Resistor(1.0, name="R4"), p="a", n="0"),
                c.add(cp.Resistor(1.0, name="R2"), p="x", n="y"),
                c.add(cp.Resistor(1.0, name="R3"), p="y", n="x"),
            ),
            r"nodes \['x', 'y'\] are floating",
        ),
        (
            lambda c: (
                c.add(cp.VoltageSource(1.0, name="V1"), p="a", n="0"),
                c.add(cp.VoltageSource(2.0, name="V2"), p="a", n="0"),
            ),
            "'V2' closes a loop of voltage sources",
        ),
        (
            lambda c: (
                c.add(cp.Resistor(1.0, name="R1"), p="a", n="0"),
                c.add(cp.CurrentSource(1.0, name="I1"), p="a", n="b"),
                c.add(cp.Resistor(1.0, name="R2"), p="b", n="c"),
                c.add(cp.CurrentSource(1.0, name="I2"), p="c", n="0"),
            ),
            r"cut-set of current sources.*I1.*I2|I1.*I2.*cut-set",
        ),
    ],
)
def test_topology_errors_name_the_culprit(build, match):
    c = cp.Circuit("bad")
    build(c)
    with pytest.raises(dv.ModelError, match=match):
        c.build()


def test_part_arguments_are_checked_by_name():
    with pytest.raises(dv.ModelError, match="resistance=-1"):
        cp.Resistor(-1.0, name="R1")
    with pytest.raises(dv.ModelError, match=r"\|k\| < 1"):
        cp.CoupledInductors((1.0, 1.0), 1.0, name="K1")
    with pytest.raises(dv.ModelError, match="missing \\['n'\\]"):
        cp.Circuit().add(cp.Resistor(1.0, name="R1"), p="a")
    with pytest.raises(dv.ModelError, match="TR"):
        cp.Pulse(0, 1, 0, 0.0, 1, 1, 1)


@pytest.mark.slow
def test_user_function_parts_equal_the_linear_ones():
    def build(nonlinear):
        c = cp.Circuit("rlc_fn")
        c.add(cp.VoltageSource(cp.Sine(0.0, 1.0, 0.5), name="V1"), p="in", n="0")
        if nonlinear:
            c.add(cp.Resistor(voltage=lambda i: 2.0 * i, name="R1"), p="in", n="a")
            c.add(cp.Inductor(coenergy=lambda i: 0.5 * 0.3 * i**2, name="L1"), p="a", n="b")
            c.add(cp.Capacitor(energy=lambda q: q**2 / (2 * 0.7), name="C1"), p="b", n="0")
        else:
            c.add(cp.Resistor(2.0, name="R1"), p="in", n="a")
            c.add(cp.Inductor(0.3, name="L1"), p="a", n="b")
            c.add(cp.Capacitor(0.7, name="C1"), p="b", n="0")
        return c.build()

    a, b = _midpoint(build(True), 0.01, 200), _midpoint(build(False), 0.01, 200)
    assert np.max(np.abs(a.q - b.q)) <= 1e-12


@pytest.mark.slow
def test_voice_coil_pushes_a_spring_to_bl_i_over_k():
    bl, k, current = 2.5, 40.0, 0.8
    c = cp.Circuit("voice_coil")
    c.add(cp.CurrentSource(cp.PWL([0.0, 0.05], [0.0, current]), name="I1"), p="0", n="a")
    c.add(cp.Resistor(4.0, name="R1"), p="a", n="0")
    c.add(cp.VoiceCoil(bl, name="coil"), p="a", n="0", flange="cone")
    c.add(cp.Mass(0.01, name="m"), flange="cone")
    c.add(cp.Spring(k, name="k"), a="frame", b="cone")
    c.add(cp.Damper(1.0, name="c"), a="frame", b="cone")
    c.add(cp.Fixed(name="frame"), flange="frame")
    built = c.build()
    traj = _midpoint(built, 1e-3, 1000)
    w = waveforms(built, traj)
    # at rest there is no back-emf Bl ẋ: v(a) = 0, R1 carries nothing, the coil all of I,
    # and its force Bl i holds the spring at x = Bl I / k
    assert abs(w["i(coil)"][-1] - current) < 1e-4
    assert abs(traj["m.x"][-1] - bl * current / k) < 1e-4


def test_every_part_takes_traced_parameters_and_grad_matches_central_differences():
    """R, C (with its initial voltage), L, a diode's IS and N, a sine's amplitude and a
    current source's value, all traced: jax.grad of a loss of the run agrees with central
    differences to 1e-6 (relative)."""
    import jax
    import jax.numpy as jnp

    def loss(theta):
        r, cap, ell, i_s, n, amp, i_dc = theta
        c = cp.Circuit("traced")
        c.add(cp.VoltageSource(cp.Sine(0.0, amp, 2e3), name="V1"), p="in", n="0")
        c.add(cp.Resistor(r, name="R1"), p="in", n="a")
        c.add(cp.Inductor(ell, name="L1"), p="a", n="b")
        c.add(cp.Diode(i_s, n, name="D1"), p="b", n="c")
        c.add(cp.Capacitor(cap, name="C1", v0=0.1 * amp), p="c", n="0")
        c.add(cp.Resistor(1e3, name="R2"), p="c", n="0")
        c.add(cp.CurrentSource(i_dc, name="I1"), p="0", n="c")
        built = c.build()
        traj = dv.simulate(
            built.system, built.q0, built.p0, dt=5e-6, steps=120, discretization="midpoint"
        )
        w = waveforms(built, traj)
        return jnp.sum(w["v(c)"] ** 2) + 1e3 * jnp.sum(w["i(L1)"] ** 2)

    theta = jnp.array([100.0, 1e-6, 1e-2, 1e-14, 1.5, 2.0, 1e-3])
    grad = jax.jit(jax.grad(loss))(theta)
    fast = jax.jit(loss)  # one program for the 14 evaluations below
    for k in range(len(theta)):
        step = 1e-5 * theta[k]
        central = (fast(theta.at[k].add(step)) - fast(theta.at[k].add(-step))) / (2 * step)
        assert abs(grad[k] - central) <= 1e-6 * abs(central), (k, grad[k], central)


@pytest.mark.parametrize("diodes", [1, 9])
def test_closed_form_momenta_equal_the_lagrangians_derivative(diodes, monkeypatch):
    """A netlist's initial momenta ``p0 = ∂L/∂v`` are written in closed form for linear
    R, L, C (``l i0`` on an inductor, 0 elsewhere); they must equal what differentiating
    every part's Lagrangian gives — with one diode and a source beside the linear parts
    (eager calls for those) and with nine (the packed, compiled call for all)."""
    from diracvi.components import network

    rng = np.random.default_rng(7)

    def circuit():
        c = cp.Circuit("ladder")
        c.add(cp.VoltageSource(cp.Sine(0.0, 1.0, 1e3), name="V1"), p="n0", n="0")
        for k in range(12):
            a, b = f"n{k}", f"n{k + 1}"
            c.add(cp.Resistor(10.0 + k, name=f"R{k}"), p=a, n=f"m{k}")
            c.add(cp.Inductor(1e-3 * (k + 1), name=f"L{k}", i0=rng.normal()), p=f"m{k}", n=b)
            c.add(cp.Capacitor(1e-6, name=f"C{k}", v0=rng.normal()), p=b, n="0")
        for k in range(diodes):
            c.add(cp.Diode(1e-14, name=f"D{k}"), p=f"n{k + 1}", n="0")
        return c.build()

    state = rng.bit_generator.state
    closed = circuit()
    rng.bit_generator.state = state
    monkeypatch.setattr(network, "template_momentum", lambda fields, velocity: None)
    derived = circuit()
    assert isinstance(closed.p0, np.ndarray)
    assert np.any(closed.p0 != 0.0)  # the inductors' l i0
    np.testing.assert_allclose(closed.p0, derived.p0, rtol=1e-15, atol=0.0)
    np.testing.assert_array_equal(closed.q0, derived.q0)
