r"""The local truncation error of one midpoint step, from the step and the recorded past.

For ``ẋ = A x`` the (+) midpoint step of size ``h`` is the trapezoidal rule, whose
amplification ``(1 + z/2)/(1 − z/2) = e^z + z³/12 + O(z⁴)`` (``z = hA``) puts the local
error of a step at

    x_{k+1} − x(t_{k+1}) = (h³/12) x''' + O(h⁴).

The third derivative is read from the step just taken and the last three nodes of the
run. The third divided difference over ``t_{k−2}, t_{k−1}, t_k, t_{k+1}`` through the
*computed* ``x_{k+1}`` carries the step's own error: with ``Π = h (h + h₁)(h + h₁ + h₂)``
(``h₁``, ``h₂`` the last two steps), ``Π·x[…]`` is the computed value minus the
quadratic through the last three nodes, whose error is ``Π x'''/6``, so
``Π·x[…] = Π x'''/6 + LTE`` (a Milne device: predictor against corrector) and

    LTE_k ≈ x[t_{k−2}, …, t_{k+1}] · h³Π / (2Π + h³)      (= (6/13) h³ x[…] at equal steps)

(:func:`local_error`) — one solve per step, where step doubling takes three per two
recorded steps. It is SPICE's estimate for the trapezoidal rule (ngspice's ``CKTterr``:
divided differences of the charges over the past points, times the rule's error
constant); no extrapolated value is ever recorded, only the plain Dirac steps. For a
driven circuit the midpoint rule evaluates the source at the step's centre, where the
trapezoidal rule averages its ends: the two local errors differ by a term in the
source's second derivative (``(h³/8) b''``, ``b`` the source term), which the estimate
does not read; the agreement with ngspice is measured (``docs/performance.md``), not
assumed.

**Judged as a try of step doubling.** :func:`estimate` judges a step of ``h`` by the
tests of :func:`diracvi.driver.step_error.estimate` applied to a try of ``H = 2h`` that
records two such steps: the positions' error over the try ``2·LTE``, the mean
velocity's ``2·LTE/H``, and the step-centred multipliers' (node potentials)
``(h²/12)|φ''|`` — what step doubling's coarse-against-fine centre measures of a signal
whose error at the centre of a step is the node average's ``(h²/8) φ''``
(:mod:`diracvi.spice._resample`). So the sizes it chooses are the fine steps step
doubling would choose, at the same :data:`~.step_error.SAFETY` and tolerances: the
decks' measured agreement carries over; the saving is in solves.

The divided differences are formed from increments (``v = Δq/h``, then their
differences), never from the absolute values, so the round-off of the estimate is that
of the velocities, not ``ε|q|/h³``. They are meaningless across a source's corner: the
caller starts every interval between breakpoints afresh (:class:`History` is built from
three nodes of one interval).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class History(NamedTuple):
    """What an estimate needs of the run before the step: the last two step sizes
    ``h1`` (the last), ``h2``; the last step's velocity ``v = (q_k − q_{k−1})/h1``; the
    positions' second divided difference ``d = q[t_{k−2}, t_{k−1}, t_k]``; the last
    step's centred multiplier ``phi`` (``φ = −c/h``), its first divided difference
    ``g`` over the last two centres, and the last impulse ``c``."""

    h1: float
    h2: float
    v: np.ndarray
    d: np.ndarray
    phi: np.ndarray
    g: np.ndarray
    c: np.ndarray


def start(q0, q1, q2, mu1, mu2, c_prev, h1: float, h2: float) -> History:
    """The history after two steps (``q0 → q1`` of ``h2``, ``q1 → q2`` of ``h1``) with
    multipliers ``mu1``, ``mu2``; ``c_prev`` the impulse before the first (see
    :mod:`diracvi.spice._resample`: ``c_k = 2μ_k − c_{k−1}``)."""
    va, vb = (q1 - q0) / h2, (q2 - q1) / h1
    ca = 2.0 * mu1 - c_prev
    cb = 2.0 * mu2 - ca
    pa, pb = -ca / h2, -cb / h1
    return History(h1, h2, vb, (vb - va) / (h1 + h2), pb, (pb - pa) / (0.5 * (h1 + h2)), cb)


def _milne(h: float, h1: float, h2: float) -> float:
    """``h³Π/(2Π + h³)``, ``Π = h (h + h₁)(h + h₁ + h₂)``: the local error of a step per
    unit of the third divided difference through it (module doc)."""
    big = h * (h + h1) * (h + h1 + h2)
    return h**3 * big / (2.0 * big + h**3)


def local_error(x_new, x, history: History, h: float):
    """``x[t_{k−2}, t_{k−1}, t_k, t_{k+1}]·h³Π/(2Π + h³)``, signed: the local error of the step
    ``x → x_new`` of size ``h`` (module doc), from ``history``'s velocity and second
    difference of the same signal."""
    v = (x_new - x) / h
    d = (v - history.v) / (history.h1 + h)
    return _milne(h, history.h1, history.h2) * (d - history.d) / (h + history.h1 + history.h2)


class Estimate(NamedTuple):
    """One step's judgement (:func:`estimate`): the worst scaled error, the running peaks
    with this step's values, and the history the next step starts from."""

    err: float
    q_peak: np.ndarray
    v_peak: np.ndarray
    m_peak: np.ndarray
    history: History


def estimate(q, q_new, mu, h, history: History, peaks, tolerances, hmax) -> Estimate:
    """The scaled error of the step ``q → q_new`` of size ``h`` with multipliers ``mu``
    (module doc), at ``peaks = (Q, V, Φ)`` and ``tolerances = (share, rtol, atol_q,
    atol_v, atol_m)`` as :func:`diracvi.driver.step_error.estimate` takes them; a rate
    is judged at the resolution ``hmax`` as there."""
    share, rtol, atol_q, atol_v, atol_m = tolerances
    h1, h2 = history.h1, history.h2
    sr, try_ = share * rtol, 2.0 * h  # (the try of step doubling whose fine steps these are)
    rate = min(1.0, try_ / hmax)  # a rate's mean over TMAX (step_error.estimate)
    # (in place where it can be: a step of a large circuit is a few solves' worth of
    # these vector operations, so each one counts)
    v = q_new - q
    v *= 1.0 / h
    d = v - history.v
    d *= 1.0 / (h1 + h)
    e = d - history.d
    np.abs(e, out=e)  # the positions' error over the try: 2·_milne·e/(h + h1 + h2)
    q_peak = np.abs(q_new)
    np.maximum(q_peak, peaks[0], out=q_peak)
    v_peak = np.abs(v)
    np.maximum(v_peak, peaks[1], out=v_peak)
    # e_q = E/(s·rtol·Q + atol_q) and e_v = E·rate/(H (s·rtol·V + atol_v)): one division
    # by the smaller denominator
    den = q_peak * sr
    den += atol_q
    den_v = v_peak * sr
    den_v += atol_v
    den_v *= try_ / rate
    np.minimum(den, den_v, out=den)
    np.divide(e, den, out=e)
    err = float(e.max(initial=0.0)) * 2.0 * _milne(h, h1, h2) / (h + h1 + h2)
    # node potentials: (h²/12)|φ''|, φ'' = 2 φ[three centres] (spanning h/2 + h1 + h2/2)
    c = mu * 2.0
    c -= history.c
    phi = c * (-1.0 / h)
    g = phi - history.phi
    g *= 2.0 / (h1 + h)
    e_m = g - history.g
    np.abs(e_m, out=e_m)
    m_peak = np.abs(phi)
    np.maximum(m_peak, peaks[2], out=m_peak)
    den_m = m_peak * sr
    den_m += atol_m
    np.divide(e_m, den_m, out=e_m)
    err_m = float(e_m.max(initial=0.0)) * h**2 / (3.0 * (h + 2.0 * h1 + h2)) * rate
    err = max(err, err_m) if err == err and err_m == err_m else math.nan  # (NaN: failed)
    return Estimate(err, q_peak, v_peak, m_peak, History(h, h1, v, d, phi, g, c))


__all__ = ["Estimate", "History", "estimate", "local_error", "start"]
