r"""The corners of the parts' laws, located as a switch's instants are.

A behavioural law built of ``abs``, ``max``/``min``, comparisons (a select's predicate)
has corners: where an argument ``g`` of such an operation changes sign, the law has a
kink or a jump (:data:`~diracvi.runtime.roundoff.CORNERS`; ``ng_memristor``'s
``f(y) = β y + ½(α − β)(|y + V_t| − |y − V_t|)``: a kink of slope ``β`` = 2e12 A/V at
``|y| = V_t``). The midpoint rule samples the law at step centres only, and step
doubling compares centres with centres (``H/2`` against ``H/4``, ``3H/4``): a corner in
the last quarter of a try (or its first) is on one side at all three, the coarse and
fine steps agree, and the try is accepted with the law's other piece missing from its
end — and the output, read between the step centres through four of them, crosses the
corner (``ng_memristor`` before: 4.1e-3 of peak at 0.895 ns, ``i(v.xmem.vx)`` 1.15e10 A
where the current is still 0: the try 0.832 → 0.906 ns with its corner at 0.8952 ns,
after its last centre at 0.8876 ns).

So each try evaluates the corners' arguments at its three step centres (``t + H/4``,
``t + H/2``, ``t + 3H/4``), passes a parabola through them and reads it at the try's
ends. ``g`` is a smooth function of the state (a control voltage less a threshold), so
the parabola is good to third order, as a switch's control is (:mod:`.events`). A corner
whose argument has opposite signs at the two ends, each beyond the window

    w = A + (0.03·rtol + 16u)·T

(``A``: how far the controls' absolute tolerances move ``g``; ``T``: its terms, the
scale it is known to relatively; both carried through the law as round-off is,
:func:`~diracvi.runtime.roundoff.corner_arguments`; the switches' window is
``0.03·rtol·|level| + atol`` alike) is crossed inside the try: the try is retried aimed
at the parabola's root ``τ*`` (never below ``H/4``, as a switch's), and accepted once its
end is within the window (the corner on its end node) — or ``τ*`` within ``10⁻⁶ H`` of
an end. A try that starts or ends within a corner's window has no corner inside it.
A comparison whose operands agree identically over a range (``f > 0`` where ``f`` is 0
up to round-off) stays inside its window there and is never a crossing.

A landed corner ends the try as a breakpoint does: the next try carries no slope and no
period-2 fit across it, and the waveforms are read on either side of it from that side's
centres only (:func:`corner_nodes`, read by :mod:`diracvi.spice._run`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..runtime.roundoff import UNIT

#: ``τ*`` this close to an end of the try (relative to ``H``) is on it
ON_END = 1e-6


def window(k, rtol):
    """``w = A + (0.03·rtol + 16u)·T`` of each corner from ``k = (g, A, T)``."""
    return k[1] + (0.03 * rtol + 16.0 * UNIT) * k[2]


def _centres(nodes, h):
    """The try's three steps' centre states ``(q, v, t)``, at ``τ = H/4, H/2, 3H/4``."""
    t, q, qc, q1, q2 = nodes
    half = 0.5 * h
    return (
        (0.5 * (q + q1), (q1 - q) / half, t + 0.5 * half),
        (0.5 * (q + qc), (qc - q) / h, t + half),
        (0.5 * (q1 + q2), (q2 - q1) / half, t + 1.5 * half),
    )


def locate(corners, nodes, h, rtol, dv, hmin):
    """``(located, h_event, landed)`` of a try of size ``h``: ``corners`` is
    :func:`~diracvi.model.roundoff.force_corners`' function, ``nodes = (t, q, q_c, q₁,
    q₂)`` the try's start and its three steps' ends (absolute), ``dv`` the velocities'
    absolute tolerances. ``located``: no corner crossed inside the try (module
    docstring); ``h_event``: else the size of the retry aimed at the first crossing;
    ``landed``: the try ends on a corner."""
    ks = [corners(qq, vv, dv, tt) for qq, vv, tt in _centres(nodes, h)]
    g1, gm, g2 = (k[0] for k in ks)
    w = jnp.maximum(jnp.maximum(window(ks[0], rtol), window(ks[1], rtol)), window(ks[2], rtol))
    # the parabola through the three centres in s = τ/H − 1/2: g = gm + b s + c s²
    b = 2.0 * (g2 - g1)
    c = 8.0 * (g1 + g2 - 2.0 * gm)
    g0 = gm - 0.5 * b + 0.25 * c
    ge = gm + 0.5 * b + 0.25 * c
    out0, oute = jnp.abs(g0) > w, jnp.abs(ge) > w
    cross = out0 & oute & (g0 * ge < 0.0)
    # its root between the ends: from the secant, three Newton steps kept inside
    safe = jnp.where(cross, g0 - ge, 1.0)
    s = -0.5 + jnp.where(cross, g0 / safe, 0.5)
    for _ in range(3):
        d = b + 2.0 * c * s
        step = jnp.where(d != 0.0, (gm + b * s + c * s * s) / jnp.where(d != 0.0, d, 1.0), 0.0)
        s = jnp.clip(s - step, -0.5, 0.5)
    tau = h * (s + 0.5)
    at_end = cross & (h - tau <= ON_END * h)
    at_start = cross & (tau <= ON_END * h)
    aim = cross & ~at_end & ~at_start
    located = ~jnp.any(aim) | (h <= 2.0 * hmin)
    target = jnp.clip(tau, jnp.maximum(0.25 * h, hmin), h)
    h_event = jnp.min(jnp.where(aim, target, h), initial=h)
    landed = jnp.any((out0 & ~oute) | at_end)
    return located, h_event, landed


@eqx.filter_jit
def _at_centres(corners, mid, vel, dv, tc):
    """``corners`` at each step centre ``(mid, vel, tc)``, stacked."""
    return jax.vmap(lambda a, b, c: corners(a, b, dv, c))(mid, vel, tc)


def corner_nodes(corners, t, q, h, rtol, dv) -> np.ndarray:
    """The interior nodes of a run (indices into ``t``) between two step centres on
    opposite sides of a corner, each beyond its window: where the waveforms are not read
    across (the run's located corners)."""
    t, q, h = np.asarray(t), np.asarray(q), np.asarray(h)
    if len(h) < 2:
        return np.zeros(0, dtype=np.int64)
    mid = 0.5 * (q[1:] + q[:-1])
    vel = (q[1:] - q[:-1]) / h[:, None]
    tc = t[:-1] + 0.5 * h
    # padded to a power of two (the last row repeated): one program per law and size
    # class, not per run (a fresh compile was half of ng_memristor's warm run, 0.17 s)
    n = len(h)
    size = 1 << (n - 1).bit_length()

    def pad(x):
        return np.concatenate([x, np.repeat(x[-1:], size - n, axis=0)])

    dv = np.broadcast_to(np.asarray(dv, dtype=np.float64), q.shape[1:])
    ks = np.asarray(_at_centres(corners, pad(mid), pad(vel), dv, pad(tc)))[:n]
    g = ks[:, 0, :]
    w = np.asarray(window(np.moveaxis(ks, 1, 0), rtol))
    out = np.abs(g) > w
    flips = out[1:] & out[:-1] & (g[1:] * g[:-1] < 0.0)
    return np.flatnonzero(np.any(flips, axis=1)) + 1


__all__ = ["corner_nodes", "locate", "window"]
