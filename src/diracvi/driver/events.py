r"""Discrete states and their events: the switches' relays, carried through a run.

A part may hold a discrete state — a :class:`~diracvi.components.switch.Relay`, a leaf
``closed`` of its force — that is constant within a step and changes between steps by
a law ``σ⁺ = next(σ, u)`` of a control value ``u`` (a step-centred velocity of one of
the part's coordinates, or a step's impulse on its momentum line divided by the step:
:mod:`diracvi.components.switch` says why a voltage control is read that way). The
driver carries the vector ``σ`` of all of them, builds each step with its current
values (:func:`with_modes`: the same system with those leaves replaced, so one compiled
program serves every state) and decides ``σ`` anew after each step.

**Events are located.** A step over which a relay's law would flip ``σ`` does not simply
flip it at its end (the flip would be late by up to a step). The adaptive driver's try
of size ``H`` has three steps (the whole one and its two halves, for the step
doubling); the control's step-centred values on them, ``u_c``, ``u₁``, ``u₂``, are the
means of its values at their ends, and the parabola ``u(τ)`` with those three means
gives the control over the try to third order (:func:`decide`) and the crossing time
``τ*`` of the level crossed (``VT + VH`` going up, ``VT − VH`` going down). A flip is
taken at a try's end only where the end value ``u(H)`` is within half the event
tolerance (:func:`tolerances`) of the level, on either side: past it (the law flips),
or short of it and heading for it, the parabola reaching it within one more try's
length (the flip is taken there, early by as much as a flip past the level is late;
a control that turns back short of the level, or creeps towards it, is not flipped on
the extrapolation). A try that ends past that window is retried with ``H = τ*``, aimed
at the crossing itself, but never below ``H/4``
(a sharp drop of the step size excites the midpoint rule's alternating mode — the lag
of the multipliers — which the step control then chases down to ``hmin``; the crossing
is approached over a few steps instead). Each retry aims at its parabola's crossing, so
a flip is placed within the tolerance of its instant in a few tries, and without a
systematic bias: the window ``|u(H) − level| ≤ tol/2`` is centred on the crossing.
(Before, a retry aimed half a tolerance *past* the crossing, the middle of a one-sided
window ``[level, level + tol]``, so every flip was late by about ``tol/(2|u̇|)``: 23 ns
at 0.8 V/ms on ``ng_switches``. The window keeps its width; a window ``±tol`` would
take fewer retries but accept a first aim's miss — the parabola of the long try
extrapolated to the retry's own discrete control, off by up to 0.85 tol on one side at
the relaxation oscillator's discharging flips — that a second aim, from the retry's
own parabola, removes.) (The line through
``u₁`` and ``u₂`` alone, used before, misses ``u(H)`` by ``H²u''/16``: 7.5e-5 V,
twice the tolerance, on a switched RC node; ``ng_switch_osc``'s 17 switch inverters
added that up to a period 0.75 % short of the exact one.) What remains of that ring's
period error (0.17 % short at its deck's settings) is mostly not the events': between
them a capacitor's node relaxing through a resistor is stepped by the midpoint rule,
i.e. the trapezoidal rule on a linear node, which decays by ``(1 − z/2)/(1 + z/2)`` per
step ``z = h/τ``, faster than ``e^{−z}`` (``ln`` of it is ``−z − z³/12 − …``): each node
reaches its level ``τ Σ (ln((1 + z/2)/(1 − z/2)) − z)`` early, about 0.1 ps per
switching at the steps taken there (``tests/test_switches.py`` checks both parts on a
7-stage ring of the same inverters). The rest, ~0.03 ps per switching early, is the end
value below: on a capacitor's node ``u₂ − u₁ + u_c`` is ``(u_f(H) + u_c(H))/2``, the
mean of the fine and the coarse steps' ends, off the recorded (fine) end by half the
coarse step's extra decay (``z³Δ/32``, several tolerances at tries of ``z`` ≈ 0.1).

**What an event does to the power balance.** Nothing discontinuous: every recorded step
is an ordinary discrete Dirac step with a fixed ``σ`` (a fixed resistance), for which the
discrete power balance holds to round-off; the state ``(q, p)`` is continuous across the
event (a resistive switch stores nothing), so the balance over a run is the sum of its
steps' balances, the steps on either side of each event included. Only the dissipation
law changes at the event, and where the event is placed (past its level or short of it,
within the window) does not enter.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..components.switch import Relay
from ..discretization.diagnostics import GROUPED_MIN_SUBSYSTEMS
from ..errors import ModelError
from .leaves import LeavesOf


def _is_relay(x) -> bool:
    return isinstance(x, Relay)


#: the relays of a model, in PyTree order (remembered per model object)
_nodes = LeavesOf(_is_relay, interactions=True)


def relays(system) -> tuple[tuple[int, Relay], ...]:
    """``(index of the control coordinate in system.coords, relay)`` for every relay, in
    the order :func:`with_modes` takes the states."""
    every = _nodes(system)
    if not every:
        return ()
    if getattr(system, "_packing", None) is not None:
        raise ModelError("a packed interconnection cannot carry switch states; pass it unpacked")
    found = []
    subsystems = getattr(system, "subsystems", None)
    for sub in subsystems if subsystems is not None else (system,):
        prefix = f"{sub.name}." if subsystems is not None else ""
        for relay in _nodes(sub):
            found.append((system.coords.index(prefix + relay.coordinate), relay))
    if len(found) != len(every):
        raise ModelError("switch states found outside the subsystems of the interconnection")
    return tuple(found)


def packed_unless_switched(system):
    """``system`` packed (an interconnection's alike parts' parameters stacked, each
    kind of part traced once: :meth:`~diracvi.model.interconnect.InterconnectedSystem._packed`),
    so that a program of its steps or of its operating point does not grow with the
    number of parts of one kind; a system with switches as it is (a packed system
    cannot carry their states: :func:`relays`), any other system as it is; and so is
    an interconnection of fewer than ``GROUPED_MIN_SUBSYSTEMS`` parts, as a fixed-step
    plan leaves it (a CMOS inverter's seven parts, packed, took 13 s more CPU on a cold
    first run: a group of one part is a ``vmap`` of one)."""
    if (
        getattr(type(system), "_packed", None) is None
        or len(system.subsystems) < GROUPED_MIN_SUBSYSTEMS
        or _nodes(system)
    ):
        return system
    return type(system)._packed(system)


def static_controls(system, v) -> np.ndarray:
    """Per relay, its control at a static state with velocities ``v`` (an operating
    point): the velocity of its coordinate, or for an impulse-read (voltage) control the
    sensing flux's velocity ``ẇ = φ_cp − φ_cn`` (no step, so no lag)."""
    flux = iter(sensing(system))
    return np.asarray(
        [v[next(flux)] if relay.impulse else v[i] for i, relay in relays(system)],
        dtype=np.float64,
    )


def sensing(system) -> np.ndarray:
    """The coordinates whose values are impulses in disguise (a voltage switch's sensing
    flux: it alternates about its momentum under the midpoint rule, see
    :mod:`diracvi.components.switch`): a step control should not judge them."""
    out = []
    for i, relay in relays(system):
        if relay.impulse:
            name = system.coords[i]
            out.append(system.coords.index(name[: -len(relay.coordinate)] + "w"))
    return np.asarray(out, dtype=np.int64)


def initial_modes(system) -> np.ndarray:
    """The relays' states as built (1.0 closed, 0.0 open)."""
    return np.array([float(r.closed) for r in _nodes(system)], dtype=np.float64)


def with_modes(system, modes):
    """``system`` with its relays' states set to ``modes`` (traceable)."""
    nodes = _nodes(system)
    if not nodes:
        return system
    return eqx.tree_at(
        lambda s: [r.closed for r in _nodes(s)],
        system,
        [jnp.asarray(modes[j], dtype=jnp.float64) for j in range(len(nodes))],
    )


def tolerances(system, rtol: float, atol) -> np.ndarray:
    """Per relay, the width of the window about its level in which a flip is taken
    (:func:`decide`: within half of it of the level, on either side):
    ``0.03 · rtol · |level| + atol`` (the share of ``rtol`` the step control holds a
    local error to), ``atol`` per relay (a voltage's or a current's absolute tolerance)."""
    out = []
    for j, (_, relay) in enumerate(relays(system)):
        level = max(abs(relay.on), abs(relay.off))
        a = atol[j] if np.ndim(atol) else atol
        out.append(0.03 * rtol * level + float(a))
    return np.asarray(out, dtype=np.float64)


def decide(found, modes, q, p, e_prev, h, tol, hmin):
    """After a try of size ``h`` with the states ``modes``: ``q = (q0, q1, q2, qc)`` its
    start, its half steps' ends and its whole step's end, ``p`` likewise; ``e_prev``: per
    relay, the last recorded step's impulse.

    The control's three step-centred values — ``u₁``, ``u₂`` of the halves, ``u_c`` of
    the whole step — are the means of its values at their steps' ends (exactly, for a
    capacitor's node: the midpoint rule's potential is ``(q_k + q_{k+1})/2C``), so the
    parabola ``u(τ) = a + bτ + cτ²`` that has those means is, with ``u₂ − u₁ + u_c =
    u(h)``, the control over the try to third order; its end value and its crossing of
    the level decide. (The line through ``u₁``, ``u₂`` alone misses ``u(h)`` by
    ``h²u''/16``: on a node relaxing exponentially into a switch's level, a fraction of a
    picosecond per switching, which a ring of switches adds up period after period.)

    ``(new modes, located, h_event, e2)``: the states at the try's end (the law's, or a
    flip taken short of the level: see below); whether the try may be accepted with them
    (no flip, or every flip within half its tolerance of its level, on either side);
    when it may not, the size of the try that ends at the first crossing ``τ*``; and the
    second half step's impulses (to carry if accepted).
    """
    if not found:
        return modes, jnp.asarray(True), h, e_prev
    index = jnp.asarray([i for i, _ in found])
    impulse = jnp.asarray([r.impulse for _, r in found])
    half = 0.5 * h
    # an impulse-read control: e_k = 2 Δp_k − e_{k−1}, u = e_k / h_k
    e1 = 2.0 * (p[1][index] - p[0][index]) - e_prev
    e2 = 2.0 * (p[2][index] - p[1][index]) - e1
    ec = 2.0 * (p[3][index] - p[0][index]) - e_prev
    u1 = jnp.where(impulse, e1, q[1][index] - q[0][index]) / half
    u2 = jnp.where(impulse, e2, q[2][index] - q[1][index]) / half
    uc = jnp.where(impulse, ec, q[3][index] - q[0][index]) / h
    # the means over [0, h/2], [h/2, h], [0, h] of the parabola a + bτ + cτ² at the
    # ends: u1 = a + bh/4 + ch²/8, u2 = a + 3bh/4 + 5ch²/8, uc = a + bh/2 + ch²/2
    c = 8.0 * (uc - 0.5 * (u1 + u2)) / (h * h)
    b = 2.0 * (u2 - u1) / h - c * h
    a = u1 - 0.25 * b * h - 0.125 * c * h * h
    u_end = a + b * h + c * h * h
    # the level each relay can cross next, and which way: an open relay closes above
    # ``on``, a closed one opens below ``off``
    closed = jnp.asarray(modes) > 0.5
    on = jnp.asarray([r.on for _, r in found])
    off = jnp.asarray([r.off for _, r in found])
    level = jnp.where(closed, off, on)
    sense = jnp.where(closed, -1.0, 1.0)
    law = jnp.stack([r.next(modes[j], u_end[j]) for j, (_, r) in enumerate(found)])
    slope = b + 2.0 * c * h  # at the end, where the flip is seen
    safe = jnp.where(slope == 0.0, 1.0, slope)
    # the crossing τ*: Newton on the parabola from its end (two steps: the parabola is
    # monotone over the try where a flip is located); the retry aims at it, unbiased
    tau = h + (level - u_end) / safe
    for _ in range(2):
        d = b + 2.0 * c * tau
        tau = tau - jnp.where(d * slope > 0.0, (a + b * tau + c * tau * tau - level) / d, 0.0)
    # the flip is taken within half the tolerance of the level on either side (a
    # window as wide as the one-sided [level, level + tol] it replaces, centred on the
    # crossing): short of the level by at most that and heading for it, it is taken
    # here, early, as a flip past the level is taken late — if the parabola reaches the
    # level within one more try's length (s* ≤ h: a control that turns back short of
    # the level, or creeps towards it, is not flipped on the extrapolation)
    window = 0.5 * tol
    gap = sense * (level - u_end)  # ≥ 0 short of the level
    rate = sense * slope  # > 0 heading for it
    bend = sense * c
    reach = (rate > 0.0) & (rate * rate >= -4.0 * bend * gap)
    root = jnp.sqrt(jnp.maximum(rate * rate + 4.0 * bend * gap, 0.0))
    s_star = 2.0 * gap / jnp.where(reach, rate + root, 1.0)  # the smaller root, stably
    near = (law == modes) & (gap <= window) & reach & (s_star <= h)
    new = jnp.where(near, 1.0 - modes, law)
    flips = new != modes
    # at most a quarter of the try at once: a sharp drop of the step size excites the
    # midpoint rule's alternating mode (the lag of the multipliers), which the step
    # control would then chase; the crossing is approached in a few steps instead
    tau = jnp.where(slope == 0.0, h, jnp.clip(tau, jnp.maximum(0.25 * h, hmin), h))
    within = (jnp.abs(u_end - level) <= window) | (tau >= h) | (h <= 2.0 * hmin)
    located = jnp.all(~flips | within)
    h_event = jnp.min(jnp.where(flips & ~within, tau, h), initial=h)
    return new, located, h_event, e2
