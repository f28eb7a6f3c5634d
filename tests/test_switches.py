"""Switches S and W (ngspice's sw/csw): hysteresis thresholds, located switching instants,
the operating point's states, the discrete power balance across events, and a buck
converter against a committed fine ngspice reference.

Closed forms: a switch across a divider is a resistor RON or ROFF, so its node voltage is
a divider's; a ramped control crosses VT + VH going up and VT − VH going down at known
times; a relaxation oscillator (a capacitor charged through R, discharged by a switch it
controls) has exponential arcs between VT − VH and VT + VH with known durations.
"""

from __future__ import annotations

import math
from pathlib import Path

import jax
import numpy as np
import pytest

import _corpus as corpus
from diracvi import components as cp
from diracvi import simulate, spice
from diracvi.driver import events
from diracvi.errors import ModelError, StepFailure

DATA = Path(__file__).parent / "data" / "switches"

RAMP = """Ramped controls through the hysteresis windows of an S and a W switch
V1 c 0 PWL(0 0 1m 2 2m 0)
VM c x 0
RX x 0 1k
V2 s 0 1
R1 s a 1k
S1 a 0 c 0 sw1
R2 s b 1k
W1 b 0 VM csw1
.model sw1 sw vt=1 vh=0.2 ron=10 roff=100k
.model csw1 csw it=0.5m ih=0.1m ron=10 roff=100k
.tran 10u 2m
.end
"""


def _switch_times(march, j):
    """The nodes where relay ``j`` changes state, and its state after each."""
    k = np.flatnonzero(np.diff(march.modes[:, j]))
    return march.t[k + 1], march.modes[k + 1, j]


@pytest.fixture(scope="module")
def ramp():
    return spice.run(RAMP, internal=True)


@pytest.mark.slow
def test_switching_instants_are_the_thresholds_located_within_the_tolerance(ramp):
    march, system = ramp.trajectory, ramp.netlist.system
    found = events.relays(system)
    names = [system.coords[i].split(".")[0] for i, _ in found]
    tol = events.tolerances(system, 1e-3, [1e-6 if r.impulse else 1e-12 for _, r in found])
    # v(c) = 2 V/ms up to 1 ms, then down: S1 closes at 1.2 V, opens at 0.8 V;
    # i(VM) = v(c)/1k: W1 closes at 0.6 mA, opens at 0.4 mA
    slope = {"S1": 2e3, "W1": 2.0}
    expected = {"S1": (0.6e-3, 1.6e-3), "W1": (0.3e-3, 1.8e-3)}
    for j, name in enumerate(names):
        times, states = _switch_times(march, j)
        np.testing.assert_array_equal(states, [1.0, 0.0])
        late = times - np.asarray(expected[name])
        # each flip is taken within half a tolerance's worth of control of its level, on
        # either side (the window centred on the crossing: events.decide)
        assert np.all(np.abs(late) <= 0.5 * tol[j] / slope[name]), (name, late)
        # and on a linear control the parabola is exact, so the retry aimed at its
        # crossing ends on it to round-off (measured ≤ 1.1e-9 of tol/slope; 0.5 to 0.54
        # when a retry aimed half a tolerance past the crossing)
        assert np.all(np.abs(late) <= 1e-6 * tol[j] / slope[name]), (name, late)


CHAIN = """Two switch inverters: the second one's control relaxes exponentially
VDD vdd 0 DC 3
VIN in 0 PWL(0 0 0.4n 3)
sp out vdd vdd in swswitch
Cl out 0 0.1p
C2 out vdd 0.1p
sn out 0 in 0 swswitch
sp2 o2 vdd vdd out swswitch
Cl2 o2 0 0.2p
sn2 o2 0 out 0 swswitch
.model swswitch sw (vt=1 vh=0.1 ron=1k roff=1e12)
.tran 10p 1n
.end
"""


@pytest.mark.slow
def test_a_curved_control_is_switched_within_the_tolerance_of_its_level():
    # v(out) is a switched RC node: after v(in) = 7.5 V/ns passes 1.1 V both switches of
    # the first inverter close (v(out) → 1.5 V, τ = 0.1 ns), after 2.1 V only sn (→ 0,
    # τ = 0.2 ns), in closed form. sp2 closes where v(out) falls through 1.9 V, sn2 opens
    # where it falls through 0.9 V: at diracvi's flips the exact v(out) must be within
    # the event tolerance of those levels. A flip read from the line through the try's
    # two half-step controls missed by h²u''/16 (7.5e-5 V at sp2, twice the tolerance)
    result = spice.run(CHAIN, internal=True)
    march, system = result.trajectory, result.netlist.system
    found = events.relays(system)
    names = [system.coords[i].split(".")[0].lower() for i, _ in found]
    tol = events.tolerances(system, 1e-3, 1e-6)  # the deck's reltol, vntol
    t1, t2, tau = 1.1 / 7.5e9, 2.1 / 7.5e9, 0.2e-9
    v2 = 1.5 + 1.5 * math.exp(-(t2 - t1) / (tau / 2))

    def v_out(t):
        if t < t1:
            return 3.0
        if t < t2:
            return 1.5 + 1.5 * math.exp(-(t - t1) / (tau / 2))
        return v2 * math.exp(-(t - t2) / tau)

    for name, (level, state) in {"sp2": (1.9, 1.0), "sn2": (0.9, 0.0)}.items():
        j = names.index(name)
        times, states = _switch_times(march, j)
        assert list(states) == [state], name
        assert abs(v_out(times[0]) - level) <= tol[j], (name, v_out(times[0]) - level)


@pytest.mark.slow
def test_a_switch_is_ron_or_roff_between_the_events(ramp):
    t = ramp.time
    open_ = 100e3 / 101e3
    closed = 10.0 / 1010.0
    for node, (on, off) in {"v(a)": (0.6e-3, 1.6e-3), "v(b)": (0.3e-3, 1.8e-3)}.items():
        want = np.where((t > on) & (t < off), closed, open_)
        away = np.abs(t - on) > 1e-6
        away &= np.abs(t - off) > 1e-6
        np.testing.assert_allclose(ramp[node][away], want[away], rtol=1e-9, atol=1e-12)


@pytest.mark.slow
def test_the_discrete_power_balance_holds_on_every_step_across_the_events(ramp):
    r"""``E_{k+1} − E_k = h_k F_k(q̄_k, v_k, t_{k+½})·v_k`` with each step's own switch
    states (this circuit stores no energy, so the sources' work is the dissipation, step
    by step, the steps on either side of each event included)."""
    march, system = ramp.trajectory, ramp.netlist.system
    q, h, t = march.q, march.h, march.t
    v = np.diff(q, axis=0) / h[:, None]
    mid = 0.5 * (q[:-1] + q[1:])

    def power(modes, a, b, tt):
        return events.with_modes(system, modes).force(a, b, tt) @ b

    def terms(modes, a, b, tt):
        return events.with_modes(system, modes).force(a, b, tt) * b

    work = h * np.asarray(jax.vmap(power)(march.modes, mid, v, t[:-1] + h / 2))
    # the scale: the largest single term (a source's work, a resistor's loss) of a step
    each = h[:, None] * np.asarray(jax.vmap(terms)(march.modes, mid, v, t[:-1] + h / 2))
    sources = np.max(np.abs(each), axis=1)
    per_step = np.abs(work) / sources
    assert np.max(per_step) <= 1e-9  # Newton's own tolerance, step by step
    assert abs(np.sum(work)) <= 1e-10 * np.sum(sources)  # the bound, per run
    # and with the states held fixed the balance would fail after the first event
    held = h * np.asarray(
        jax.vmap(power, in_axes=(None, 0, 0, 0))(march.modes[0], mid, v, t[:-1] + h / 2)
    )
    assert np.max(np.abs(held) / sources) > 1e-3  # measured: worst step 4.8e-13, run 1.5e-15


@pytest.mark.slow
def test_on_and_off_flags_decide_a_control_inside_the_window():
    # v(c) starts at 1 V, inside S's window (0.8, 1.2): the flags decide, as in ngspice
    deck = """flags
V1 c 0 1
V2 s 0 1
R1 s a 1k
R2 s b 1k
S1 a 0 c 0 sw1 ON
S2 b 0 c 0 sw1
.model sw1 sw vt=1 vh=0.2 ron=10 roff=100k
.tran 10u 0.1m
.end
"""
    op = spice.operating_point(deck)
    assert op["v(a)"] == pytest.approx(10.0 / 1010.0, rel=1e-9)
    assert op["v(b)"] == pytest.approx(100e3 / 101e3, rel=1e-9)
    np.testing.assert_array_equal(op.modes, [1.0, 0.0])
    # a control above VT + VH at the operating point closes the switch (from OFF)
    above = spice.operating_point(deck.replace("V1 c 0 1", "V1 c 0 1.5"))
    np.testing.assert_array_equal(above.modes, [1.0, 1.0])


@pytest.mark.slow
def test_relaxation_oscillator_swings_between_vt_minus_vh_and_vt_plus_vh():
    r"""C charged from 10 V through 10 kΩ, discharged by S (RON 100 Ω) closed at
    ``VT + VH = 7 V`` and opened at ``VT − VH = 3 V``: charging arcs from 3 to 7 V of
    ``RC ln(7/3)``, discharges towards ``V·RON/(R + RON)`` with ``τ = (R ∥ RON) C``."""
    result = spice.run(DATA / "relaxation.cir", internal=True)
    march = result.trajectory
    times, states = _switch_times(march, 0)
    np.testing.assert_array_equal(states[:6], [1.0, 0.0] * 3)
    rc = 10e3 * 10e-9
    r_par = 10e3 * 100 / 10.1e3
    v_low = 10 * 100 / 10.1e3
    first = rc * math.log(10 / 3)
    discharge = r_par * 10e-9 * math.log((7 - v_low) / (3 - v_low))
    charge = rc * math.log(7 / 3)
    exact = [first]
    while len(exact) < len(times):
        exact.append(exact[-1] + (discharge if len(exact) % 2 else charge))
    # the capacitor's voltage at each flip is the threshold crossed, within the event
    # tolerance (half of it is the window the driver takes a flip in, judged on the
    # try's parabola; the recorded node differs from that by the step's own error)
    tol = events.tolerances(result.netlist.system, 1e-3, 1e-6)[0]  # 0.211 mV
    c_index = result.netlist.system.coords.index("C1.q")
    k = np.searchsorted(march.t, times)
    offset = march.q[k, c_index] / 10e-9 - np.where(states > 0, 7.0, 3.0)
    assert np.max(np.abs(offset)) <= tol, offset
    # and without a systematic side: past the level on average by less than a tenth of
    # the tolerance (measured 0.03 tol; 0.48 tol when a retry aimed half a tolerance past
    # the crossing, 0.5 at every closing flip)
    past = np.where(states > 0, offset, -offset)
    assert abs(np.mean(past)) <= 0.1 * tol, past / tol
    # a flip's offset δ moves the next arc's end by δ over the slope there, the charging
    # arc's at 7 V and 3 V (RC·dv/dt = 10 V − v): so the flips drift from the exact ones
    # by at most a tolerance's worth of each period's two (measured: within 2 ns over
    # the run; 54 ns, late, when every flip was aimed past its level)
    late = times - np.asarray(exact)
    drift = (len(times) / 2) * tol * (rc / 3.0 + rc / 7.0)  # 111 ns
    assert np.max(np.abs(late)) <= drift, late


@pytest.mark.slow
def test_synchronous_buck_agrees_with_fine_ngspice():
    deck = DATA / "buck.cir"
    grid, ref = _reference("buck")
    result = spice.run(deck)
    worst, errors, missing = corpus.compare(result, grid, ref)
    assert not missing
    assert worst <= 1e-3, errors


def _reference(name):
    import gzip

    with gzip.open(DATA / "reference" / f"{name}.csv.gz", "rt") as f:
        header = f.readline().strip().split(",")
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    return data[:, 0], {h: data[:, j] for j, h in enumerate(header) if j}


@pytest.mark.slow
@pytest.mark.skipif(not corpus.shutil.which("ngspice"), reason="ngspice is not installed")
def test_the_buck_reference_is_a_fresh_ngspice_run():
    grid, ref = _reference("buck")
    fresh_grid, fresh, _ = corpus.reference_from_run(DATA / "buck.cir")
    np.testing.assert_allclose(fresh_grid, grid, rtol=1e-9)
    for k, values in ref.items():
        peak = max(np.max(np.abs(values)), 1e-300)
        assert np.max(np.abs(fresh[k] - values)) <= 1e-8 * peak, k


def test_switch_mistakes_name_the_line_and_the_fix():
    base = "x\nV1 c 0 1\nR1 c a 1k\n{line}\n{model}\n.tran 1u 10u\n.end\n"
    cases = {
        ("S1 a 0 c 0 m1", ".model m1 csw it=1"): r"line 4: model 'm1' .* is a CSW model; a "
        r"voltage-controlled switch \(S\) needs a SW model",
        ("S1 a 0 c 0 m1", ".model m1 sw vt=1 von=2"): r"line 4: SW model 'm1' .* sets \['von'\]",
        ("S1 a 0 c 0 m1 maybe", ".model m1 sw"): r"line 4: expected 'Sname n\+ n- nc\+ nc- model",
        ("S1 a 0 c 0 m1", ".model m1 sw vh=-0.1"): r"hysteresis=-0\.1 is negative",
        ("W1 a 0 R1 m1", ".model m1 csw"): r"controlling element 'R1' must be a voltage source",
    }
    for (line, model), match in cases.items():
        with pytest.raises(spice.NetlistError, match=match):
            spice.read(base.format(line=line, model=model))


def test_a_fixed_step_run_refuses_switches():
    part = cp.VoltageSwitch(name="S1")
    with pytest.raises(ModelError, match=r"has switches .* run it with variable steps"):
        simulate(part, np.zeros(3), np.zeros(3), dt=1e-3, steps=2)
    with pytest.raises(ModelError, match=r"has switches"):
        spice.run(RAMP, dt=1e-5)


@pytest.mark.slow
def test_retries_aimed_at_switching_instants_are_not_counted_against_the_tries_budget(
    monkeypatch,
):
    """A switched run's budget of tries (``max_tries``) counts its ordinary tries, not
    the retries that place each flip on its instant (a few per event: a ring oscillator
    of switches has thousands of events, ng_switch_osc stopped on the budget with 3755 of
    them). The relaxation oscillator in chunks of 256 steps, so the budget is checked
    between chunks: given as a plain count, with exactly its ordinary tries it runs to the
    end, with half of them it stops on the budget. As ``spice.run`` gives it, judged by
    the run's pace (``driver/budget.py``: on while the last tries project the end within
    ``LIMIT`` = 4 times the count), half of them are enough — its steady pace needs twice
    that — and an eighth are not: the end is 8 times that away, and the run stops."""
    from diracvi.driver import adaptive as adaptive_module
    from diracvi.driver.budget import LIMIT
    from diracvi.spice import _run

    assert LIMIT == 4.0  # (the fractions below bracket it)
    monkeypatch.setattr(adaptive_module, "buffer_size", lambda n: 256)
    free = spice.run(DATA / "relaxation.cir", internal=True).trajectory
    assert free.status == 0 and free.aimed > 0 and len(free.h) > 3 * 256
    ordinary = free.tries - free.aimed

    paced_type = _run.TriesBudget

    def given(count, paced):
        monkeypatch.setattr(_run, "tries_budget", lambda settings, cycles=0.0: count)
        monkeypatch.setattr(_run, "TriesBudget", paced_type if paced else (lambda base: base))
        return lambda: spice.run(DATA / "relaxation.cir", internal=True).trajectory

    bounded = given(ordinary, paced=False)()
    assert bounded.status == 0 and bounded.tries == free.tries
    with pytest.raises(StepFailure, match="more step tries than its budget"):
        given(ordinary // 2, paced=False)()
    paced = given(ordinary // 2, paced=True)()
    assert paced.status == 0 and paced.tries == free.tries
    with pytest.raises(StepFailure, match=r"more step tries than its budget.*steps .* s on"):
        given(ordinary // 8, paced=True)()


RING7 = """A ring of seven switch inverters (ng_switch_osc's stage, tests/_switch_ring.py)
.ic v(osc_out)=0.25
.tran 0.1n 4n
VDD VDD2 0 DC 3
VMEASURE VDD2 VDD dc 0
cvdd vdd 0 1e-18
XS1 osc_out n1 vdd 0 inverter
XS2 n1 n2 vdd 0 inverter
XS3 n2 n3 vdd 0 inverter
XS4 n3 n4 vdd 0 inverter
XS5 n4 n5 vdd 0 inverter
XS6 n5 n6 vdd 0 inverter
XS0 n6 osc_out vdd 0 inverter
.subckt inverter In Out VDD DGND
sp out vdd vdd in swswitch
Cl out dgnd 0.1p
C2 out vdd 0.1p
sn out dgnd in dgnd swswitch
.ends inverter
.model swswitch sw (vt=1 vh=0.1 ron=1k roff=1e12)
.end
"""


def _ring_decay_bias(reltol):
    """RING7 at ``reltol``, switching by switching (in the order of the exact ones): the
    discrete output's advance on its exact exponential, in time, and the midpoint rule's
    predicted one (the docstring below), after asserting (a) at each flip and each
    instant within the step tolerance of the exact one."""
    from _switch_ring import ring_switchings

    run = spice.run(RING7, reltol=reltol, internal=True)
    march, system = run.trajectory, run.netlist.system
    t, h, q, modes = march.t, march.h, march.q, march.modes
    found = events.relays(system)
    column = {}
    for j, (i, _) in enumerate(found):
        _, stage, switch = system.coords[i].split(":")  # 's:xs3:sp.s'
        column[(int(stage[2:]), switch[:2])] = j
    n, c, vdd = 7, 0.2e-12, 3.0
    v = [q[:, system.coords.index(f"c:xs{k}:cl.q")] / 1e-13 for k in range(n)]
    flips = {key: list(np.flatnonzero(np.diff(modes[:, j])) + 1) for key, j in column.items()}
    exact = ring_switchings(t[-1], stages=n)
    assert len(exact) == sum(len(f) for f in flips.values()) == 60
    tol = events.tolerances(system, reltol, 1e-6)[0]
    seen, starts = {}, {k: 0 for k in range(n)}
    advance, predicted = [], []
    for te, k, switch, closed in sorted(exact, key=lambda e: e[0]):
        nth = seen.get((k, switch), 0)
        seen[(k, switch)] = nth + 1
        i = flips[(k, switch)][nth]
        assert modes[i, column[(k, switch)]] == float(closed)
        assert abs(t[i] - te) <= reltol * te  # within the step tolerance
        j, i0 = (k - 1) % n, starts[(k - 1) % n]
        g = [1e-3 if modes[i0, column[(j, s)]] else 1e-12 for s in ("sp", "sn")]
        v_inf, tau = vdd * g[0] / sum(g), c / sum(g)
        shadow = v_inf + (v[j][i0] - v_inf) * math.exp(-(t[i] - t[i0]) / tau)
        slope = (v_inf - shadow) / tau  # dv_j/dt
        # (a) the control at the flip (sn reads v_j, sp reads VDD − v_j)
        u = v[j][i] if switch == "sn" else vdd - v[j][i]
        assert abs(u - (1.1 if closed else 0.9)) <= tol
        # (b) the discrete node ahead of its exact exponential, in time
        advance.append((v[j][i] - shadow) / slope)
        z = h[i0:i] / tau
        predicted.append(tau * np.sum(np.log((1 + z / 2) / (1 - z / 2)) - z))
        starts[k] = i  # stage k's output follows a new law from here
    return np.array(advance), np.array(predicted)


@pytest.mark.slow
def test_a_switch_ring_s_instants_err_only_by_the_midpoint_rule_s_decay_bias():
    """Where ng_switch_osc's period error comes from, on a 7-stage ring of its inverters
    (exact switchings: tests/_switch_ring.py). Per switching of stage k, caused by the
    output v_j of stage j = k − 1 reaching a level, the error splits into
    (a) locating the crossing: the discrete v_j at the flip is within the event tolerance
        of the level (events.tolerances);
    (b) the state between events: from v_j's own last switching (where its law
        C v̇ = g_p (VDD − v) − g_n v began, v → v∞ with time constant τ), the midpoint rule
        (trapezoidal on a linear node) decays by r(z) = (1 − z/2)/(1 + z/2) per step
        z = h/τ, and ln r(z) = −z − z³/12 − …: the discrete node is ahead of the exact
        exponential from the same start by τ Σ (ln((1 + z/2)/(1 − z/2)) − z) in time.
    (b) is all there is beyond (a): the measured advance equals that sum to 10 % + 1 fs,
    and every instant is within the step tolerance of the exact one, at reltol 1e-3 (the
    deck's) and 3e-3 (event tolerance and the instants' bound with it).

    The premise. The 1 fs is a floor that does not move with the steps (the largest
    |advance − sum|: 6.6e-16 s at 1e-3, 7.8e-16 s at 3e-3), while the sum, ∝ τ Σ z³, goes
    as the steps squared: since bd5d10c the steps are set by the node potentials' step-
    doubling error, O(H²) per try, so H² ∝ reltol and the sum ∝ reltol (median 3.0e-15 s
    at 1e-3, 8.9e-15 s at 3e-3, a ratio 2.9; it was 1.5e-14 s at 1e-3 with the steps held
    to TMAX, docs/circuits.md "The ring's steps since node potentials are judged per
    try"). The check tells the bias from no bias, or from twice it, at a switching only
    where the sum exceeds 1 fs / 0.9: the premise is that the sum is well above the floor,
    median ≥ 5e-15 s, which holds at 3e-3 (margin 1.8), not at 1e-3 (3.0e-15 s, where the
    check still fails at 57 or 58 of the 60 switchings if the sum is doubled or absent).
    And the medians' ratio across the two is the reltol's (2.93), which tells the H²
    control from an H³ one (3^(2/3) = 2.08): the bias is what the steps make it.
    Measured 2026-12-02 (session 39): worst |advance − sum| 0.31 (1e-3) and 0.21 (3e-3)
    of its bound; with the predicted sum doubled the test fails."""
    bias = {}
    for reltol in (1e-3, 3e-3):
        advance, predicted = _ring_decay_bias(reltol)
        assert np.all(predicted > 0.0)
        assert np.all(np.abs(advance - predicted) <= 0.1 * predicted + 1e-15), reltol
        bias[reltol] = float(np.median(predicted))
    assert bias[3e-3] > 5e-15  # 8.9e-15 s
    # ∝ reltol is an H² control (3); an H³ one would give 3^(2/3) = 2.08
    assert 2.5 <= bias[3e-3] / bias[1e-3] <= 3.6  # 2.93


def _ring_instants_error(reltol):
    """RING7 at ``reltol``: the run's switching instants, in order, minus the exact ones
    (tests/_switch_ring.py), and the run."""
    from _switch_ring import ring_switchings

    run = spice.run(RING7, reltol=reltol, internal=True)
    march = run.trajectory
    found = events.relays(run.netlist.system)
    flips = sorted(
        (march.t[i], j)
        for j in range(len(found))
        for i in np.flatnonzero(np.diff(march.modes[:, j])) + 1
    )
    exact = sorted(e[0] for e in ring_switchings(march.t[-1], stages=7))
    assert len(flips) == len(exact) == 60
    return np.array([t for t, _ in flips]) - np.array(exact), run


@pytest.mark.slow
def test_a_switch_ring_tightened_finishes_and_its_instants_converge():
    """A switch ring at reltol 1e-5 runs to its end and its switching instants come
    closer to the exact ones than at 1e-4. The gap check between tries (driver/adaptive.py)
    is for a junction turning on; on this circuit, linear between its switching instants,
    its estimate (the linear interpolant's error, O(h²)) sized the steps instead of the
    step error, and the run stopped on its budget of tries at 2.1 ns of 4 (10 352 steps
    at 1e-4, 2120 without it).

    Then the floor of the step-doubling estimate: each stage's capacitors and VDD form a
    capacitor–source loop whose alternation (≈ 8e-19 C, 7.7 tolerances at 1e-5) no step
    lowers. On the try after a flip it was not fitted (the last try is on another law),
    so that try was rejected from ps down to 1.3e-16 s, 13 rejections per flip on average
    and 2642 in all; fitted from a retry of the same start and every try judged without
    it, 62 (1 per flip), the shortest step 3.6e-14 s, and the instants 2.5 times closer.

    What the shortest step shows. A flip's landing try ends on its crossing (retries aimed
    at it, each at least a quarter of the last, events.decide), so its size is where the
    crossing falls after the last accepted try: 1.9e-15 s here (a crossing 3.8e-15 s past
    a try's end), and the tries after it regrow by the growth law, at most 2× a try. The
    old assertion, ``min(h) > 1e-14``, read that grid (it failed from bd5d10c on, and on
    its first parent under this compile, with no cascade: the 1.9e-15 s is such a
    landing). That the landings end on their crossings is what the instants' assertions
    measure (the flip nodes are the exact instants to 5.4e-15 s at most). What the old
    assertion was for is asserted away from the flips: outside each landing try and the
    ``log₂(B/ℓ) + 2`` tries after it that the growth law needs to regrow from a landing
    ``ℓ`` to ``B`` (one more for the first try after a flip, sized on the new law, down to
    0.6 of the landing), no step is below ``B = 5e-14 s``. A floor collapse or a
    rejection cascade (the 6.5e-17 s above) puts steps there; measured 1.67e-13 s, a
    margin of 3.3 (1.38e-13 s, 2.8, under the default compile; 2026-12-02, session 39;
    1.85e-13 s outside 2 steps before to 16 after each flip, session 38's 1.7e-13)."""
    loose, _ = _ring_instants_error(1e-4)
    tight, run = _ring_instants_error(1e-5)
    march = run.trajectory
    assert march.status == 0 and march.t[-1] == pytest.approx(4e-9)
    rms = [float(np.sqrt(np.mean(d**2))) for d in (loose, tight)]
    # measured 2.0e-14 s and 3.3e-15 s (2026-12-02; 1.12e-13 and 2.4e-14 s when written,
    # before bd5d10c judged the node potentials per try; 6.0e-14 s before the floor fit)
    assert rms[1] < 0.35 * rms[0]
    assert np.max(np.abs(tight)) < 0.5 * np.max(np.abs(loose))  # 3.9e-14 s and 5.4e-15 s
    # rejections other than the retries aimed at an instant: 89 (62 when written, 2642
    # before the floor fit)
    assert march.rejected - march.aimed < 10 * len(tight)
    h, modes = march.h, march.modes
    # away from the landings and their regrowth, no short step
    bound = 5e-14
    near = np.zeros(len(h), bool)
    for f in np.flatnonzero(np.any(np.diff(modes, axis=0) != 0, axis=1)) + 1:
        landing = h[f - 1]  # the try's second half, ending on the flip node
        tries = math.ceil(math.log2(bound / landing)) + 2 if landing < bound else 2
        near[f - 2 : f + 2 * tries] = True  # each try is recorded as its two halves
    assert np.all(np.isclose(h[0::2], h[1::2], rtol=1e-12))
    assert np.min(h[~near]) > bound  # 1.67e-13 s


def _decide_on_parabola(a, b, c, closed, h=1.0, tol=0.01):
    """``events.decide`` for a try of size ``h`` over which a velocity-read control is the
    parabola ``u(τ) = a + bτ + cτ²``: each step's value (its coordinate's increment over
    the step) the mean of the parabola at the step's ends, as the midpoint rule's
    step-centred values are on a capacitor's node; a relay with levels 1.1 (on) and 0.9
    (off)."""
    from diracvi.components.switch import Relay

    relay = Relay(jax.numpy.asarray(float(closed)), 1.1, 0.9, "x")

    def u(t):
        return a + b * t + c * t * t

    half = h / 2
    q1 = half * (u(0.0) + u(half)) / 2
    q2 = q1 + half * (u(half) + u(h)) / 2
    qc = h * (u(0.0) + u(h)) / 2
    q = tuple(np.array([x]) for x in (0.0, q1, q2, qc))
    p = tuple(np.zeros(1) for _ in range(4))
    new, located, h_event, _ = events.decide(
        ((0, relay),), np.array([float(closed)]), q, p, np.zeros(1), h, np.array([tol]), 1e-9
    )
    return float(new[0]), bool(located), float(h_event)


def test_a_flip_is_taken_within_half_the_tolerance_of_its_level_on_either_side():
    """A try whose control ends within tol/2 of the level is accepted with the flip: past
    it, or short of it and heading for it (the parabola reaching it); one that ends
    further past is retried at the parabola's crossing itself, not past it (before, the
    retry aimed tol/2 past the crossing, so every flip was late by tol/(2|u̇|)); short of
    it by more, or turning back before it, the state is kept."""
    # rising through on = 1.1 (open), u(1) = 1.1 + d with u' = 1 at the end
    for d, flipped in ((0.004, 1.0), (-0.004, 1.0), (-0.006, 0.0)):
        new, located, h_event = _decide_on_parabola(0.1 + d, 1.0, 0.0, closed=False)
        assert (new, located, h_event) == (flipped, True, 1.0), d
    # falling through off = 0.9 (closed), the mirror image
    for d, kept in ((0.004, 0.0), (-0.004, 0.0), (-0.006, 1.0)):
        new, located, h_event = _decide_on_parabola(1.9 - d, -1.0, 0.0, closed=True)
        assert (new, located, h_event) == (kept, True, 1.0), d
    # 0.0026 short, heading up (u' = 0.05 at the end) but turning (u'' = −2): its peak,
    # 1.0980, is below the level, so it is not flipped on the extrapolation
    new, located, _ = _decide_on_parabola(0.0474, 2.05, -1.0, closed=False)
    assert (new, located) == (0.0, True)
    # past by 0.3 (and by 0.008, which the one-sided window [level, level + tol] took):
    # retried at the crossing of 0.5 + 0.8τ + 0.1τ² (resp. of the line) with 1.1
    crossing = (-0.8 + math.sqrt(0.64 + 0.24)) / 0.2
    new, located, h_event = _decide_on_parabola(0.5, 0.8, 0.1, closed=False)
    assert new == 1.0 and not located
    assert abs(h_event - crossing) <= 1e-10  # two Newton steps from the end: 1.0e-11
    new, located, h_event = _decide_on_parabola(0.108, 1.0, 0.0, closed=False)
    assert new == 1.0 and not located and abs(h_event - 0.992) <= 1e-12
