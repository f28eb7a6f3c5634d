r"""Sampling weights that take out the midpoint rule's period-2 alternation.

The midpoint rule's stability function tends to ``R(z) → −1`` on stiff modes, so a mode
excited at a corner of a device law (Meyer's capacitances at a MOSFET's saturation
boundary) persists as an undamped alternation of the *state*: a position ``±δ``, an
impulse ``±ε`` from node to node (Lindberg, BIT 11 (1971), for the trapezoidal rule, its
adjoint). What a run reports is a step quotient of the state (:mod:`._resample`): a branch
current ``i_{k+½} = (q_{k+1} − q_k)/h_k``, a node potential ``φ_{k+½} = −c_k/h_k`` with
``c_k = 2μ_k − c_{k−1}`` (whose homogeneous part is itself ``±ε``). So every reported
signal carries the alternation as

    s_k = f(t_{k+½}) + A (−1)^k / h_k        (A = 2δ, or −ε)

at its step centres: constant in the state, divided by each step's own size.

**The weights.** A value at ``τ`` is read from four consecutive step centres
``x_0 < x_1 < x_2 < x_3`` of one interval between corners with weights ``w`` that are
exact for quadratics and blind to the alternation:

    Σ w_j = 1,   Σ w_j (x_j − τ) = 0,   Σ w_j (x_j − τ)² = 0,   Σ w_j (−1)^j / h_j = 0.

Every ``w`` meeting the first three is the cubic's Lagrange weights ``L_j(τ)`` plus a
multiple of the third divided difference's ``r_j = 1/∏_{i≠j}(x_j − x_i)`` (the one
combination of four values that is blind to quadratics), so

    w = L(τ) − λ r,   λ = Σ_j a_j L_j(τ) / Σ_j a_j r_j,   a_j = (−1)^j / h_j :

the cubic through the four centres with the part of its cubic term that the
alternation makes taken out. ``Σ a_j r_j`` never vanishes: on sorted centres ``r_j``
alternates in sign as ``a_j`` does, so every term has one sign. On equal steps, at a
centre, ``w = (−1, 3, 5, 1)/8``; midway between two, ``(−1, 9, 9, −1)/16`` (the cubic's
own); half a step beyond the last centre (an interval's end), ``(7, −15, 1, 23)/16``,
where the quadratic through the last three, ``(3, −10, 15)/8``, multiplies a ``±A``
alternation by 3.5.

**Error on a smooth signal.** ``w·f = p₃(τ) − λ f[x_0, x_1, x_2, x_3]`` with ``p₃`` the
cubic interpolant, so the error is ``−λ f'''(ξ)/6`` plus the cubic's own ``O(h⁴)``:
third order, below the midpoint rule's second-order error at the centres. On equal
steps ``|λ| ≤ 3h³/4`` between the middle two centres (so ``h³|f'''|/8``), ``0.89h³``
over the window, ``9h³/2`` half a step beyond the last centre (``3h³|f'''|/4``, where
the quadratic's extrapolation errs by ``5h³|f'''|/16``).

**What is left.** The alternation's residue is exactly zero when it is ``A(−1)^k/h_k``
with ``A`` constant over the four steps. Where it is born (a corner of a device law
between breakpoints, or a source's corner: then the interval's first centre carries
half of it) the windows that reach back to its birth keep a part of it: the output within
two steps after it. ``A`` constant in the *state* is what the stiff limit gives: weights
blind to a constant-amplitude ``(−1)^k`` instead leave 1e-3 to 1e-2 of an alternation of
0.3 to 0.7, not falling with the step, on steps graded by up to 1.9 (the stiff RC of
``tests/test_smooth.py``, 40 to 320 steps), where ``A/h_k`` leaves a second-order error.
"""

from __future__ import annotations

import numpy as np


def alternation_free(x: np.ndarray, h: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Weights ``w = L(τ) − λ r`` (module doc) of four step centres ``x`` (Q, 4, sorted,
    distinct) of steps ``h`` (Q, 4) for the times ``query`` (Q,): exact for quadratics,
    ``Σ w_j (−1)^j / h_j = 0``."""
    # in units of the window's span: the same weights, numbers near one
    scale = (x[:, 3] - x[:, 0])[:, None]
    u = (x - query[:, None]) / scale
    a = np.array([1.0, -1.0, 1.0, -1.0]) * (scale / h)
    lagrange = np.empty_like(u)
    r = np.empty_like(u)
    for j in range(4):
        num = np.ones(len(u))
        den = np.ones(len(u))
        for i in range(4):
            if i != j:
                num = num * (0.0 - u[:, i])
                den = den * (u[:, j] - u[:, i])
        lagrange[:, j] = num / den
        r[:, j] = 1.0 / den
    lam = np.sum(a * lagrange, axis=1) / np.sum(a * r, axis=1)
    return lagrange - lam[:, None] * r
