"""A motor-driven R–L loop's per-step power balance and the round-off it closes to
(tests/test_robot_arm.py, tests/test_spatial_motor.py)."""

from __future__ import annotations

import numpy as np

EPS = np.finfo(float).eps


def loop_balance(charge, volts, shaft, h, inductance, resistance, constant):
    r"""``(gap, bound, port, work)`` per pair of steps k−1, k of a loop
    ``L di/dt = V − R i − K θ̇_m``: ``gap = Δ(½ L i²) − (h (V̄ ī − R ī²) − K ī Δθ̄_m)``
    (``ī``, ``V̄``, ``Δθ̄_m`` the two steps' means, ``i = Δq/h`` the step currents),
    which the midpoint rule makes zero in exact arithmetic, and ``bound`` its round-off.
    The currents carry the charges': each solved ``q`` is within Newton's stop (4 ulps
    of its update) and its own rounding of the exact step's, so
    ``|δi| ≤ 2·5ε max|q| / h`` (charges of coulombs differenced over ms steps: the bound
    grows as ``h`` shrinks); the gap moves by ``∂gap/∂i`` times that — ``L|i|`` from
    each end's magnetic term, ``h|V̄|/2``, ``h R |ī|`` and ``K|Δθ̄|/2`` from each
    current's share of the means — by ``K|ī|`` times the shaft angles' differencing
    (``2ε max|θ|``), and by the arithmetic of the terms themselves (``4ε`` of their
    sum). ``port = K ī Δθ̄_m`` and ``work = h (V̄ ī − R ī²)`` are the balance's terms."""
    charge, shaft = np.asarray(charge), np.asarray(shaft)
    i = np.diff(charge) / h
    turn = np.diff(shaft)
    i_bar, v_bar = (i[:-1] + i[1:]) / 2, (volts[:-1] + volts[1:]) / 2
    turn_bar = (turn[:-1] + turn[1:]) / 2
    port = constant * i_bar * turn_bar
    magnetic = np.diff(0.5 * inductance * i**2)
    work = h * (v_bar * i_bar - resistance * i_bar**2)
    gap = magnetic - (work - port)
    d_i = 2 * 5 * EPS * np.max(np.abs(charge)) / h
    slope = (
        inductance * (np.abs(i[:-1]) + np.abs(i[1:]))
        + h * np.abs(v_bar)
        + 2 * h * resistance * np.abs(i_bar)
        + constant * np.abs(turn_bar)
    )
    terms = np.abs(magnetic) + np.abs(h * v_bar * i_bar) + h * resistance * i_bar**2 + np.abs(port)
    bound = (
        slope * d_i + constant * np.abs(i_bar) * 2 * EPS * np.max(np.abs(shaft)) + 4 * EPS * terms
    )
    return gap, bound, port, work
