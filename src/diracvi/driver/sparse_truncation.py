r"""One solve per step: the sparse path's steps judged by their local truncation error.

:func:`march` is the loop of :func:`~diracvi.driver.adaptive_sparse.adaptive_sparse`
with ``error="truncation"``. Each try is one (+) midpoint step of ``h`` on the sparse
map of that size; its local error is estimated from the step and the last three nodes
(:mod:`.truncation_error`: ``q[t_{k−2}, …, t_{k+1}]`` times the rule's error constant,
the node potentials' ``φ''`` from the last three step centres), judged by the tests, share
:data:`~.step_error.SAFETY` and tolerances of step doubling, applied as to a doubled try
whose two fine steps are this one and its like. ``e ≤ 1`` records the step; either way
the next ``h`` is ``h·clip(0.9 e^{−1/3}, 0.2, 2)`` (:func:`~.step_error.growth`), at
most ``hmax``, rounded down to the grid ``hmax·2^{−k}`` (the grid of step doubling's
fine steps: both controls share the maps of :class:`~.adaptive_sparse._Maps`).

**Restarts.** A divided difference across a source's corner measures the corner, not
the error: the run's start and every breakpoint begin with one doubled try
(:meth:`~.adaptive_sparse._Tries.doubled`: three solves, two recorded steps — the
three nodes the estimate needs, all in the new interval), then single steps follow.
Breakpoints are landed exactly as by step doubling: a step that would pass one is
shortened to end on it, and the two steps before it share the remainder when it is
under twice the step (no sliver).

**A change of size.** The global error of a midpoint run is ``h²`` times a smooth
function: where ``h`` changes, its slope changes, and the next divided difference reads
that kink as well as the step's own error — measured on a 30-stage ladder, the first
step after a doubling of ``h`` estimated 0.75–0.82 of the tolerance where the steps
after it settled at 0.55. On the grid of sizes that was a ping-pong: 0.75 rounds the next
size down a level (``0.9·0.75^{−1/3} < 1``), whose error 0.07 sends it up again (187
changes of size in 5428 steps, each a new call of the offsets program, against step
doubling's 15). So the first step at a new size, when accepted (``e ≤ 1``: its error
within the tolerance, overestimated or not), keeps its size for the next step, which
judges it again (9 changes, 5383 steps).

Every recorded step is a plain Dirac step of its own size, so
:mod:`diracvi.spice._resample` reads the run as it reads step doubling's (step-centred
values through the steps' own sizes, whatever they are).
"""

from __future__ import annotations

import math

import numpy as np

from . import truncation_error as lte
from .adaptive import FAILED_SOLVE, OK, TOO_MANY, TOO_SMALL
from .step_error import growth_of


def march(tries, rec, z, t, t_stop, breaks, controls, max_tries, m):
    """Step from ``z`` at ``t`` to ``t_stop`` (module doc), recording into ``rec``;
    ``tries``: the run's :class:`~.adaptive_sparse._Tries`. Returns ``(tries,
    rejected, status)``."""
    # a failed step's NaN or overflow is judged by the finiteness tests, not warned
    # about (one context for the run: entered per step it was ~3% of a large circuit's)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return _march(tries, rec, z, t, t_stop, breaks, controls, max_tries, m)


def _march(tries, rec, z, t, t_stop, breaks, controls, max_tries, m):
    n, hmax, hmin = tries.n, tries.hmax, float(controls.hmin)
    h = min(float(controls.h_first), hmax)  # the next step's size
    ib = 0
    c_last = np.zeros(m)  # the given p0 carries no lag: c_{−1} = 0
    peaks = (np.abs(z[:n]), np.zeros(n), np.zeros(m))
    history = None  # None: the start of an interval (a doubled try)
    count = rejected = 0
    status = OK
    while t < t_stop:
        if count >= max_tries:
            status = TOO_MANY
            break
        target = min(breaks[ib], t_stop) if ib < len(breaks) else t_stop
        doubled = history is None
        # a doubled try of H records two steps of H/2: proposed at twice the step
        top = tries.top if doubled else hmax
        h_try, level, land, h0 = tries.plan(2.0 * h if doubled else h, target - t, top)
        if not (h_try > 0.0 and t + h_try > t):  # a try that cannot advance time
            status = TOO_SMALL  # (a breakpoint behind t, or h below t's resolution)
            break
        count += 1
        if doubled:
            ok, est, found, z1, y1, z2, y2 = tries.doubled(z, t, h_try, level, c_last, peaks)
        else:
            # hmax·2^{−k} is the maps' level k + 1 (their grid starts at 2·hmax)
            found, z2, y2 = tries.single(z, t, h_try, None if level is None else level + 1)
            ok = bool(np.isfinite(z2).all())
            est = lte.estimate(z[:n], z2[:n], y2[n:], h_try, history, peaks, tries.tolerances, hmax)
        err = float(est.err)
        ok = ok and math.isfinite(err)
        accept = ok and err <= 1.0
        h_next = h_try * growth_of(err) if ok else 0.25 * h_try
        if accept and h_try < h0:  # a landing step says little about the next one
            h_next = max(h_next, h0)
        if accept and not doubled and h_try != history.h1:
            # the first step at a new size: kept (module doc, "A change of size")
            h_next = max(h_next, h_try)
        stuck = not accept and h_next < hmin  # (the try's size, as step doubling's)
        if doubled:
            h_next *= 0.5  # the next step's size, not the next try's
        if accept:
            if doubled:
                half = 0.5 * h_try
                t_new = target if land else t + half + half
                rec.add(t + half, half, z1, y1[n:])
                rec.add(t_new, half, z2, y2[n:])
                tries.sample(found, z, y1, t, 2)
                history = lte.start(z[:n], z1[:n], z2[:n], y1[n:], y2[n:], c_last, half, half)
                c_last = est.c2
            else:
                t_new = target if land else t + h_try
                rec.add(t_new, h_try, z2, y2[n:])
                tries.sample(found, z, y2, t, 1)
                history = est.history
                c_last = history.c
            t, z = t_new, z2
            peaks = (est.q_peak, est.v_peak, est.m_peak)
            if land and ib < len(breaks) and target == breaks[ib]:
                ib += 1
                history = None  # a corner: the divided differences start again
        else:
            rejected += 1
        h = min(h_next, hmax)
        if stuck:
            status = TOO_SMALL if ok else FAILED_SOLVE
            break
    return count, rejected, status


__all__ = ["march"]
