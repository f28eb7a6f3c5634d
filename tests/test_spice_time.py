"""SPICE's time semantics: TSTEP is the output interval, the steps are chosen for the
tolerances, never longer than TMAX and ending on every source corner.

Each deck below is run at its OWN ``.tran`` settings (default ``.options``) and compared
with a fine ngspice run (reltol 1e-7, TMAX = TSTEP/50) to 1e-3 of each signal's peak;
variable steps keep KCL and the discrete power balance to round-off per step.
"""

from __future__ import annotations

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

import _ngspice as ng
from _ngspice import available, ngspice
from diracvi import components as cp
from diracvi import spice
from diracvi.cli import app
from diracvi.discretization.maps import discrete_constraints
from diracvi.discretization.rules import get_rule
from diracvi.driver import adaptive as _adaptive
from diracvi.errors import ModelError
from diracvi.spice._resample import Sampler
from diracvi.spice._tran import breakpoints, tran_settings

FINE = ".options reltol=1e-7 abstol=1e-15 vntol=1e-12 chgtol=1e-18 trtol=1"
needs_ngspice = pytest.mark.skipif(not available(), reason="ngspice is not installed")

# name -> (netlist, probes); every deck starts from a consistent state (UIC, sources 0)
DECKS = {
    "rc-charge": (
        """RC charging from a DC source
V1 in 0 DC 1
R1 in out 1k
C1 out 0 1u
.tran 0.1m 5m uic
.end
""",
        ("v(out)", "i(V1)"),
    ),
    # PW and PER default to TSTOP (not TSTEP): one 1 ns edge up, no fall within the run
    "rlc-pulse": (
        """Series RLC driven by a 1 ns-edge pulse
V1 in 0 PULSE(0 1 10n 1n 1n)
R1 in a 10
L1 a b 1u
C1 b 0 1n
.tran 2n 1u uic
.end
""",
        ("v(b)", "v(a)", "i(V1)"),
    ),
    "square-rc": (
        """Square wave into an RC
V1 in 0 PULSE(0 5 0 1u 1u 0.5m 1m)
R1 in out 1k
C1 out 0 0.1u
.tran 10u 3m uic
.end
""",
        ("v(out)", "i(V1)"),
    ),
    "delayed-sin": (
        """A sine that starts after its delay, into an RC
V1 in 0 SIN(0 1 1k 0.5m)
R1 in out 100
C1 out 0 1u
.tran 10u 3m uic
.end
""",
        ("v(out)", "i(V1)"),
    ),
    "pwl-rl": (
        """A piecewise-linear source into an RL
V1 in 0 PWL(0 0 0.1m 1 0.5m 1 0.6m -0.5 1m 0)
R1 in a 10
L1 a 0 1m
.tran 5u 1.5m uic
.end
""",
        ("v(a)", "i(V1)"),
    ),
    # EXP with TD2 inside the run (a rise, then the fall back), into an RC
    "exp-rc": (
        """An exponential pulse into an RC
V1 in 0 EXP(0 2 0.2m 0.1m 0.8m 0.3m)
R1 in out 100
C1 out 0 1u
.tran 10u 2m uic
.end
""",
        ("v(out)", "i(V1)"),
    ),
    # PWL delayed by TD= and repeated from its second point by R= (a sawtooth after the
    # first ramp, with a jump back at each repeat; the corners are off the TSTEP grid,
    # where ngspice, which puts no breakpoint at a delayed corner, is exact too)
    "pwl-repeat-rc": (
        """A delayed, repeating PWL into an RC
V1 in 0 PWL(0 0 0.1m 1 0.3m -1 0.4m 0.5) TD=0.153m R=0.1m
R1 in out 100
C1 out 0 1u
.tran 10u 2m uic
.end
""",
        ("v(out)", "i(V1)"),
    ),
    # a negative TD starts the sine before t = 0: SIN(0 1 1k -0.25m) is a cosine
    "cosine-rc": (
        """A cosine from a sine with a negative delay, into an RC
V1 in 0 SIN(0 1 1k -0.25m)
R1 in out 100
C1 out 0 1u
.tran 10u 3m uic
.end
""",
        ("v(out)", "i(V1)"),
    ),
    # SFFM with every value given, phases included (ngspice 39's order: VO VA FC MDI FS
    # PHASEC PHASES), into an RC whose corner sits between the FM band's edges
    "sffm-rc": (
        """An FM wave into an RC
V1 in 0 SFFM(0.2 1 10k 3 1k 30 60)
R1 in out 100
C1 out 0 0.1u
.tran 2u 2m uic
.end
""",
        ("v(in)", "v(out)", "i(V1)"),
    ),
    # a current source's SFFM with ngspice 39's defaults: FS = 1/TSTOP (the 0 given),
    # FC = 1/TSTOP when absent is covered by the reader's test; the current flows from
    # n+ through the source to n-, so into node a here
    "isffm-rl": (
        """An FM current into an RL
I1 0 a SFFM(0 1m 5k 2 0)
R1 a 0 1k
L1 a 0 10m
.tran 2u 1m uic
.end
""",
        ("v(a)",),
    ),
    # AM as ngspice 39 reads it, AM(VA VO MF FC TD PHASEC PHASES): delayed (a corner at
    # TD = 0.13 m, off the TSTEP grid), PHASEC read and not used (were it the carrier's
    # phase the wave would jump at TD; a jump there, as PHASES ≠ 0 makes, stops ngspice
    # 39's fine run: "timestep too small", so the phases are checked on a resistor below)
    "am-rc": (
        """An AM wave into an RC
V1 in 0 AM(0.5 2 1k 10k 0.13m 30 0)
R1 in out 100
C1 out 0 0.1u
.tran 2u 2m uic
.end
""",
        ("v(in)", "v(out)", "i(V1)"),
    ),
    # a current source's AM with MF given as 0 (ngspice 39: 1/TSTOP) and TD, PHASES absent
    "iam-rl": (
        """An AM current into an RL
I1 0 a AM(1m 0.5 0 5k)
R1 a 0 1k
L1 a 0 10m
.tran 2u 1m uic
.end
""",
        ("v(a)",),
    ),
}


def _errors(name: str):
    """Worst error over the output grid relative to each probe's peak, per probe."""
    netlist, probes = DECKS[name]
    result = spice.run(netlist)
    settings = result.settings
    t_ref, ref = ngspice(netlist, probes, tmax=settings.step / 50, options=FINE)
    # ngspice's first written point is a little after 0 (its UIC point is not written):
    # the grid's t = 0 is checked against the initial state in the other tests
    keep = result.time >= t_ref[0]
    assert np.count_nonzero(keep) >= len(result.time) - 1
    out = {}
    for probe in probes:
        peak = np.max(np.abs(ref[probe]))
        want = np.interp(result.time[keep], t_ref, ref[probe])
        out[probe] = np.max(np.abs(result[probe][keep] - want)) / peak
    return result, out


@needs_ngspice
@pytest.mark.parametrize("name", list(DECKS))
def test_decks_agree_with_a_fine_ngspice_at_their_own_settings(name):
    result, errors = _errors(name)
    settings = result.settings
    # output on the TSTEP grid, TSTOP included
    np.testing.assert_allclose(np.diff(result.time), settings.step, rtol=1e-9)
    assert result.time[0] == 0.0 and result.time[-1] == pytest.approx(settings.stop)
    # the steps were the run's own: ≤ TMAX, and not all equal
    march = result.trajectory
    assert np.max(march.h) <= settings.max_step * (1 + 1e-12)
    assert np.min(march.h) < 0.5 * np.max(march.h)
    for probe, err in errors.items():
        assert err <= 1e-3, (probe, err)


@pytest.mark.parametrize(
    "name",
    [
        "rc",
        "rlc",
        "ladder",
        pytest.param("coupled", marks=pytest.mark.slow),
        pytest.param("rectifier", marks=pytest.mark.slow),
        pytest.param("bridge", marks=pytest.mark.slow),
    ],
)
def test_validation_circuits_agree_at_their_own_settings(name):
    """The committed fine-ngspice references (tests/data/ngspice; no ngspice needed), at
    each netlist's own .tran and default tolerances, on its TSTEP grid."""
    netlist, probes, _ = ng.CIRCUITS[name]
    t_ref, ref = ng.load(name)
    result = spice.run(netlist)
    assert result.trajectory.status == 0
    # the reference's 101 times are points of the TSTEP grid
    at = np.searchsorted(result.time, t_ref - 1e-9 * t_ref[-1])
    np.testing.assert_allclose(result.time[at], t_ref, rtol=0, atol=1e-9 * t_ref[-1])
    for probe in probes:
        # t = 0 is not an independent check (SPICE's UIC point is the given state)
        err = np.max(np.abs(result[probe][at] - ref[probe])[1:]) / np.max(np.abs(ref[probe]))
        assert err <= 1e-3, (probe, err)


@pytest.mark.slow
def test_each_solve_of_a_try_starts_from_a_predicted_end():
    """The variable-step loop's Newton solves start from predicted ends
    (``driver.tries.three_steps``: the coarse step's end extrapolated along the last two
    velocities, the fine ones from the coarse step's solution). On the bridge rectifier
    at its own tolerances that is 2.94 simplified-Newton iterations a solve (its fresh
    factorization, an update, the update that confirms it, sometimes one more); guessed
    from the last velocity alone it took 5.2."""
    march = spice.run(ng.CIRCUITS["bridge"][0]).trajectory
    assert march.status == 0
    assert march.iterations <= 3.2 * 3 * march.tries, march.iterations / (3 * march.tries)


def test_every_breakpoint_is_a_node_of_the_run():
    netlist, _ = DECKS["square-rc"]
    result = spice.run(netlist)
    corners = breakpoints(result.netlist.system, 0.0, result.settings.stop)
    # PULSE(0 5 0 1u 1u 0.5m 1m) over 3 ms: four corners a period, three periods, and
    # the fourth period's start at TSTOP
    expected = [k * 1e-3 + c for k in range(3) for c in (0.0, 1e-6, 0.501e-3, 0.502e-3)]
    expected.append(3e-3)
    np.testing.assert_allclose(corners, expected, rtol=0, atol=1e-18)
    nodes = result.internal.time
    for corner in corners:
        assert np.min(np.abs(nodes - corner)) <= 1e-15 * result.settings.stop, corner


def test_waveform_breakpoints():
    pulse = cp.Pulse(0, 1, 1.0, 0.1, 0.2, 0.5, 2.0)
    assert pulse.breakpoints(0.0, 4.0) == (1.0, 1.1, 1.6, 1.8, 3.0, 3.1, 3.6, 3.8)
    assert pulse.breakpoints(3.05, 3.7) == (3.1, 3.6)
    counted = cp.Pulse(0, 1, 1.0, 0.1, 0.2, 0.5, 2.0, count=1)
    assert counted.breakpoints(0.0, 10.0) == (1.0, 1.1, 1.6, 1.8)
    assert cp.PWL([0, 1, 3], [0, 2, 2]).breakpoints(0.5, 3.0) == (1.0, 3.0)
    assert cp.Sine(0, 1, 50, 0.25).breakpoints(0.0, 1.0) == (0.25,)
    assert cp.Sine(0, 1, 50).breakpoints(0.0, 1.0) == ()
    assert cp.DC(1.0).breakpoints(0.0, 1.0) == ()


def test_waveform_cycles_bound_its_oscillations():
    """``cycles`` (what a run's budget of tries counts) is ``∫ f_max dt``: the sine's
    periods exactly, and at least half the zero crossings of an FM or AM wave."""

    def half_crossings(wave, t0, t1, centre):
        u = np.asarray(wave(jnp.linspace(t0, t1, 2_000_001))) - centre
        return np.count_nonzero(np.signbit(u[1:]) != np.signbit(u[:-1])) / 2

    sine = cp.Sine(0.5, 1, 1e3, 2e-3)
    assert sine.cycles(0.0, 10e-3) == pytest.approx(8.0)
    assert half_crossings(sine, 0.0, 10e-3, 0.5) == pytest.approx(8.0, abs=0.5)
    fm = cp.SFFM(0.1, 2, 200, 45, 10e3)  # ng_v_i_sources_am_ffm's V2: up to 450.2 kHz
    assert fm.cycles(0.0, 1e-3) == pytest.approx(450.2)
    assert 0.5 * fm.cycles(0.0, 1e-3) < half_crossings(fm, 0.0, 1e-3, 0.1) <= fm.cycles(0.0, 1e-3)
    am = cp.AM(2, 0.5, 1e3, 20e3, 1e-3)
    assert am.cycles(0.0, 3e-3) == pytest.approx(21e3 * 2e-3)
    assert half_crossings(am, 1e-3 + 1e-9, 3e-3, 0.0) <= am.cycles(0.0, 3e-3)
    assert cp.DC(1.0).cycles(0.0, 1.0) == 0.0
    assert cp.Pulse(0, 1, 1.0, 0.1, 0.2, 0.5, 2.0).cycles(0.0, 4.0) == 0.0


def test_sampler_is_exact_for_quadratics_at_the_ends_and_at_corners():
    """Step-centred values of a quadratic on each interval are reproduced everywhere,
    including the run's ends and the breakpoints half a step beyond the last centre (a
    linear extrapolation there would be off by (3/8) h² f'')."""
    rng = np.random.default_rng(3)
    bounds = np.array([0.0, 0.3, 1.0])
    t = np.unique(np.concatenate([bounds, rng.uniform(0, 1, 40)]))
    h = np.diff(t)
    sampler = Sampler(t, h, bounds)
    centres = t[:-1] + h / 2

    def f(x):  # a kink at 0.3 (the breakpoint), smooth on either side
        return np.where(x <= 0.3, 2.0 * x**2 - x, -3.0 * (x - 0.3) ** 2 + 0.5 * (x - 0.3) - 0.12)

    query = np.concatenate([t, np.linspace(0, 1, 37)])
    np.testing.assert_allclose(sampler(f(centres), query), f(query), rtol=0, atol=1e-12)


def test_a_time_an_ulp_past_a_corner_is_read_on_the_corner():
    """ngspice's corner of ``PULSE(… td tr pw …)`` can be an ulp from this run's (another
    order of the same sum); a current that jumps there is read as its left limit at
    either time, not the other side of the jump."""
    corner = np.nextafter(
        1.04e-6, 1.0
    )  # ngspice's 1.0400000000000002e-06 (tests/general/mosmem.cir)
    bounds = np.array([0.0, 1.04e-6, 2e-6])
    t = np.unique(np.concatenate([bounds, np.linspace(0.0, 2e-6, 41)]))
    h = np.diff(t)
    centres = t[:-1] + h / 2
    jump = np.where(centres < bounds[1], 0.0, 1.0)  # 0 before the corner, 1 after
    sampler = Sampler(t, h, bounds)
    query = np.array([bounds[1], corner, np.nextafter(corner, 1.0), 1.05e-6])
    assert corner > bounds[1]
    np.testing.assert_allclose(sampler(jump, query), [0.0, 0.0, 0.0, 1.0], rtol=0, atol=1e-15)


RAMP = """A current ramp into a capacitor: v(out) = t²/2 exactly
I1 0 out PWL(0 0 1 1)
C1 out 0 1
R1 out 0 1e9
.tran 0.05 1 uic
.end
"""


@pytest.mark.parametrize("fixed", [False, True])
def test_node_voltages_at_the_ends_are_second_order(fixed):
    """At the run's ends the node voltages are extrapolated from inside the run; their
    error must be of the order of the interior error (second order), which a linear
    extrapolation (error h² f'') is not."""
    result = spice.run(RAMP, dt=0.05) if fixed else spice.run(RAMP, internal=True)
    t = result.time
    exact = 0.5 * t**2 - 0.5 * t**4 * 1e-9 / 12  # the leak is negligible; kept honest
    err = np.abs(result["v(out)"] - exact)
    interior = np.max(err[1:-1])
    assert interior > 0.0
    assert err[0] <= 1.5 * interior and err[-1] <= 1.5 * interior, (err[0], err[-1], interior)


def _lc_and_ladder():
    tank = """LC tank, charged capacitor
L1 a 0 1m
C1 a 0 1u IC=1
.tran 2u 1m uic
.end
"""
    ladder = """RLC ladder driven by a pulse
V1 in 0 PULSE(0 1 10u 1u 1u 100u 300u)
R1 in a 5
L1 a b 100u
C1 b 0 1u
L2 b c 100u
C2 c 0 1u
R2 c 0 20
.tran 1u 600u uic
.end
"""
    return {"tank": tank, "ladder": ladder}


@pytest.mark.parametrize("name", ["tank", "ladder"])
def test_variable_steps_keep_kcl_and_the_power_balance_per_step(name):
    r"""Each variable step is a Dirac step: KCL ``B v_k = 0`` to round-off, and
    ``E_{k+1} − E_k = h_k F(q̄_k, v_k, t_{k+½})·v_k`` with the stored energy
    ``E = ½ p̂_Lᵀ M_L⁻¹ p̂_L + V(q)`` at the nodes (``p̂_k = p_k − ½Bᵀc_{k−1}``, the
    momentum the two steps at node k agree on, with ``c`` the step impulses)."""
    result = spice.run(_lc_and_ladder()[name])
    march, system = result.trajectory, result.netlist.system
    t, h, q, p, mu = march.t, march.h, march.q, march.p, march.mu
    assert np.max(h) / np.min(h) > 5.0  # the steps did vary
    rule = get_rule("midpoint")
    # each check below is one jitted program: run eagerly, every primitive of the vmapped
    # maps was dispatched (and compiled) on its own, ~110 small programs per case (the
    # two cases: 11.4 → 5.5 s CPU); the same arithmetic, checked at the same round-off
    con = jax.jit(
        jax.vmap(lambda a, b, hh, tt: discrete_constraints(rule, system, "plus", a, b, hh, tt))
    )(q[:-1], q[1:], h, t[:-1])
    v = np.diff(q, axis=0) / h[:, None]
    assert np.max(np.abs(con)) <= 1e-12 * max(1.0, np.max(np.abs(v)))
    # impulses c_k from μ_k = ½(c_{k−1} + c_k), c_{−1} = 0
    c = np.empty_like(mu)
    prev = np.zeros(mu.shape[1])
    for k in range(len(h)):
        prev = 2.0 * mu[k] - prev
        c[k] = prev
    reaction = np.asarray(
        jax.jit(jax.vmap(lambda a, m: system.multiplier_force(a, m, 0.0)))(q[:-1], c)
    )
    p_hat = p.copy()
    p_hat[1:] -= 0.5 * reaction  # p̂_{k+1} = p_{k+1} − ½ Bᵀ c_k
    zero = jnp.zeros(system.n)
    mass = np.asarray(jax.jit(jax.hessian(lambda vv: system.lagrangian(q[0], vv, 0.0)))(zero))
    inductive = np.flatnonzero(np.abs(np.diag(mass)) > 0)
    m_inv = np.linalg.inv(mass[np.ix_(inductive, inductive)])
    kinetic = 0.5 * np.einsum("ki,ij,kj->k", p_hat[:, inductive], m_inv, p_hat[:, inductive])
    potential = np.asarray(jax.jit(jax.vmap(lambda a, tt: -system.lagrangian(a, zero, tt)))(q, t))
    energy = kinetic + potential
    mid = 0.5 * (q[:-1] + q[1:])
    force = np.asarray(jax.jit(jax.vmap(system.force))(mid, v, t[:-1] + h / 2))
    work = h * np.sum(force * v, axis=1)
    scale = np.max(np.abs(energy)) + np.max(np.abs(work))
    assert np.max(np.abs(np.diff(energy) - work)) <= 1e-12 * scale
    # non-inductive coordinates carry no nodal momentum (consistent data stay consistent)
    others = np.setdiff1d(np.arange(system.n), inductive)
    assert np.max(np.abs(p_hat[:, others])) <= 1e-12 * max(1.0, np.max(np.abs(p_hat)))
    if name == "tank":  # lossless: the energy is conserved to round-off over the run
        assert np.max(np.abs(energy - energy[0])) <= 1e-12 * energy[0]


def test_a_new_step_size_or_tolerance_does_not_compile_again():
    deck, _ = DECKS["square-rc"]
    first = spice.run(deck)
    traces = _adaptive.TRACES["count"]
    tighter = deck.replace(".tran 10u 3m uic", ".tran 10u 3m 0 3u uic\n.options reltol=1e-5")
    second = spice.run(tighter)
    assert _adaptive.TRACES["count"] == traces
    assert second.settings.reltol == 1e-5 and second.settings.max_step == 3e-6
    assert len(second.trajectory.h) > len(first.trajectory.h)
    assert np.max(second.trajectory.h) <= 3e-6 * (1 + 1e-12)


def test_keyword_tolerances_and_tmax_run_the_deck_as_if_it_said_so():
    # the deck unedited, run as if its .options and .tran TMAX gave these: the same settings,
    # the same steps and waveforms, bit for bit
    deck, _ = DECKS["square-rc"]
    written = deck.replace(
        ".tran 10u 3m uic", ".tran 10u 3m 0 3u uic\n.options reltol=1e-5 vntol=1e-8"
    )
    said = spice.run(written)
    given = spice.run(deck, reltol=1e-5, vntol=1e-8, tmax=3e-6)
    assert given.settings == said.settings
    np.testing.assert_array_equal(given.trajectory.t, said.trajectory.t)
    np.testing.assert_array_equal(given["v(out)"], said["v(out)"])
    # a keyword replaces what the deck says, whichever way
    loose = spice.run(written, reltol=1e-3, tmax=1e-5)
    assert (loose.settings.reltol, loose.settings.max_step, loose.settings.vntol) == (
        1e-3,
        1e-5,
        1e-8,
    )
    assert len(loose.trajectory.h) < len(said.trajectory.h)


def test_bad_keyword_tolerances_name_the_argument_and_the_fix(tmp_path):
    deck = DECKS["rc-charge"][0]
    fix = r"must be a finite number > 0 \(SPICE's \.options reltol\); e\.g\. reltol=1e-5"
    for bad in (-1e-5, 0.0, float("nan"), float("inf"), "1e-5", True):
        with pytest.raises(ModelError, match=rf"reltol={re.escape(repr(bad))}: {fix}"):
            spice.run(deck, reltol=bad)
    with pytest.raises(ModelError, match=r"tmax='1n': .*\.tran TMAX\); e\.g\. tmax=1e-9"):
        spice.run(deck, tmax="1n")
    with pytest.raises(ModelError, match=r"spice\.run\(reltol=1e-05\): .*fixed step"):
        spice.run(deck, dt=1e-4, reltol=1e-5)
    path = tmp_path / "rc.cir"
    path.write_text(deck)
    runner = CliRunner()
    for args, says in [
        ([str(path), "--reltol", "-1"], "not a finite number > 0"),
        ([str(path), "--dt", "1e-4", "--vntol", "1u"], "a fixed step (--dt/--steps) has none"),
        (["rlc", "--tmax", "1u"], "--tmax: a SPICE netlist's variable-step settings"),
    ]:
        result = runner.invoke(app, ["run", *args])
        assert result.exit_code == 2 and says in " ".join(result.output.split()), result.output
    done = runner.invoke(app, ["run", str(path), "--reltol", "1e-5", "--tmax", "20u"])
    assert done.exit_code == 0, done.output
    assert "TMAX 2e-05" in done.output and "reltol 1e-05, abstol 1e-12" in done.output


def _steps_and_tries(output: str) -> tuple[int, int]:
    """The recorded steps and the tries of ``diracvi run``'s summary of a netlist."""
    found = re.search(r"steps\s+(\d+) \(h .*?; (\d+) of (\d+) tries rejected\)", output, re.S)
    assert found is not None, output
    return int(found[1]), int(found[3])


@pytest.mark.slow  # (four runs of two decks through the CLI and spice.run: ~4 s unloaded)
def test_cli_step_error_reaches_spice_run(tmp_path):
    """``diracvi run deck --step-error KIND`` steps as ``spice.run(deck, step_error=KIND)``:
    on the sparse path (a 6-stage ladder, 19 coordinates) the two controls take different
    steps; a deck the compiled loop steps (the series RLC, 3 coordinates) is judged by step
    doubling whatever is given, by the CLI as by ``spice.run``."""
    from diracvi.bench.ladders import ladder

    runner = CliRunner()
    sparse, small = tmp_path / "ladder.cir", tmp_path / "rc.cir"
    sparse.write_text(ladder(6, steps=40))
    small.write_text(DECKS["rc-charge"][0])
    for path in (sparse, small):
        seen = {}
        for kind in ("doubling", "truncation"):
            result = runner.invoke(app, ["run", str(path), "--step-error", kind])
            assert result.exit_code == 0, result.output
            want = spice.run(str(path), step_error=kind).trajectory
            seen[kind] = _steps_and_tries(result.output)
            assert seen[kind] == (len(want.h), want.tries), (path.name, kind)
        # (a truncation try is one step: as many tries as steps but for the first and the
        # rejected; a doubled try records two)
        assert (seen["truncation"] != seen["doubling"]) == (path is sparse), seen


def test_cli_step_error_bad_values_name_the_option_and_the_choices(tmp_path):
    small = tmp_path / "rc.cir"
    small.write_text(DECKS["rc-charge"][0])
    runner = CliRunner()
    for args, says in [
        ([str(small), "--step-error", "richardson"], "'richardson' is not one of doubling, "
         "truncation"),
        ([str(small), "--dt", "1e-4", "--step-error", "truncation"], "--step-error: "
         "tolerances, TMAX and the error control steer SPICE's variable steps"),
        (["rlc", "--step-error", "truncation"], "--step-error: a SPICE netlist's variable-step"),
    ]:  # fmt: skip
        result = runner.invoke(app, ["run", *args])
        text = " ".join(result.output.replace("│", " ").split())  # (rich's box, unwrapped)
        assert result.exit_code == 2 and says in text and "--step-error" in text, result.output


def test_tran_settings_and_options():
    text = """t
V1 in 0 DC 1
R1 in 0 1k
.param tm=2u
.tran 1u 10u 4u {tm} uic
.options reltol=1e-4 abstol=1p method=gear
.end
"""
    settings = tran_settings(spice.read(text))
    assert (settings.step, settings.stop, settings.start, settings.tmax) == (1e-6, 1e-5, 4e-6, 2e-6)
    assert settings.reltol == 1e-4 and settings.abstol == 1e-12 and settings.vntol == 1e-6
    np.testing.assert_allclose(settings.output_times(), np.arange(4, 11) * 1e-6, rtol=1e-12)
    default = tran_settings(spice.read(text.replace(" 4u {tm}", "").replace("reltol", "x")))
    assert default.max_step == min(1e-6, 1e-5 / 50) and default.reltol == 1e-3


def test_the_first_output_point_is_the_operating_point_as_spice_prints_it():
    """A PULSE current rising from t = 0 into R + L: the node voltage is
    v(1) = −(R·i + L·di/dt), whose right limit at t = 0 is −L·(5 A/1 ms) = −50 V while the
    DC operating point (the left limit, every source at 0) is 0 V. SPICE prints the
    operating point at t = 0 (Xyce's inductor test deck, in the corpus as xy_inductor);
    with UIC there is no operating point and the steps' own value stands."""
    deck = """R-L fed by a current ramp
I1 1 0 PULSE(0 5 0 1m 1m 10m 25m)
L1 2 0 10m
R1 1 2 1m
.tran 0.1m 2m{uic}
.end
"""
    r, l_ = 1e-3, 10e-3

    def exact(t):  # during the rise: i = 5000·t
        return -(r * 5000.0 * t + l_ * 5000.0)

    result = spice.run(deck.format(uic=""))
    v1, t = result["v(1)"], result.time
    assert v1[0] == 0.0 and result["i(l1)"][0] == 0.0  # the operating point
    rise = (t > 0) & (t < 1e-3)
    np.testing.assert_allclose(v1[rise], exact(t[rise]), rtol=1e-9)
    dense = np.linspace(0.0, 0.9e-3, 37)
    at = result.at(dense)["v(1)"]
    assert at[0] == 0.0
    np.testing.assert_allclose(at[1:], exact(dense[1:]), rtol=1e-9)
    assert result.internal["v(1)"][0] == 0.0
    with_uic = spice.run(deck.format(uic=" uic"))
    assert with_uic["v(1)"][0] == pytest.approx(exact(0.0), rel=1e-9)


@needs_ngspice
def test_output_from_tstart():
    netlist, probes = DECKS["delayed-sin"]
    late = netlist.replace(".tran 10u 3m uic", ".tran 10u 3m 1m uic")
    result = spice.run(late)
    assert result.time[0] == pytest.approx(1e-3) and len(result.time) == 201
    t_ref, ref = ngspice(netlist, probes, tmax=10e-6 / 50, options=FINE)
    for probe in probes:
        peak = np.max(np.abs(ref[probe]))
        assert np.max(np.abs(result[probe] - np.interp(result.time, t_ref, ref[probe]))) <= (
            1e-3 * peak
        )


def test_a_variable_step_file_reads_as_its_dataset(tmp_path):
    """``Result.save`` writes a variable-step run with h5netcdf alone (no xarray import);
    xarray reads from it the very dataset ``to_xarray`` builds and xarray would write:
    values, coordinate, attributes and their types, fill values, variable order."""
    import xarray as xr

    result = spice.run(DECKS["rc-charge"][0])
    ours, theirs = tmp_path / "ours.nc", tmp_path / "theirs.nc"
    result.save(ours)
    result.to_xarray().to_netcdf(theirs, engine="h5netcdf")
    with (
        xr.open_dataset(ours, engine="h5netcdf") as a,
        xr.open_dataset(theirs, engine="h5netcdf") as b,
    ):
        assert a.identical(b) and list(a.variables) == list(b.variables)
        assert {k: type(v) for k, v in a.attrs.items()} == {k: type(v) for k, v in b.attrs.items()}
        for name in b.variables:
            assert np.isnan(a[name].encoding["_FillValue"]) == np.isnan(
                b[name].encoding["_FillValue"]
            )
        np.testing.assert_array_equal(a["v(out)"].values, result["v(out)"])


def test_cli_dt_keeps_a_fixed_step_to_tstop(tmp_path):
    deck = tmp_path / "rc.cir"
    deck.write_text(DECKS["rc-charge"][0])
    runner = CliRunner()
    fixed = runner.invoke(app, ["run", str(deck), "--dt", "20u", "--out", str(tmp_path / "f.nc")])
    assert fixed.exit_code == 0, fixed.output
    assert re.search(r"steps\s+250 of 250, dt = 2e-05", fixed.output), fixed.output
    assert re.search(r"time\s+0 → 0\.005", fixed.output), fixed.output
    adaptive = runner.invoke(app, ["run", str(deck), "--out", str(tmp_path / "v.nc")])
    assert adaptive.exit_code == 0, adaptive.output
    assert "variable steps" in adaptive.output and "51 points every 0.0001" in adaptive.output
    import xarray as xr

    with xr.open_dataset(tmp_path / "v.nc", engine="h5netcdf") as ds:
        np.testing.assert_allclose(ds["time"].values, np.linspace(0, 5e-3, 51), rtol=1e-12)
        exact = 1.0 - np.exp(-ds["time"].values / 1e-3)
        assert np.max(np.abs(ds["v(out)"].values - exact)) <= 1e-3
    with xr.open_dataset(tmp_path / "f.nc", engine="h5netcdf") as ds:
        assert ds["time"].values[-1] == pytest.approx(5e-3) and ds.sizes["time"] == 251


def test_fixed_dt_is_the_simulate_run_bitwise():
    import diracvi as dv

    netlist = spice.read(DECKS["rc-charge"][0])
    result = spice.run(netlist, dt=1e-4)
    traj = dv.simulate(
        netlist.system, netlist.q0, netlist.p0, dt=1e-4, steps=50, discretization="midpoint"
    )
    np.testing.assert_array_equal(result.time, traj.t)
    np.testing.assert_array_equal(result["v(out)"], spice.waveforms(netlist, traj)["v(out)"])
    assert math.isclose(result.time[-1], 5e-3)


def test_bad_tran_or_options_name_the_line_and_the_fix():
    base = DECKS["rc-charge"][0]
    # the reader checks .tran and .options, each problem naming its line
    with pytest.raises(spice.NetlistError, match=r"line 5: '\.tran' needs 0 ≤ TSTART < TSTOP"):
        spice.read(base.replace(".tran 0.1m 5m uic", ".tran 0.1m 5m 6m uic"))
    with pytest.raises(spice.NetlistError, match=r"line 6: \.options reltol=-1 must be a positive"):
        spice.read(base.replace(".end", ".options reltol=-1\n.end"))
    with pytest.raises(spice.NetlistError, match=r"line 5: '\.tran' needs TMAX > 0"):
        spice.read(base.replace(".tran 0.1m 5m uic", ".tran 0.1m 5m 0 -1u uic"))


def test_a_tolerance_below_round_off_stops_with_the_fix():
    from diracvi import StepFailure

    deck = DECKS["rc-charge"][0].replace(
        ".end", ".options reltol=1e-17 abstol=1e-30 chgtol=1e-40\n.end"
    )
    with pytest.raises(StepFailure, match=r"stopped at t = .* below hmin.*Fix: a fixed step"):
        spice.run(deck)
    # the fix it names works
    assert spice.run(deck, dt=1e-4).trajectory.status == 0


def test_a_solution_that_blows_up_is_named_as_such():
    from diracvi import StepFailure

    # C dv/dt = k v³ (the B source pushes k v³ into the node): v = v0 / sqrt(1 − 2 k v0² t / C)
    # blows up at t* = C / (2 k v0²) = 5e-7 s; no step follows it, and the message says so
    deck = "blow-up\nC1 n 0 1n ic=1\nB1 n 0 I=-1m*v(n)^3\n.tran 1n 1u uic\n.end\n"
    with pytest.raises(StepFailure, match=r"below hmin.*runs away there: \|v\(n\)\|") as info:
        spice.run(deck)
    stop = info.value.trajectory.t[-1]
    assert 0.99 * 5e-7 < stop < 5e-7
    assert "Fix: a fixed step" not in str(info.value)  # (that fix does not apply here)


def _source(netlist, name):
    (part,) = [s for s in netlist.system.subsystems if s.name == name]
    (wave,) = part.waveforms
    return wave


def test_pulse_and_sin_defaults_without_ngspice():
    """ngspice's defaults, checked on the read waveforms (the decks above check them
    against ngspice itself): PULSE's PW and PER are TSTOP, TR and TF are TSTEP; SIN
    holds VO + VA sin(PHASE) until TD, then runs from TD."""
    text = """defaults
V1 a 0 PULSE(0 1 1u)
V2 b 0 SIN(0.5 2 1k 0.2m 0 30)
R1 a b 1k
R2 b 0 1k
.tran 1u 1m
.end
"""
    netlist = spice.read(text)
    pulse, sine = _source(netlist, "V1"), _source(netlist, "V2")
    # rises over TSTEP = 1 µs from TD = 1 µs, then stays up to TSTOP (PW = TSTOP)
    assert float(pulse(1.5e-6)) == pytest.approx(0.5)
    assert float(pulse(2e-6)) == 1.0 and float(pulse(0.9e-3)) == 1.0
    assert pulse.breakpoints(0.0, 1e-3) == (1e-6, 2e-6)
    held = 0.5 + 2 * math.sin(math.radians(30))
    assert float(sine(0.1e-3)) == pytest.approx(held, rel=1e-15)
    t = 0.45e-3
    running = 0.5 + 2 * math.sin(2 * math.pi * 1e3 * (t - 0.2e-3) + math.radians(30))
    assert float(sine(t)) == pytest.approx(running, rel=1e-12)
    assert sine.breakpoints(0.0, 1e-3) == (0.2e-3,)


def test_exp_pwl_options_and_negative_sin_delay_without_ngspice():
    """Values ngspice 39 prints for these lines (``print`` in a .control run): EXP's TD1,
    TAU1, TAU2 default to TSTEP and TD2 to TD1 + TSTEP (0 counts as not given); PWL's TD=
    shifts the list and R= repeats it from that point, jumping back after the last value;
    a negative SIN delay starts the wave before t = 0."""
    netlist = spice.read(
        """sources
V1 a 0 EXP(0 1)
V2 b 0 EXP(0 1 0 2u)
V3 c 0 SIN(0 5 100k -2.5u)
R1 a 0 1
R2 b 0 1
R3 c 0 1
.tran 1u 10u
.end
"""
    )
    exp1, exp2, cosine = (_source(netlist, n) for n in ("V1", "V2", "V3"))
    assert float(exp1(1e-6)) == 0.0 and float(exp2(0.9e-6)) == 0.0
    assert float(exp1(2.056e-6)) == pytest.approx(5.976947e-01, rel=1e-6)
    assert float(exp2(2.056e-6)) == pytest.approx(3.557558e-01, rel=1e-6)
    assert exp1.breakpoints(0.0, 10e-6) == (1e-6, 2e-6)
    for t in (0.0, 1e-6, 3.3e-6):
        assert float(cosine(t)) == pytest.approx(5 * math.cos(2 * math.pi * 1e5 * t), abs=1e-12)
    assert cosine.breakpoints(0.0, 10e-6) == ()

    pwl = _source(
        spice.read("pwl\nV1 a 0 PWL(0 0 1 1 2 0) r=1 td=0.5\nR1 a 0 1\n.tran 0.1 5\n.end\n"),
        "V1",
    )
    printed = {0.328: 0.0, 1.15: 0.65, 2.45: 0.05, 2.55: 0.95, 3.05: 0.45, 4.45: 0.05, 4.55: 0.95}
    for t, value in printed.items():
        assert float(pwl(t)) == pytest.approx(value, abs=1e-12), t
    assert float(pwl(2.5)) == pytest.approx(0.0, abs=1e-15)  # the last value, then the jump
    assert pwl.breakpoints(0.0, 5.0) == (0.5, 1.5, 2.5, 3.5, 4.5)


def test_source_option_mistakes_name_the_line_and_the_fix():
    with pytest.raises(spice.NetlistError, match=r"line 2: .*R=0\.5 must be one of the times"):
        spice.read("x\nV1 a 0 PWL(0 0 1 1 2 0) R=0.5\nR1 a 0 1\n.tran 0.1 5\n.end\n")
    with pytest.raises(spice.NetlistError, match=r"line 2: TD= belongs to a PWL source"):
        spice.read("x\nV1 a 0 SIN(0 1 1k) TD=1m\nR1 a 0 1\n.tran 0.1m 5m\n.end\n")
    with pytest.raises(spice.NetlistError, match=r"line 2: EXP\(V1 V2 \[TD1"):
        spice.read("x\nV1 a 0 EXP(0)\nR1 a 0 1\n.tran 0.1m 5m\n.end\n")


def test_sffm_defaults_and_refused_functions_without_ngspice():
    """SFFM's defaults as ngspice 39 takes them (FC and FS absent or 0: 1/TSTOP; MDI
    absent: 0; the decks above check the formula against ngspice itself), a note where
    a deck gives the values ngspice 46 reads otherwise, TRNOISE refused with why, and
    too many values for SFFM and AM, or AM's MF default without a '.tran', refused."""
    netlist = spice.read(
        "x\nV1 a 0 SFFM(0.5 2)\nV2 b 0 SFFM(0 1 1k 2 0 90 0)\nR1 a b 1\n.tran 1u 4m\n.end\n"
    )
    plain, phased = _source(netlist, "V1"), _source(netlist, "V2")
    t = 0.3e-3
    # MDI = 0: a sine of 1/TSTOP = 250 Hz
    assert float(plain(t)) == pytest.approx(0.5 + 2 * math.sin(2 * math.pi * 250 * t), rel=1e-14)
    # FS given as 0 is 1/TSTOP; PHASEC = 90°
    want = math.sin(2 * math.pi * 1e3 * t + math.pi / 2 + 2 * math.sin(2 * math.pi * 250 * t))
    assert float(phased(t)) == pytest.approx(want, rel=1e-13)
    assert plain.breakpoints(0.0, 4e-3) == ()
    assert [n for n in netlist.notes if "6th and 7th" in n] == [
        "line 3: SFFM's 6th and 7th values read as ngspice 39 reads them, the carrier's and "
        "the signal's phases in degrees (ngspice 46 reads TD and PHASEM there)"
    ]
    with pytest.raises(spice.NetlistError, match=r"line 2: .*transient noise is random"):
        spice.read("x\nV1 a 0 TRNOISE(1m 1n 0 0)\nR1 a 0 1\n.tran 1u 1m\n.end\n")
    with pytest.raises(spice.NetlistError, match=r"line 2: SFFM\(VO VA \[FC .* 2 to 7 values"):
        spice.read("x\nI1 a 0 SFFM(0 1 1k 2 1k 0 0 5 6)\nR1 a 0 1\n.tran 1u 1m\n.end\n")
    with pytest.raises(spice.NetlistError, match=r"line 2: AM\(VA VO \[MF .* 2 to 7 values"):
        spice.read("x\nV1 a 0 AM(1 0 1k 10k 0 0 0 0 1)\nR1 a 0 1\n.tran 1u 1m\n.end\n")
    with pytest.raises(spice.NetlistError, match=r"line 2: AM MF defaults to 1/TSTOP"):
        spice.read("x\nV1 a 0 AM(1 0)\nR1 a 0 1\n.end\n")
    with pytest.raises(spice.NetlistError, match=r"line 2: SFFM FC and FS default to 1/TSTOP"):
        spice.read("x\nV1 a 0 SFFM(0 1)\nR1 a 0 1\n.end\n")


# every AM and SFFM form a deck may write, each source across its own 1 Ω (a V source's
# node is its value; a current source drives n+ → n-, so node c is +I·1 Ω): the values,
# defaults and phases as ngspice 39 reads them, the 8th value of each ignored
SOURCE_FORMS = """AM and SFFM forms
V1 a 0 AM(0.5 2 1k 100k 1m 30 60)
V2 b 0 AM(0.5 2 1.8 1k 100k 1m 0 0)
I3 0 c AM(0.7 -0.4 0 20k 0 0 -45)
R3 c 0 1
V4 d 0 AM(1.5 0.3 2k)
V5 e 0 SFFM(0.1 2 200 45 10k 1m 0 0)
V6 f 0 SFFM(0.1 2 200 45 10k 30 60 90)
R1 a b 1
.tran 1u 3m
.end
"""


@needs_ngspice
def test_am_and_sffm_are_ngspices_waveforms_to_round_off():
    """The read waveforms at ngspice's own time points against ngspice 39's node values
    (15 digits): the same to round-off (1e-12 of the peak, plus the slope times the
    printed time's rounding, 1e-15·t: SFFM's phase turns at 2.8 Mrad/s), so a wrong
    sign, default, phase or delay fails
    (V2 is the AM line of ngspice's examples/various/v_i_sources_am_ffm.cir: with 39's
    reading its TD is 100k, so it is 0 throughout; V4's FC is absent, 0, so is V4)."""
    netlist = spice.read(SOURCE_FORMS)
    probes = {"V1": "v(a)", "V2": "v(b)", "I3": "v(c)", "V4": "v(d)", "V5": "v(e)", "V6": "v(f)"}
    t, ref = ngspice(SOURCE_FORMS, tuple(probes.values()), tmax=1e-6)
    assert t[-1] == pytest.approx(3e-3)
    for name, probe in probes.items():
        u = _source(netlist, name)
        wave = np.asarray(u(jnp.asarray(t)))
        slope = np.abs(np.asarray(jax.vmap(jax.grad(u))(jnp.asarray(t))))
        bound = 1e-12 * max(np.max(np.abs(ref[probe])), 1.0) + 1e-15 * t * slope
        assert np.all(np.abs(wave - ref[probe]) <= bound), name
    assert np.max(np.abs(ref["v(a)"])) > 1.0 and np.max(np.abs(ref["v(c)"])) > 0.5
    # the delayed AM's corner is a breakpoint of the run; an undelayed one has none
    assert _source(netlist, "V1").breakpoints(0.0, 3e-3) == (1e-3,)
    assert _source(netlist, "I3").breakpoints(0.0, 3e-3) == ()
