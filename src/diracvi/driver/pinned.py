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
each step's end it sets ``y_{k+1}`` to the value there of the quadratic through the
step's ``ȳ`` and the two steps' before it, each at its step's centre
(:func:`centre_value`: the sensed ``g_k`` is the value at the step's centre, a source's
exactly), and each step starts from that node value less ``Y'' h²/8`` of the step's own
``h`` (:func:`start_value`), so that its ``ddt = 2(ȳ − y_start)/(hτ)`` is the derivative
at its centre, ``O(h²)``, exact for a quadratic ``g``. (Started from the node value
itself, as fitted before to the steps' means taken as cell averages, ``ddt`` was
``Y'(t + h/3)``, first order: a 1 kHz sine's ``ddt`` off by ``g''h/6``, and its
step-doubling difference, coarse against fine, ``O(H)``, which the step control, judging
node potentials per try, met with steps 250 times shorter than TMAX.) Nothing of ``y``
is carried but the three means, so there is no mode to drive: a round-off ``ε`` in them
stays an error of ``≈ 9ε/h`` in one step's ``ddt``. Across a source corner (a breakpoint,
a switching instant) the means before it do not describe ``g`` after it: the steps of the
first try after one keep the midpoint's own ``y_{k+1} = 2τ g_k − y_k`` (from a node value
pinned up to the corner from the left, exact for a piecewise linear ``g``).

Every step still solves its own equations; only the start of the next one is replaced.
``y`` stores no energy (the hold term and its derivatives vanish on its line) and has
no momentum, so KCL, the step's discrete power balance (the output's force is the same
resistive-like port, its power ``−f·i`` accounted as before) and a fixed-step run are
unchanged; the recorded ``y`` are the pinned node values.
"""

from __future__ import annotations

import jax.numpy as jnp


def centre_value(means, sizes):
    """The value at the right end of the last of three adjacent intervals (``sizes =
    (a, b, c)``) of the quadratic through ``means = (m_a, m_b, m_c)`` at the intervals'
    centres (Lagrange, extrapolated to that end)."""
    a, b, c = sizes
    x = (-(c + b + 0.5 * a), -(c + 0.5 * b), -0.5 * c)
    out = 0.0
    for j in range(3):
        w = 1.0
        for i in range(3):
            if i != j:
                w = w * (0.0 - x[i]) / (x[j] - x[i])
        out = out + means[j] * w
    return out


def start_value(node, means, sizes, h):
    """The value a pinned position starts a step of ``h`` from: ``node − Y'' h²/8``, with
    ``Y`` the quadratic through ``node`` at the start and the means ``(m_a, m_b)`` of the
    two steps before it (``sizes = (a, b)``) at their centres ``s₁ = −b − a/2``,
    ``s₂ = −b/2``: with ``d_i = m_i − node``,

        Y'' = 2 (d₁/s₁ − d₂/s₂) / (s₁ − s₂).

    The step's line fixes its mean ``ȳ = τ g_k`` (``g_k`` the sensed value at the step's
    centre ``t + h/2``) and ``ddt = 2(ȳ − y_start)/(hτ)``: from ``Y(t)`` that is
    ``Y'(t) + Y'' h/4``, first order, and its step-doubling difference, coarse against
    fine, is ``O(H)``, not the ``O(H³)`` the step control is written for; from
    ``Y(t) − Y'' h²/8`` it is ``Y'(t + h/2) + O(h²)``, the centre's derivative, exact
    for a quadratic ``g``."""
    m_a, m_b = means
    a, b = sizes
    s1, s2 = -(b + 0.5 * a), -0.5 * b
    curvature = 2.0 * ((m_a - node) / s1 - (m_b - node) / s2) / (s1 - s2)
    return node - curvature * h * h / 8.0


def repin(mask, start, end, history, sizes):
    """``(end with its pinned coordinates re-pinned, this step's means)``: ``start``,
    ``end`` are the step's ends as solved, ``history = (m_a, m_b)`` the means of the two
    steps before it, ``sizes = (a, b, c)`` the three steps' sizes. ``mask``: which
    coordinates (booleans, or all False for none)."""
    mean = 0.5 * (start + end)
    pinned = centre_value((history[0], history[1], mean), sizes)
    return jnp.where(mask, pinned, end), mean


__all__ = ["centre_value", "repin", "start_value"]
