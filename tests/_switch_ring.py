r"""The exact response of ``ng_switch_osc``: a ring of switch inverters, event by event.

Stage ``j`` (``j = 0 … N−1``; stage 0 drives ``osc_out``) is two hysteresis switches on
its output node ``v_j``: ``sp`` from ``v_j`` to VDD, closed when ``VDD − v_{j−1} > VT +
VH`` and open when it is below ``VT − VH``; ``sn`` from ``v_j`` to ground, closed when
``v_{j−1} > VT + VH``, open below ``VT − VH`` (each held in between), with ``C = Cl + C2``
from ``v_j`` to ground and to the constant VDD. Between two switchings every node obeys
its own linear law

    C v̇_j = g_p (VDD − v_j) − g_n v_j,   v_j(t) = v∞ + (v_j(t₀) − v∞) e^{−(t−t₀)/τ},

``v∞ = VDD g_p/(g_p + g_n)``, ``τ = C/(g_p + g_n)``, ``g = 1/RON`` closed, ``1/ROFF``
open; the instant at which ``v_{j−1}`` reaches a level is ``t₀ + τ ln((v₀ − v∞)/(level −
v∞))``. Marching from one such instant to the next gives the waveforms exactly (to
round-off): no step, no tolerance.

The start is the deck's: ``.ic v(osc_out)=0.25`` held at the operating point (the other
nodes alternately at VDD and 0, each switch as its input at the operating point sets
it), released at t = 0.
"""

from __future__ import annotations

import math

import numpy as np


def ring_edges(stop, **ring):
    """The instants at which ``v(osc_out)`` (stage 0's output) rises through VDD/2,
    up to ``stop``, exactly (module docstring)."""
    return ring_march(stop, **ring)[0]


def ring_switchings(stop, **ring):
    """Every switching up to ``stop``, in order: ``(t, stage, "sp" or "sn", closed after)``,
    exactly (module docstring)."""
    return ring_march(stop, **ring)[1]


def ring_march(stop, *, stages=17, c=0.2e-12, vdd=3.0, ron=1e3, roff=1e12, vt=1.0, vh=0.1, v0=0.25):
    """``(rising edges of v(osc_out), switchings)`` up to ``stop``: the march of the
    module docstring, from one switching instant to the next."""
    n = stages
    v = np.array([vdd if j % 2 else 0.0 for j in range(n)])
    v[0] = v0
    sp = [vdd - v[j - 1] > vt + vh for j in range(n)]
    sn = [v[j - 1] > vt + vh for j in range(n)]
    t0 = np.zeros(n)  # each node's law holds from t0[j], where it had the value v[j]

    def law(j):
        gp = 1.0 / (ron if sp[j] else roff)
        gn = 1.0 / (ron if sn[j] else roff)
        return vdd * gp / (gp + gn), c / (gp + gn)

    def value(j, t):
        vi, tau = law(j)
        return vi + (v[j] - vi) * math.exp(-(t - t0[j]) / tau)

    def reach(j, level, after):
        """When node j next reaches ``level`` after ``after`` on its present law (inf if
        it does not: it tends away from it, or passed it before)."""
        vi, tau = law(j)
        if (v[j] - level) * (vi - level) >= 0.0:
            return math.inf
        when = t0[j] + tau * math.log((v[j] - vi) / (level - vi))
        return when if when > after else math.inf

    def levels(j):
        """The levels of v_j at which a switch of the stage it drives flips."""
        k = (j + 1) % n
        return (vt - vh if sn[k] else vt + vh, vdd - (vt - vh) if sp[k] else vdd - (vt + vh))

    edges, switchings = [], []
    t = 0.0
    while True:
        when = [min(reach(j, lv, t) for lv in levels(j)) for j in range(n)]
        j = int(np.argmin(when))
        t_next = min(when[j], stop)
        rise = reach(0, 0.5 * vdd, t)
        if value(0, t) < 0.5 * vdd and rise <= t_next:
            edges.append(rise)
        if when[j] > stop:
            return np.array(edges), switchings
        t, k = t_next, (j + 1) % n
        u = value(j, t)  # stage k's input, at one of its levels
        v[k], t0[k] = value(k, t), t
        # the level crossed is u itself (to round-off): flip the switch it belongs to
        if abs(u - (vt + vh)) < 1e-9 or abs(u - (vt - vh)) < 1e-9:
            sn[k] = not sn[k]
            switchings.append((t, k, "sn", sn[k]))
        else:
            sp[k] = not sp[k]
            switchings.append((t, k, "sp", sp[k]))
