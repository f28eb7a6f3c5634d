r"""Positions whose line fixes only their step midpoint, re-pinned at the nodes.

A behavioural source's ``ddt(g)`` is the velocity of a pin-less position ``y = τ g``
held by the term ``−½ C (g − y/τ)²`` in ``L`` (:mod:`diracvi.components.behavioural`).
Under the midpoint rule its line reads

    ȳ_k = (y_k + y_{k+1})/2 = τ g_k,         ddt_k = (y_{k+1} − y_k)/(h_k τ),

with ``g_k`` the step's mean of ``g`` (the sensed voltages are the velocities ``Δw/h``).
The line fixes the midpoint only: ``y_{k+1} = 2τ g_k − y_k`` keeps any ±alternation
``δ(−1)^k`` of ``y`` for ever (an undamped −1 mode, the same in exact arithmetic), and
``ddt`` reads it as ``±2δ/(hτ)``. The sensed ``g_k`` alternates by its round-off (the
potentials' own −1 mode), which drives ``y``'s mode at its own frequency: a resonance,
whose amplitude grows by ``2τ|ε|`` per step. On ``ng_ddt_test1`` (a 2 V/s ramp) it grew
to ±3e-4 V/s in ``ddt`` by 2.7 s, the step control read the alternating output as an
error, cut the step, and ``2δ/h`` grew until the output was off by 3.8 of its peak.

So the variable-step driver does not carry ``y``'s node values from step to step: at
each step's end it sets ``y_{k+1}`` to the node value of the quadratic whose means over
the step and the two steps before it are those steps' ``ȳ`` (:func:`edge_value`, the
cell-average reconstruction: exact for a quadratic ``g``, so the next step's
``ddt = 2(g_{k+1} − y_{k+1}/τ)/h`` is second order). Nothing of ``y`` is carried but
the three means, so there is no mode to drive: a round-off ``ε`` in them stays an error
of ``≈ 9ε/h`` in one step's ``ddt``. Across a source corner (a breakpoint, a switching
instant) the means before it do not describe ``g`` after it: the steps of the first try
after one keep the midpoint's own ``y_{k+1} = 2τ g_k − y_k`` (from a node value pinned
up to the corner from the left, exact for a piecewise linear ``g``).

Every step still solves its own equations; only the start of the next one is replaced.
``y`` stores no energy (the hold term and its derivatives vanish on its line) and has
no momentum, so KCL, the step's discrete power balance (the output's force is the same
resistive-like port, its power ``−f·i`` accounted as before) and a fixed-step run are
unchanged; the recorded ``y`` are the pinned node values.
"""

from __future__ import annotations

import jax.numpy as jnp


def edge_value(means, sizes):
    """The value at the right end of the last of three adjacent intervals of the
    quadratic whose means over them are ``means = (m_a, m_b, m_c)`` (arrays) for
    ``sizes = (a, b, c)`` (scalars): the derivative at that end of the cubic through
    the primitive's values at the four ends (Lagrange, the end at 0)."""
    m_a, m_b, m_c = means
    a, b, c = sizes
    x = (-(a + b + c), -(b + c), -c)  # the three other ends; the last one is 0
    # the primitive P with P(0) = 0, at the other ends
    pv = (-(c * m_c + b * m_b + a * m_a), -(c * m_c + b * m_b), -c * m_c)
    out = 0.0
    for j in range(3):
        others = [x[i] for i in range(3) if i != j]
        num = (0.0 - others[0]) * (0.0 - others[1])
        den = (x[j] - others[0]) * (x[j] - others[1]) * (x[j] - 0.0)
        out = out + pv[j] * num / den
    return out


def repin(mask, start, end, history, sizes):
    """``(end with its pinned coordinates re-pinned, this step's means)``: ``start``,
    ``end`` are the step's ends as solved, ``history = (m_a, m_b)`` the means of the two
    steps before it, ``sizes = (a, b, c)`` the three steps' sizes. ``mask``: which
    coordinates (booleans, or all False for none)."""
    mean = 0.5 * (start + end)
    pinned = edge_value((history[0], history[1], mean), sizes)
    return jnp.where(mask, pinned, end), mean


__all__ = ["edge_value", "repin"]
