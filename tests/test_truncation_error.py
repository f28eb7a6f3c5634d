"""The local truncation error estimate of one midpoint step (driver/truncation_error.py)
and the sparse path's loop that steps by it (driver/sparse_truncation.py).

The estimate ``(h³/2)·x[t_{k−2}, …, t_{k+1}]`` is held to the true local error of a step
taken from the exact solution of problems solved in closed form (its ratio → 1 at first
order in ``h``, whatever the ratios of the past steps); the loop to the promises of the
sparse path (breakpoints landed exactly, agreement with a fine ngspice run on the TSTEP
grid) at one solve a step.
"""

from __future__ import annotations

import numpy as np
import pytest

from _sparse_path import PULSE_DECK, sparse_run
from diracvi import spice
from diracvi.bench.ladders import ladder
from diracvi.driver import adaptive_sparse as sparse
from diracvi.driver import truncation_error as lte
from diracvi.errors import ModelError
from diracvi.spice import _ngspice as ng

#: the past steps before the one judged, as multiples of it (unequal on purpose)
H2, H1 = 1.3, 0.8


def _ratios(exact, step, hs):
    """Estimate / true local error of one step of each ``h`` in ``hs``, taken by ``step``
    from the exact state at ``t = 0.7`` with the exact past at ``−(H1 + H2)h, −H1 h``."""
    out = []
    for h in hs:
        t0 = 0.7
        x = [exact(t0 - (H1 + H2) * h), exact(t0 - H1 * h), exact(t0)]
        zero = np.zeros(1)
        history = lte.start(*x, zero, zero, zero, H1 * h, H2 * h)
        x_new = step(x[2], h)
        estimate = lte.local_error(x_new, x[2], history, h)
        true = x_new - exact(t0 + h)
        out.append(float(estimate[0] / true[0]))
    return np.array(out)


def _first_order_to_one(ratios, hs):
    gap = np.abs(ratios - 1.0)
    slope = np.polyfit(np.log(hs), np.log(gap), 1)[0]
    assert gap[-1] < 5e-3, ratios
    assert 0.8 < slope < 1.2, (slope, ratios)


def test_estimate_of_an_exponential_step_tends_to_its_true_local_error():
    """``ẋ = λx``: the midpoint step ``x (1 + λh/2)/(1 − λh/2)`` from ``e^{λt}``."""
    lam = -3.0

    def step(x, h):
        return x * (1.0 + 0.5 * lam * h) / (1.0 - 0.5 * lam * h)

    hs = 0.02 * 2.0 ** -np.arange(6)
    _first_order_to_one(_ratios(lambda t: np.array([np.exp(lam * t)]), step, hs), hs)


def test_estimate_of_an_oscillator_step_tends_to_its_true_local_error():
    """``q̈ = −ω² q`` as ``(q, p)``: the midpoint step ``(I − hA/2)⁻¹(I + hA/2)`` from
    ``(sin ωt, ω cos ωt)``; the estimate of the position's local error."""
    w = 5.0
    a = np.array([[0.0, 1.0], [-(w**2), 0.0]])

    def step(x, h):
        eye = np.eye(2)
        return np.linalg.solve(eye - 0.5 * h * a, (eye + 0.5 * h * a) @ x)

    def exact(t):
        return np.array([np.sin(w * t), w * np.cos(w * t)])

    hs = 0.01 * 2.0 ** -np.arange(6)
    _first_order_to_one(_ratios(exact, step, hs), hs)


def test_one_solve_a_step_and_breakpoints_landed_exactly(monkeypatch):
    """Every source corner is a node of the run (bitwise), no step longer than TMAX;
    each corner restarts with one doubled try (three solves), every other try is one
    solve; the factorizations stay within the fit's builds, the levels and the landings."""
    solves = []
    step = sparse._Map.step

    def counting(self, z, u):
        solves.append(self.h)
        return step(self, z, u)

    monkeypatch.setattr(sparse._Map, "step", counting)
    _, settings, breaks, march, info = sparse_run(PULSE_DECK, error="truncation")
    assert march.status == 0 and len(breaks) >= 12
    nodes = set(march.t.tolist())
    assert all(float(b) in nodes for b in breaks)
    assert march.t[-1] == settings.stop
    assert np.max(march.h) <= settings.max_step * (1 + 1e-12)
    doubled = (len(solves) - march.tries) // 2  # a doubled try is two solves more
    assert doubled >= len(breaks) + 1  # the start and every corner
    assert doubled <= 3 * (len(breaks) + 1)  # (and a rejected one now and then)
    assert len(march.h) <= march.tries + doubled
    assert info.factorizations <= 4 + (len(info.levels) + 1) + 2 * info.landings


@pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")
def test_a_ladder_by_its_truncation_error_agrees_with_a_fine_ngspice_run():
    """A 6-stage ladder on the sparse path at its own settings (reltol 1e-3), judged by
    the truncation error, against ngspice at reltol 1e-7, TMAX = TSTEP/50 on the TSTEP
    grid: within 1e-3 of each probe's peak, at one solve a step but for the first try."""
    text = ladder(6, steps=300)
    result = spice.run(text, step_error="truncation")
    assert result.trajectory.solver == sparse.DESCRIBE
    probes = ("v(n1)", "v(n6)", "i(L1)")
    fine = ".options reltol=1e-7 abstol=1e-15 vntol=1e-12 chgtol=1e-18 trtol=1"
    t_ref, ref = ng.ngspice(text, probes, tmax=result.settings.step / 50, options=fine)
    keep = result.time >= t_ref[0]
    for probe in probes:
        want = np.interp(result.time[keep], t_ref, ref[probe])
        error = np.max(np.abs(result[probe][keep] - want)) / np.max(np.abs(ref[probe]))
        assert error <= 1e-3, (probe, error)


def test_an_unknown_error_control_is_refused_with_the_choices():
    with pytest.raises(ModelError, match=r"step_error='richardson'.*'doubling', 'truncation'"):
        spice.run(PULSE_DECK, step_error="richardson")
    with pytest.raises(ModelError, match=r"step_error='truncation'.*fixed step"):
        spice.run(PULSE_DECK, dt=5e-9, step_error="truncation")
