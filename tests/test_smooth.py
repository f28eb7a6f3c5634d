"""The sampler's alternation-free weights (``spice/_smooth.py``): exact for quadratics,
blind to the midpoint rule's period-2 alternation ``A(−1)^k/h_k``, third order on a
smooth signal over nonuniform steps, and second order on a stiff RC whose undamped mode
a kink of its source excites between breakpoints (the raw step-centred current keeps an
O(1) alternation)."""

from __future__ import annotations

import itertools

import numpy as np

from diracvi.spice._resample import Sampler
from diracvi.spice._smooth import alternation_free


def _graded(n: int, bounds) -> np.ndarray:
    """Nodes with ``n`` steps per interval, graded smoothly (ratios up to ~1.9, the same
    shape at every ``n``: halving the steps keeps their ratios)."""
    x = np.linspace(0.0, 1.0, n + 1)
    x = x + 0.3 * np.sin(2 * np.pi * x) / (2 * np.pi)
    pieces = [a + (b - a) * x[1:] for a, b in itertools.pairwise(bounds)]
    return np.concatenate([[bounds[0]], *pieces])


def test_equal_steps_weights_are_the_documented_ones():
    x = np.tile([-1.5, -0.5, 0.5, 1.5], (3, 1))
    w = alternation_free(x, np.ones_like(x), np.array([-0.5, 0.0, 2.0]))
    np.testing.assert_allclose(
        16 * w, [[2, 10, 6, -2], [-1, 9, 9, -1], [7, -15, 1, 23]], rtol=0, atol=1e-12
    )


def test_quadratics_are_exact_and_the_alternation_is_taken_out():
    """On random steps (ratios up to 30) with a corner: a quadratic on each interval plus
    ``A(−1)^k/h_k`` (a different ``A`` on each side) is read as the quadratic alone,
    at the nodes, between them and at the ends half a step beyond the last centres."""
    rng = np.random.default_rng(7)
    bounds = np.array([0.0, 0.4, 1.0])
    inner = [np.sort(rng.uniform(a, b, 30)) for a, b in itertools.pairwise(bounds)]
    t = np.unique(np.concatenate([bounds, *inner]))
    h = np.diff(t)
    assert np.max(h[1:] / h[:-1]) > 5.0 and np.min(h[1:] / h[:-1]) < 0.2
    centres = t[:-1] + h / 2
    sampler = Sampler(t, h, bounds)
    k = np.arange(len(h))

    def f(x):
        return np.where(x <= 0.4, 3 * x**2 - x + 0.2, -2 * (x - 0.4) ** 2 + 0.7 * x)

    amplitude = np.where(centres <= 0.4, 2e-3, -5e-3)
    values = f(centres) + amplitude * (-1.0) ** k / h
    query = np.concatenate([t, rng.uniform(0, 1, 200)])
    assert np.max(np.abs(amplitude / h)) > 0.1  # an alternation of O(1) at the shortest
    np.testing.assert_allclose(sampler(values, query), f(query), rtol=0, atol=1e-11)
    # the quadratic through three centres (what was read before) passes it on
    index = np.clip(np.searchsorted(centres, 0.7) + np.array([-1, 0, 1]), 0, None)
    x = centres[index]
    lagrange = [
        np.prod([(0.7 - x[i]) / (x[j] - x[i]) for i in range(3) if i != j]) for j in range(3)
    ]
    assert abs(np.dot(lagrange, values[index]) - f(0.7)) > 1e-3


def test_a_smooth_signal_on_graded_steps_is_third_order():
    """``w·f − f(τ) = −λ f'''/6 + O(h⁴)`` (module doc): the fitted order of the worst
    error over nodes, centres and other times, ends included, is 3 on graded steps."""
    bounds = np.array([0.0, 0.7, 2.0])

    def f(x):
        return np.sin(3 * x) + np.exp(x)

    errors = []
    for n in (20, 40, 80, 160):
        t = _graded(n, bounds)
        h = np.diff(t)
        centres = t[:-1] + h / 2
        query = np.concatenate([t, centres, np.linspace(0, 2, 301)])
        errors.append(np.max(np.abs(Sampler(t, h, bounds)(f(centres), query) - f(query))))
    order = np.polyfit(np.log([20, 40, 80, 160]), np.log(errors), 1)[0]
    assert -order > 2.8, (errors, order)


TAU, KINK, STOP = 1e-9, 0.5 + 1e-3 * np.pi, 2.0


def _stiff_rc(t: np.ndarray):
    """The midpoint rule on ``τ q' = u(t) − q`` (an RC of ``τ = 1 ns`` driven through its
    resistor by ``u``, ``q`` the capacitor's charge at ``C = 1``), ``u = sin t`` plus a
    slope 0.5 from a kink at ``KINK`` that is no node of any grid below (a device law's
    corner between breakpoints). ``h ≫ τ``: the rule's stiff mode ``R → −1`` is excited
    at the kink and carried undamped. Returns the steps and the step currents
    ``i_{k+½} = (q_{k+1} − q_k)/h_k``."""

    def u(x):
        return np.sin(x) + 0.5 * np.maximum(x - KINK, 0.0)

    h = np.diff(t)
    q = np.zeros(len(t))  # q(0) = u(0): a consistent start
    for k in range(len(h)):  # (q_{k+1} − q_k)/h = (u(t_{k+½}) − (q_k + q_{k+1})/2)/τ
        q[k + 1] = (u(t[k] + h[k] / 2) / TAU + q[k] * (1 / h[k] - 0.5 / TAU)) / (
            1 / h[k] + 0.5 / TAU
        )
    return h, np.diff(q) / h


def _stiff_rc_current(x):
    """The exact current ``q' = u' − τu'' + …`` away from the kink's ``τ``-wide layer."""
    return np.cos(x) + 0.5 * (x > KINK) + TAU * np.sin(x)


def test_a_stiff_mode_excited_at_a_kink_is_read_to_second_order():
    """Raw step currents after the kink alternate by O(1) at every step size; read
    through the sampler (times 0.1 after the kink on, the run's end included) they are
    second order, on equal and on graded steps."""
    for grade in (False, True):
        sizes, raw, read = (40, 80, 160, 320), [], []
        for n in sizes:
            t = _graded(n, [0.0, STOP]) if grade else np.linspace(0.0, STOP, n + 1)
            h, current = _stiff_rc(t)
            centres = t[:-1] + h / 2
            after = centres > KINK + 0.1
            raw.append(np.max(np.abs(current[after] - _stiff_rc_current(centres[after]))))
            query = np.concatenate([centres[after], np.linspace(KINK + 0.1, STOP, 301)])
            sampled = Sampler(t, h, np.array([0.0, STOP]))(current, query)
            read.append(np.max(np.abs(sampled - _stiff_rc_current(query))))
        assert min(raw) > 0.05, raw  # the alternation: no smaller on finer steps
        order = np.polyfit(np.log(sizes), np.log(read), 1)[0]
        assert -order > 1.9, (grade, read, order)
        assert np.all(np.array(read) < 0.01 * np.array(raw)), (read, raw)
