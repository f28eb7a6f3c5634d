"""A variable-step run's budget of tries judged by its pace (``diracvi.driver.budget``).

The rule, checked on runs described by their checks ``(t, tries)`` (one per return of the
compiled loop to the host): past ``base`` tries a run goes on while its pace over the last
``WINDOW · base`` tries projects its end within ``LIMIT · base`` tries, and stops at
``LIMIT · base`` whatever its pace; a plain count stops at the count.
"""

from __future__ import annotations

import math

import pytest

from diracvi.driver.budget import LIMIT, WINDOW, TriesBudget


def _stop(budget, t0, t_stop, checks):
    """The first check ``(t, tries)`` at which ``budget`` stops the run, or ``None`` (a
    run that reached ``t_stop`` is not asked, as in ``driver/adaptive.py``'s loop)."""
    made = TriesBudget.of(budget, t0)
    for t, tries in checks:
        if t < t_stop and made.spent(t, tries, t_stop):
            return t, tries
    return None


def _steady(total, t0=0.0, t_stop=1.0, chunk=300):
    """A run that advances at one pace and reaches ``t_stop`` after ``total`` tries."""
    n = [*range(chunk, total, chunk), total]
    return [(t0 + (t_stop - t0) * k / total, k) for k in n]


def test_a_plain_count_stops_at_the_count_whatever_the_pace():
    checks = _steady(15_000)
    assert _stop(10_000, 0.0, 1.0, checks) == pytest.approx((10_200 / 15_000, 10_200))
    assert _stop(15_000, 0.0, 1.0, checks) is None


def test_a_run_at_a_steady_pace_goes_on_to_its_end_within_the_limit():
    # ng_switch_osc's shape: 15 436 ordinary tries to the end against a base of 10 510
    assert _stop(TriesBudget(10_510), 0.0, 80e-9, _steady(15_436, 0.0, 80e-9)) is None
    need = int(LIMIT * 10_000) - 1  # just inside the limit: the projection is exact
    assert _stop(TriesBudget(10_000), 0.0, 1.0, _steady(need)) is None


def test_a_run_whose_pace_projects_past_the_limit_stops_at_its_base():
    need = int(1.2 * LIMIT * 10_000)
    t, tries = _stop(TriesBudget(10_000), 0.0, 1.0, _steady(need))
    assert 10_000 <= tries < 10_300  # the first check past the base
    assert t == pytest.approx(tries / need)


def test_a_run_that_gets_stuck_stops_at_its_base_and_no_later():
    # fast to t = 0.5 (5 000 tries), then creeping at 1e-9 of the run a try (a step at a
    # floor: ng_memristor crept at 5e-15 s of 1e-8): judged on its recent pace, not its
    # mean one (which projects 2·tries to the end and would carry it to twice its base)
    fast = [(0.5 * k / 5_000, k) for k in range(300, 5_001, 300)]
    creep = [(0.5 + 1e-9 * (k - 5_000), k) for k in range(5_300, 60_000, 300)]
    made = TriesBudget.of(TriesBudget(10_000), 0.0)
    stopped = next(((t, k) for t, k in fast + creep if made.spent(t, k, 1.0)), None)
    assert stopped is not None and 10_000 <= stopped[1] < 10_300
    assert made.projected == pytest.approx(stopped[1] + (1.0 - stopped[0]) / 1e-9, rel=1e-9)


def test_no_run_goes_past_the_limit_and_a_stalled_one_stops():
    # a pace that would finish, checked only past the limit: stops there
    made = TriesBudget.of(TriesBudget(1_000), 0.0)
    assert made.spent(0.99, int(LIMIT * 1_000), 1.0)
    # no time advanced over the window (from 700 tries on): stops at the base
    made = TriesBudget.of(TriesBudget(1_000), 0.0)
    assert not any(made.spent(0.5, k, 1.0) for k in (700, 800, 900))
    assert made.spent(0.5, 1_000, 1.0) and math.isinf(made.projected)


def test_the_pace_is_read_over_the_window_not_the_last_check():
    # a burst of slow tries in the last chunk (a switching event) inside a window of
    # steady pace: the window's pace goes on; the last check's pace alone would stop it
    base = 10_000
    steady = [(k / 20_000, k) for k in range(500, 10_001, 500)]  # 20 000 to the end
    t_last, n_last = steady[-1]
    burst = (t_last + 1e-6, n_last + 400)  # 400 tries for 1e-6: 5e5 more at that pace
    made = TriesBudget.of(TriesBudget(base), 0.0)
    assert not any(made.spent(t, k, 1.0) for t, k in [*steady[:-1], steady[-1], burst])
    window = WINDOW * base
    assert made.projected == pytest.approx(
        burst[1] + (1.0 - burst[0]) * window / (burst[0] - (burst[1] - window) / 20_000), 0.05
    )


def test_a_budget_is_a_count():
    with pytest.raises(ValueError, match="count >= 0"):
        TriesBudget(-1)
