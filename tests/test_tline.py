"""SPICE's lossless transmission line T (components/tline.py, driver/delay.py on fixed
steps, driver/sparse_lines.py on variable ones): the method of characteristics against
the exact delay recursion of resistive ends, ngspice, the line's energy balance, its DC
point and its refusals."""

from __future__ import annotations

import numpy as np
import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.errors import ModelError

DECK = """unmatched line, a ramped pulse
v1 1 0 pulse(0 1 1n 0.5n 0.5n 2n 40n)
rs 1 2 {rs}
t1 2 0 3 0 z0={z0} td={td}
rl 3 0 {rl}
.tran 0.01n 25n
.end
"""
LINE = dict(rs=25.0, z0=50.0, td=3e-9, rl=150.0)
CORNERS = np.array([1.0, 1.5, 3.5, 4.0]) * 1e-9  # the PULSE's


def _ramp(t):
    return np.clip((t - 1e-9) / 0.5e-9, 0, 1) - np.clip((t - 3.5e-9) / 0.5e-9, 0, 1)


def exact(t, rs, z0, td, rl, drive=_ramp):
    """``(v(2), v(3))``: port 1 is ``Z₀`` and ``e₁`` against the source and ``rs``, port
    2 ``Z₀`` and ``e₂`` against ``rl``; ``e₁(t) = w₂(t − T_D) = Γ_L e₂(t − T_D)``,
    ``e₂(t) = w₁(t − T_D)``, ``w = v + Z₀ i``: the recursion ends at ``t < 0``."""
    gamma = (rl - z0) / (rl + z0)

    def delayed(f, t):
        out = np.zeros_like(t)
        m = t - td > 0
        if m.any():
            out[m] = f(t[m] - td)
        return out

    def e1(t):
        return gamma * delayed(w1, t - td)

    def w1(t):
        u, e = drive(t), e1(t)
        return (z0 * u + rs * e) / (rs + z0) + z0 * (u - e) / (rs + z0)

    u, e = drive(t), e1(t)
    return (z0 * u + rs * e) / (rs + z0), rl * delayed(w1, t) / (rl + z0)


def _off_corners(t, td, h):
    """Nodes not at a corner of the exact waves (the PULSE's and its echoes k·T_D later):
    there the midpoint rule's node value is the mean of its two steps' values."""
    echoes = (CORNERS[:, None] + td * np.arange(10)[None, :]).ravel()
    return np.min(np.abs(t[:, None] - echoes[None, :]), axis=1) > 0.5 * h


def _worst(result, params, keep, drive=_ramp):
    v2, v3 = exact(result.time, **params, drive=drive)
    return max(np.max(np.abs(result["v(2)"] - v2)[keep]), np.max(np.abs(result["v(3)"] - v3)[keep]))


def test_unmatched_line_is_the_delay_recursion_off_its_corners():
    """A step that divides T_D and the PULSE's corners: between corners the waves are
    linear and the midpoint steps reproduce them to round-off (the reflections of both
    unmatched ends, four round trips); at a corner node the value is the mean of the two
    steps about it, off by ``h·Δslope/4`` (first order, as for any source's corner on a
    fixed step). A 5 % wrong Z0 or TD is 1e-2 … 0.3 V off."""
    h = 0.1e-9
    result = spice.run(DECK.format(**LINE), dt=h)
    keep = _off_corners(result.time, LINE["td"], h)
    assert keep.sum() > 0.8 * len(keep)
    assert _worst(result, LINE, keep) < 1e-9
    assert _worst(result, dict(LINE, z0=52.5), keep) > 1e-2
    assert _worst(result, dict(LINE, td=3.15e-9), keep) > 0.1
    # at the corners: the mean of the steps about it, h·Δslope/4 off the corner value
    at = ~keep
    v2, _ = exact(result.time, **LINE)
    assert np.max(np.abs(result["v(2)"] - v2)[at]) == pytest.approx(h * (2 / 3) / 0.5e-9 / 4)


def _sine(t):
    return np.where(t > 0, np.sin(2 * np.pi * 2e8 * t), 0.0)


@pytest.mark.slow  # four runs, one of 1000 steps: 23 s at load 8 on 2 cores
def test_delay_between_steps_is_interpolated_to_second_order():
    """T_D not a whole number of steps (60.6 and 121.2 of them): the waves are read
    between two recorded step centres. With a sine drive, away from its start and the
    start's echoes, the error falls as h² (fitted over three steps). A piecewise-linear
    wave is read exactly (linear interpolation), so the ramped pulse is round-off off
    its corners."""
    params = dict(LINE, td=3.03e-9)
    deck = DECK.format(**params).replace("pulse(0 1 1n 0.5n 0.5n 2n 40n)", "sin(0 1 200meg)")
    errs = []
    steps = (0.1e-9, 0.05e-9, 0.025e-9)
    for h in steps:
        result = spice.run(deck, dt=h)
        t = result.time
        starts = params["td"] * np.arange(10)
        keep = np.min(np.abs(t[:, None] - starts[None, :]), axis=1) > 0.3e-9
        errs.append(_worst(result, params, keep, drive=_sine))
    order = np.polyfit(np.log(steps), np.log(errs), 1)[0]
    assert 1.9 < order < 2.1, (errs, order)
    result = spice.run(DECK.format(**params), dt=0.05e-9)
    t = result.time
    echoes = (CORNERS[:, None] + params["td"] * np.arange(10)[None, :]).ravel()
    keep = np.min(np.abs(t[:, None] - echoes[None, :]), axis=1) > 0.3e-9
    assert _worst(result, params, keep) < 1e-12


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_unmatched_line_agrees_with_ngspice():
    """ngspice 39 (max step TSTOP/40000) at its own points, away from the corners of the
    waves (its breakpoints): ≤ 1e-4 V of a 1 V pulse; the exact recursion is 1e-6 from it."""
    deck = DECK.format(**LINE)
    t, ref = ng.ngspice(deck, ("v(2)", "v(3)"), tmax=25e-9 / 40000)
    h = 0.05e-9
    result = spice.run(deck, dt=h)
    keep = _off_corners(t, LINE["td"], 4 * h) & (t > 0)
    for probe in ("v(2)", "v(3)"):
        mine = np.interp(t, result.time, result[probe])
        assert np.max(np.abs(mine - ref[probe])[keep]) < 1e-4, probe
        assert np.max(np.abs(ref[probe])) > 0.5


def test_line_power_balance_closes_per_step():
    """With T_D = m·h each step's work on the ports, ``h Σ (Z₀ i + e)·i``, is the change of
    the energy of the waves in flight, ``E = Σ_{last m steps} h (a₁² + a₂²)/Z₀``,
    ``a = Z₀ i + e/2``, to round-off."""
    h = 0.1e-9
    result = spice.run(DECK.format(**LINE), dt=h)
    rec = result.trajectory.line_record
    z0, m = rec["z0"][0], round(LINE["td"] / h)
    e, i = rec["e"][:, 0, :], rec["i"][:, 0, :]
    work = h * np.sum((z0 * i + e) * i, axis=1)
    a2 = h * np.sum((z0 * i + 0.5 * e) ** 2, axis=1) / z0
    energy = np.array([a2[max(0, k - m + 1) : k + 1].sum() for k in range(len(a2))])
    previous = np.concatenate([[0.0], energy[:-1]])
    assert np.max(np.abs(work)) > 1e-13
    assert np.max(np.abs(work - (energy - previous))) < 1e-12 * np.max(np.abs(work)) + 1e-28


def test_dc_through_the_line_is_a_wire():
    """At DC a lossless line joins its ports (v₁ = v₂, i₁ = −i₂): 2 V through 50 Ω, the
    line and 150 Ω is 1.5 V at both ports, and the transient — fixed or variable steps —
    stays there."""
    deck = """dc through a line
v1 1 0 dc 2
rs 1 2 50
t1 2 0 3 0 z0=75 td=1n
rl 3 0 150
.tran 0.1n 5n
.end
"""
    for run in (dict(dt=0.1e-9), {}):  # a fixed step, and the variable steps
        result = spice.run(deck, **run)
        assert np.max(np.abs(result["v(2)"] - 1.5)) < 1e-9
        assert np.max(np.abs(result["v(3)"] - 1.5)) < 1e-9


def test_refusals_name_the_fix():
    deck = DECK.format(**LINE)
    with pytest.raises(ModelError, match="shorter than the step"):
        spice.run(deck, dt=4e-9)
    # variable steps: step doubling's loop records the waves; the truncation control and
    # the compiled loop (junctions, switches) do not carry them
    with pytest.raises(ModelError, match="step_error='doubling' only"):
        spice.run(deck, step_error="truncation")
    diode = deck.replace("rl 3 0 150", "rl 3 0 150\nd1 3 0 dmod\n.model dmod d")
    with pytest.raises(ModelError, match=r"junctions or switches.*Fix: a fixed step"):
        spice.run(diode)
    with pytest.raises(ModelError, match="discretization='midpoint'"):
        spice.run(deck, dt=1e-10, discretization="retraction")
    with pytest.raises(Exception, match="Z0= is required"):
        spice.read(deck.replace("z0=50.0 ", ""))


def test_td_from_f_and_nl():
    """Without TD the delay is NL/F (ngspice's defaults NL = 0.25, F = 1 GHz)."""
    deck = DECK.format(**LINE).replace("td=3e-09", "f=250meg nl=0.75")
    net = spice.read(deck)
    part = next(s for s in net.system.subsystems if s.name == "t1")
    assert dict(part.parameters)["delay"] == pytest.approx(3e-9)
    net = spice.read(DECK.format(**LINE).replace("td=3e-09", ""))
    part = next(s for s in net.system.subsystems if s.name == "t1")
    assert dict(part.parameters)["delay"] == pytest.approx(0.25e-9)


def test_every_other_run_refuses_a_system_with_lines():
    """dv.simulate and the compiled variable-step loop would hold the waves at 0: each
    refuses, naming the fix; the sparse loop refuses a TMAX over half the delay (its
    waves would have to be extrapolated) and the truncation control."""
    import diracvi as dv
    from diracvi.driver.adaptive import adaptive
    from diracvi.driver.adaptive_sparse import adaptive_sparse
    from diracvi.spice._run import controls
    from diracvi.spice._tran import tran_settings

    net = spice.read(DECK.format(**LINE))
    ctl = controls(net, tran_settings(net))
    q0, p0 = net.initial_state()
    with pytest.raises(ModelError, match="simulate_lines"):
        dv.simulate(net.system, q0, p0, dt=1e-10, steps=4)
    with pytest.raises(ModelError, match="fixed step no longer than"):
        adaptive(net.system, q0, p0, t0=0.0, t_stop=1e-9, controls=ctl)
    long = ctl._replace(hmax=2e-9)  # TD = 3 ns
    with pytest.raises(ModelError, match=r"hmax ≤ 1\.5e-09"):
        adaptive_sparse(net.system._packed(), q0, p0, t0=0.0, t_stop=1e-9, controls=long)
    with pytest.raises(ModelError, match="step doubling only"):
        adaptive_sparse(
            net.system._packed(), q0, p0, t0=0.0, t_stop=1e-9, controls=ctl, error="truncation"
        )


#: two matched 50 Ω ends, the line between them released from ``IC=1,0,1,0``
_RELEASED = """line released from its initial condition
r1 2 0 50
t1 2 0 3 0 z0=50 td={td} ic=1,0,1,0
r2 3 0 50
.tran 0.1n 6n uic
.end
"""


def _assert_released(result, inside, after):
    """Both ends at 0.5 V for one delay (``inside``), then 0 (``after``)."""
    for probe in ("v(2)", "v(3)"):
        assert np.max(np.abs(result[probe][inside] - 0.5)) < 1e-12
        assert np.max(np.abs(result[probe][after])) < 1e-12


def test_uic_starts_the_waves_from_ic():
    """Under UIC a line's ``IC=v1,i1,v2,i2`` are its ports before t0 (ngspice's
    ``traload.c``: ``e₁ = v₂ + Z₀ i₂``): with ``IC=1,0,1,0`` between two matched 50 Ω
    ends each port sees ``e = 1`` for one delay, so ``v = 0.5``, and then the wave that
    left the other end, ``w = v + Z₀ i = 0.5 − 0.5 = 0``. (ngspice 39: the same, 0.5 then
    0.)"""
    result = spice.run(_RELEASED.format(td="2n"), dt=0.1e-9)
    t = result.time
    _assert_released(result, (t > 0.05e-9) & (t < 1.95e-9), t > 2.05e-9)


def test_uic_on_variable_steps():
    """The same release on variable steps: 0.5 V for one delay, then 0, at every node
    (the echo of ``t₀`` is a breakpoint). The waves jump at ``t₀`` (``w₀ = 1`` before,
    ``0`` after): the history holds ``w₀`` before ``t₀`` and the right limit at it."""
    from diracvi.driver.adaptive_sparse import adaptive_sparse
    from diracvi.spice._run import _line_waves, controls
    from diracvi.spice._tran import tran_settings

    deck = _RELEASED.format(td="2.05n")
    result = spice.run(deck, internal=True)
    t = result.time
    _assert_released(result, (t > 0) & (t < 2.05e-9), t > 2.05e-9)
    net = spice.read(deck)
    settings = tran_settings(net)
    q0, p0 = net.initial_state()
    _, info = adaptive_sparse(
        net.system._packed(), q0, p0, t0=0.0, t_stop=settings.stop,
        controls=controls(net, settings), waves0=_line_waves(net),
    )  # fmt: skip
    waves = info.lines[1]
    np.testing.assert_allclose(waves.at(np.array([-1e-12])), [[1.0, 1.0]], atol=1e-15)
    np.testing.assert_allclose(waves.at(np.array([0.0])), [[0.0, 0.0]], atol=1e-12)


# ---------------------------------------------------------------- variable steps
def _variable_deck(params, drive=None, tran=".tran 0.1n 25n"):
    deck = DECK.format(**params).replace(".tran 0.01n 25n", tran)
    return deck if drive is None else deck.replace("pulse(0 1 1n 0.5n 0.5n 2n 40n)", drive)


def test_variable_steps_are_the_delay_recursion():
    """``spice.run(deck)`` without ``dt``: the sparse loop's steps, the waves read one
    delay back by linear interpolation between recorded centres, and the corners (the
    PULSE's, and each one ``k·T_D`` later, landed, the wave's value recorded there). A
    piecewise-linear wave is then stepped exactly at every node — corners included, where
    a fixed step is first order — and on the TSTEP grid; a 5 % wrong Z0 or TD is 1e-2 …
    0.3 V off."""
    result = spice.run(_variable_deck(LINE), internal=True)
    assert len(result.time) > 100
    steps = np.diff(result.time)
    assert np.max(steps) <= 0.1e-9 * (1 + 1e-9) and np.ptp(steps) > 0  # variable, ≤ TMAX
    assert _worst(result, LINE, slice(None)) < 1e-12
    assert _worst(result, dict(LINE, z0=52.5), slice(None)) > 1e-2
    assert _worst(result, dict(LINE, td=3.15e-9), slice(None)) > 0.1
    on_grid = spice.run(_variable_deck(LINE))
    assert len(on_grid.time) == 251
    assert _worst(on_grid, LINE, slice(None)) < 1e-12


@pytest.mark.slow  # three runs: 3.5 CPU s
def test_variable_step_error_falls_with_the_tolerance():
    """A sine drive (smooth waves: the interpolation's ``Δ²/8·|w''|`` and the midpoint
    rule's error), TD = 3.03 ns: against the exact recursion, away from the drive's start
    and its echoes, the error falls as ``reltol^(2/3)`` — the midpoint's local error is
    ``O(h³)``, so the control's steps go as ``reltol^(1/3)`` and the global error as
    ``h²``. Measured: 1.0e-4, 2.2e-5, 4.9e-6 V at reltol 1e-3, 1e-4, 1e-5 (exponent 0.65)."""
    params = dict(LINE, td=3.03e-9)
    deck = _variable_deck(params, drive="sin(0 1 200meg)")
    tolerances, errs = (1e-3, 1e-4, 1e-5), []
    for reltol in tolerances:
        result = spice.run(deck, internal=True, reltol=reltol)
        starts = params["td"] * np.arange(10)
        keep = np.min(np.abs(result.time[:, None] - starts[None, :]), axis=1) > 0.3e-9
        errs.append(_worst(result, params, keep, drive=_sine))
    slope = np.polyfit(np.log(tolerances), np.log(errs), 1)[0]
    assert 0.55 < slope < 0.8, (errs, slope)
    assert errs[0] < 3e-4


def test_rejected_tries_do_not_enter_the_waves():
    """The recorded waves are exactly the accepted steps' centres (and ``t₀``, and the
    landed corners ``k·T_D``, TSTOP): a rejected try's halves, solved and thrown away,
    leave nothing in the history."""
    from diracvi.driver.adaptive_sparse import adaptive_sparse
    from diracvi.spice._run import controls
    from diracvi.spice._tran import breakpoints, tran_settings

    params = dict(LINE, td=3.03e-9)
    net = spice.read(_variable_deck(params, drive="sin(0 1 200meg)", tran=".tran 0.1n 10n"))
    settings = tran_settings(net)
    q0, p0 = net.initial_state()
    run, info = adaptive_sparse(
        net.system._packed(), q0, p0, t0=0.0, t_stop=settings.stop,
        controls=controls(net, settings), breakpoints=breakpoints(net.system, 0.0, 10e-9),
        waves0=net.operating_point().waves,
    )  # fmt: skip
    assert run.status == 0 and run.rejected > 0
    t_w, _ = info.lines[1].arrays()
    centres = run.t[:-1] + 0.5 * run.h
    corners = np.array([0.0, 3.03e-9, 6.06e-9, 9.09e-9, 10e-9])
    want = np.sort(np.concatenate([centres, corners]))
    assert len(t_w) == len(want) == 2 * (run.tries - run.rejected) + len(corners)
    np.testing.assert_allclose(t_w, want, rtol=0, atol=1e-22)


def _integral_of_square(t, f, x0, x1):
    """``∫_{x0}^{x1} F²`` for ``F`` the piecewise-linear interpolant of ``(t, f)``, ``f[0]``
    before ``t[0]`` (exact: Simpson on each linear piece)."""
    total = 0.0
    if x0 < t[0]:
        total += f[0] ** 2 * (min(x1, t[0]) - x0)
        x0 = t[0]
    if x1 <= x0:
        return total
    grid = np.concatenate([[x0], t[(t > x0) & (t < x1)], [x1]])
    v = np.interp(grid, t, f)
    return total + np.sum(np.diff(grid) * (v[:-1] ** 2 + v[:-1] * v[1:] + v[1:] ** 2) / 3.0)


def test_variable_step_power_balance_closes_to_the_midpoint_quadrature():
    """On variable steps a step's work on the ports is still exactly
    ``h Σ (a² − b²)/Z₀`` (``a = Z₀ i + e/2``, the recorded half-wave; ``b = e/2``, the
    incident one read between recorded centres). Over a run, against the energy in
    flight of the recorded waves' interpolant ``A``,
    ``E(t) = (1/Z₀) ∫_{t−T_D}^{t} (A₁² + A₂²) dτ``, the work closes to the midpoint
    rule's quadrature error of the squared waves: for waves linear within each step (a
    ramped PULSE, corners landed) exactly ``E(T) − E(t₀) − W = Σ_k h_k³ Σ (a'² − b'²)/(12 Z₀)``
    — measured to 3e-13 and 1.1e-10 of it at TMAX 0.1 and 0.025 ns, while that term is
    5e-4 and 5e-5 of the work (it falls as h²)."""
    from diracvi.driver.adaptive_sparse import adaptive_sparse
    from diracvi.spice._run import controls
    from diracvi.spice._tran import breakpoints, tran_settings

    params = dict(LINE, td=3.03e-9)
    net = spice.read(_variable_deck(params, tran=".tran 0.1n 5n"))
    settings = tran_settings(net)
    q0, p0 = net.initial_state()
    terms = []
    for tmax in (0.1e-9, 0.025e-9):
        run, info = adaptive_sparse(
            net.system._packed(), q0, p0, t0=0.0, t_stop=settings.stop,
            controls=controls(net, settings)._replace(hmax=tmax),
            breakpoints=breakpoints(net.system, 0.0, settings.stop),
            waves0=net.operating_point().waves,
        )  # fmt: skip
        lines, waves = info.lines
        t_w, w = waves.arrays()
        z0, td = lines.z0[0], lines.delay[0]
        centres = run.t[:-1] + 0.5 * run.h
        ports = lines.q_index[0]
        i = (run.q[1:, ports] - run.q[:-1, ports]) / run.h[:, None]
        e = np.array([waves.at(np.array([c - td]))[0, ::-1] for c in centres])
        a, b = z0 * i + 0.5 * e, 0.5 * e
        np.testing.assert_array_equal(w[np.isin(t_w, centres), 0], 2.0 * a)  # as recorded
        work = run.h * np.sum((z0 * i + e) * i, axis=1)
        per_step = run.h * np.sum(a * a - b * b, axis=1) / z0
        assert np.max(np.abs(work - per_step)) < 1e-14 * np.max(np.abs(work))
        total, end = work.sum(), run.t[-1]
        flight = [
            sum(_integral_of_square(t_w, w[:, 0, p] / 2, x - td, x) for p in range(2)) / z0
            for x in (0.0, end)
        ]

        def wave(p, s, t_w=t_w, w=w):
            return np.interp(s, t_w, w[:, 0, p] / 2)

        term = 0.0
        for p in range(2):
            da = (wave(p, run.t[1:]) - wave(p, run.t[:-1])) / run.h
            db = (wave(1 - p, run.t[1:] - td) - wave(1 - p, run.t[:-1] - td)) / run.h
            term += np.sum(run.h**3 * (da**2 - db**2)) / (12.0 * z0)
        assert abs(flight[1] - flight[0] - total - term) < 1e-9 * abs(term)
        terms.append(term / np.sum(np.abs(work)))
    assert 1e-4 < terms[0] < 1e-3 and terms[1] < terms[0] / 8  # h²: TMAX / 4


@pytest.mark.slow  # two runs: 11 s at load 11 on 2 cores
def test_the_sparse_verification_sees_the_lines_offsets(monkeypatch):
    """The sparse map's sampled verification re-evaluates steps with the model's own
    residual, whose lines' ``e`` is 0: it adds the lines' rows the step was taken with.
    Dropped, the verified steps are off (0.41 relative on `xy_transline`) and the run is refused
    naming the fix, as the compiled loop does not carry the waves."""
    from diracvi.driver import adaptive_sparse as sparse

    deck = _variable_deck(LINE)
    assert spice.run(deck).trajectory.status == 0
    kept = sparse._Tries._line_offsets

    def dropped(self, found, u, h, e):
        u, shift = kept(self, found, u, h, e)
        return u, np.zeros_like(shift)

    monkeypatch.setattr(sparse._Tries, "_line_offsets", dropped)
    with pytest.raises(ModelError, match=r"a step was off by .* Fix: a fixed step"):
        spice.run(deck)


@pytest.mark.slow  # a variable-step and a fixed-step run: 6 CPU s at load 12 on 2 cores
def test_two_lines_of_unequal_delays_take_every_sum_of_delays_as_a_corner():
    """Two lines in cascade (1 ns into 0.7 ns, Z₀ 50 and 80 Ω, between 20 and 200 Ω): the
    waves' corners are the PULSE's plus every sum ``k₁·1 + k₂·0.7`` ns after them (109
    before 12 ns). Landed, the variable steps are exact: against a fixed step of 50 ps,
    which divides every delay and corner and is exact at its nodes off the corners, to
    round-off at every such node (TSTOP, itself a corner, 0.8 + 1 + 6·0.7 … ns, is the
    fixed step's first-order point and is left out)."""
    from diracvi.driver.sparse_lines import line_breakpoints
    from diracvi.spice._tran import breakpoints

    deck = """two lines of unequal delays in cascade
v1 1 0 pulse(0 1 0.5n 0.3n 0.3n 1n 40n)
rs 1 2 20
t1 2 0 3 0 z0=50 td=1n
t2 3 0 4 0 z0=80 td=0.7n
rl 4 0 200
.tran 0.1n 12n
.end
"""
    net = spice.read(deck)
    corners = line_breakpoints(breakpoints(net.system, 0.0, 12e-9), [1e-9, 0.7e-9], 0.0, 12e-9)
    assert len(corners) == 109
    # the PULSE's start through both lines (0.5 + 1 + 0.7 ns), there and back on t1 (0.5 + 2)
    for corner in (2.2e-9, 2.5e-9):
        assert np.min(np.abs(corners - corner)) < 1e-18
    result = spice.run(deck, internal=True)
    fixed = spice.run(deck, dt=0.05e-9)
    t = fixed.time
    at = np.concatenate([[0.0], corners, [12e-9]])
    keep = np.min(np.abs(t[:, None] - at[None, :]), axis=1) > 0.025e-9
    assert keep.sum() > 100
    mine = result.at(t)
    for probe in ("v(2)", "v(3)", "v(4)"):
        assert np.max(np.abs(mine[probe] - fixed[probe])[keep]) < 1e-12, probe
