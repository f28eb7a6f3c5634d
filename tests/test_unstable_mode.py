"""A node potential growing as an unstable mode, judged against its own growing part.

An unstable mode ``b + a e^{λt}`` damps nothing: the tries' local errors, relative to
``a e^{λt}``, add up until the mode is over (a regenerative switch's firing instant).
The node potentials' step-doubling estimate reads ``(λH)²/48`` of the mode a try, which
is the mode's own error per e-folding time, so judged against ``|a e^{λt}|`` it holds the
mode's error to the tolerance per e-folding; judged against the potential's running peak
it is as many times looser as the offset ``b`` is larger than the mode
(``diracvi.driver.step_error.mode_amplitude``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from diracvi import spice
from diracvi.driver.step_error import SAFETY, mode_amplitude


def _centres(h_last, h_try):
    """The four step centres around a try at t = 0: the last try's two, this one's."""
    return (-1.5 * h_last, -0.5 * h_last, 0.25 * h_try, 0.75 * h_try)


def test_the_amplitude_of_a_growing_mode_is_its_growing_part_whatever_its_offset():
    # b + a e^{λt} on evenly spaced centres (h_last = H/2): λ from the slopes' ratio is
    # exact, and |s₃|/λ is the growing part's mean over the last spacing d,
    # a e^{λ m₃} · sinh(λd/2)/(λd/2)
    lam, a, h = 3.4e6, 2e-3, 40e-9
    xs = _centres(0.5 * h, h)
    d = xs[3] - xs[2]
    m3 = 0.5 * (xs[2] + xs[3])
    expected = a * math.exp(lam * m3) * math.sinh(0.5 * lam * d) / (0.5 * lam * d)
    for b in (0.0, 0.64, -50.0):
        ys = tuple(np.array([b + a * math.exp(lam * x)]) for x in xs)
        got = mode_amplitude(np, xs, ys)[0][0]
        assert got == pytest.approx(expected, rel=1e-9)
    # a falling mode of one sign too (a < 0): its magnitude
    ys = tuple(np.array([0.7 - a * math.exp(lam * x)]) for x in xs)
    assert mode_amplitude(np, xs, ys)[0][0] == pytest.approx(expected, rel=1e-9)


@pytest.mark.parametrize(
    "f",
    [
        lambda t: 1.0 + np.exp(-3e6 * t),  # a decaying mode: the slopes shrink
        lambda t: 0.5 + 1e5 * t,  # a ramp: the slopes equal
        lambda t: np.cos(2e7 * t),  # a turn (a peak): the slopes change sign
        lambda t: 1e-3 * (-1.0) ** np.round(t / 1e-8 + 1.5),  # an alternation
    ],
)
def test_what_does_not_grow_is_judged_against_its_running_peak(f):
    xs = _centres(20e-9, 40e-9)
    ys = tuple(np.array([f(x)]) for x in xs)
    assert np.isinf(mode_amplitude(np, xs, ys)[0][0])


NEGATIVE_RC = """negative RC on an offset: v(1) = {b} + 1 mV e^(t/RC), RC = 1 ms
V0 2 0 DC {b}
C1 1 0 1u IC={ic!r}
R1 1 2 -1k
.tran 1m 10m UIC
.end
"""


def _mode_error(offset):
    """The relative error of the mode ``v(1) − b`` at 10 ms (10 e-foldings), and the
    steps: the exact ``1 mV e^{t/RC}`` against the run's TSTEP points."""
    result = spice.run(NEGATIVE_RC.format(b=offset, ic=offset + 1e-3))
    t, v = result.time, result["v(1)"] - offset
    assert t[-1] == pytest.approx(10e-3, rel=1e-12)
    exact = 1e-3 * np.exp(t[-1] / 1e-3)
    return abs(v[-1] - exact) / exact, len(result.trajectory.h)


def test_an_unstable_mode_is_held_to_the_tolerance_per_e_folding_whatever_its_offset():
    # a capacitor and a negative resistance, the mode riding on 0 V and on 1000 V: the
    # step-doubling estimate of the potential holds the mode's error to SAFETY·reltol
    # (the deck's 1e-3) per e-folding only judged against the mode itself. Measured
    # (session 39): 4.1e-4 of the mode after 10 e-foldings on 0 V (506 steps), 4.3e-4 on
    # 1000 V (506); judged against the running peak as every other potential, 8.0e-4 on
    # 1000 V (342 steps: the tolerance 1000 V times looser early on; what still holds the
    # steps there is not this judgement). The bound: 10 e-foldings of SAFETY·reltol,
    # twice (an accepted try's estimate reaches its tolerance, and the TSTEP point is read
    # from the output's interpolant between centres: 1.4 times measured)
    bare, steps_bare = _mode_error(0.0)
    raised, steps_raised = _mode_error(1000.0)
    bound = 2.0 * 10 * SAFETY * 1e-3
    assert bare <= bound
    assert raised <= bound
    # the offset changes neither the error nor the steps much (without the rule: 1.94
    # times the error, 0.68 times the steps)
    assert raised <= 1.25 * bare
    assert steps_raised >= 0.9 * steps_bare
