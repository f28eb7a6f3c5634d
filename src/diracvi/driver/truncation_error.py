r"""The local truncation error of one midpoint step, from the step and the recorded past.

For ``ẋ = A x`` the (+) midpoint step of size ``h`` is the trapezoidal rule, whose
amplification ``(1 + z/2)/(1 − z/2) = e^z + z³/12 + O(z⁴)`` (``z = hA``) puts the local
error of a step at

    x_{k+1} − x(t_{k+1}) = (h³/12) x''' + O(h⁴).

The third derivative is read from the step just taken and the last three nodes of the
run: the third divided difference over ``t_{k−2}, t_{k−1}, t_k, t_{k+1}`` is
``x'''/6 + O(h)``, so

    LTE_k ≈ (h³/12) · 6 x[t_{k−2}, t_{k−1}, t_k, t_{k+1}] = (h³/2) x[t_{k−2}, …, t_{k+1}]

(:func:`local_error`) — one solve per step, where step doubling takes three per two
recorded steps. It is SPICE's estimate for the trapezoidal rule (ngspice's ``CKTterr``:
divided differences of the charges over the past points, times the rule's error
constant); no extrapolated value is ever recorded, only the plain Dirac steps. For a
driven circuit the midpoint rule evaluates the source at the step's centre, which adds
``−(h³/8)·b''`` to the error of the driven rows (``b`` the source term): the estimate
reads the response's curvature, not that one, and the agreement with ngspice is measured
(``docs/performance.md``), not assumed.

**Judged as a try of step doubling.** :func:`estimate` judges a step of ``h`` by the
tests of :func:`diracvi.driver.step_error.estimate` applied to a try of ``H = 2h`` that
records two such steps: the positions' error over the try ``2·LTE`` (``= h³ |x[…]|``),
the mean velocity's ``2·LTE/H``, and the step-centred multipliers' (node potentials)
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


def local_error(x_new, x, history: History, h: float):
    """``(h³/2) x[t_{k−2}, t_{k−1}, t_k, t_{k+1}]``, signed: the local error of the step
    ``x → x_new`` of size ``h`` (module doc), from ``history``'s velocity and second
    difference of the same signal."""
    v = (x_new - x) / h
    d = (v - history.v) / (history.h1 + h)
    return 0.5 * h**3 * (d - history.d) / (h + history.h1 + history.h2)


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
    try_ = 2.0 * h  # the try of step doubling whose fine steps these are
    v = (q_new - q) / h
    d = (v - history.v) / (h1 + h)
    # the positions' error over the try: 2·(h³/2)·x[…] (module doc)
    e = np.abs(d - history.d)
    e *= h**3 / (h + h1 + h2)
    q_peak = np.maximum(peaks[0], np.abs(q_new))
    v_peak = np.maximum(peaks[1], np.abs(v))
    e_q = e / (share * rtol * q_peak + atol_q)
    e_v = e / try_ / (share * rtol * v_peak + atol_v)
    rate = min(1.0, try_ / hmax)  # a rate's mean over TMAX (step_error.estimate)
    c = 2.0 * mu - history.c
    phi = -c / h
    g = (phi - history.phi) / (0.5 * (h1 + h))
    # (h²/12)|φ''|, φ'' = 2 φ[three centres]; the centres span h/2 + h1 + h2/2
    e_m = np.abs(g - history.g)
    e_m *= h**2 / (3.0 * (h + 2.0 * h1 + h2))
    m_peak = np.maximum(peaks[2], np.abs(phi))
    e_m /= share * rtol * m_peak + atol_m
    err = max(
        float(np.max(e_q, initial=0.0)),
        float(np.max(e_v, initial=0.0)) * rate,
        float(np.max(e_m, initial=0.0)) * rate,
    )
    return Estimate(err, q_peak, v_peak, m_peak, History(h, h1, v, d, phi, g, c))


__all__ = ["Estimate", "History", "estimate", "local_error", "start"]
