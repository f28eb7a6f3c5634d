r"""The step-doubling error of one try, shared by the variable-step loops.

:mod:`diracvi.driver.adaptive` (the compiled loop) and
:mod:`diracvi.driver.adaptive_sparse` (the sparse host loop) judge a try alike: its
coarse step against its two fine ones, per coordinate and per multiplier, at the share
:data:`SAFETY` of the tolerance (the rules are in :mod:`diracvi.driver.adaptive`'s
docstring); :func:`growth` sizes the next try and :func:`gap_error` judges the output's
interpolant between two tries. :func:`alternating` fits the period-2 part of the nodes
(a mode the midpoint rule does not damp) from the nodes around a try's start, and
:func:`alternating_from_retry` from two tries of one start; :func:`estimate` can leave it
out.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp

#: the local error of a step is held at this share of the tolerance: errors accumulate
#: over the steps (an oscillating circuit's phase error over many periods). Measured
#: against fine ngspice runs at the decks' own settings (reltol 1e-3): with 1 a 1 ns-edge
#: RLC was off by 2.4e-3 of its peak, with 0.1 the 3-stage ladder (2000 steps, 5
#: periods) by 1.3e-3, with 0.03 every deck within 5.6e-4 for 1.1-1.7x the steps of 0.1
#: (4.0e-4 once the node potentials were judged too).
#: Passed to the program as data, like the tolerances (a change compiles nothing).
SAFETY = 0.03

#: the error controls of :func:`~.adaptive_sparse.adaptive_sparse` (this step doubling,
#: or :mod:`.sparse_truncation`'s one solve a step), and the one ``spice.run`` takes; here,
#: not there, so the command line lists them without importing the loop
ERRORS = ("doubling", "truncation")
DEFAULT_ERROR = "doubling"

#: how far apart (a ratio) the alternation's amplitude may read in the last try and in
#: this one for :func:`gap_error` to take it for one alternation (:func:`gap_error`)
ALIKE = 4.0

#: the order this error control is written for (the midpoint rule's)
_ORDER = 2


class Estimate(NamedTuple):
    """One try's error estimate (:func:`estimate`): the worst scaled error, the running
    peaks with this try's values, the second fine step's impulse ``c₂``, the worst
    scaled error without the period-2 part of the positions, and the nodal momenta's
    running peak (None where they are not judged)."""

    err: object
    q_peak: object
    v_peak: object
    m_peak: object
    c2: object
    smooth: object
    p_peak: object = None


def alternating(xp, last, this, h_last, half):
    """The period-2 part ``δ`` of each coordinate at a try's start (:func:`estimate`):
    with the last try's two fine increments ``last = (b₁, b₂)`` (steps of ``h_last``)
    and this try's ``this = (a₁, a₂)`` (steps of ``half``), the five nodes
    ``q₋₂ … q₂`` at ``t = (−2h_last, −h_last, 0, half, 2 half)`` are taken as a cubic
    plus ``δ (−1)^i``: the fourth divided difference annihilates the cubic,

        δ = q[t₋₂, …, t₂] / s[t₋₂, …, t₂],     s_i = (−1)^i,

    exact for a constant alternation on a signal that is locally a cubic (its error is
    the fourth derivative's, ``O(h⁴)``, a step below the truncation error's ``O(h³)``)."""
    (b1, b2), (a1, a2) = last, this
    x = (-2.0 * h_last, -h_last, 0.0, half, 2.0 * half)
    values = (-(b1 + b2), -b2, 0.0 * a1, a1, a1 + a2)  # relative to q₀ (the weights sum to 0)
    num, den = 0.0, 0.0
    for i in range(5):
        weight = 1.0
        for j in range(5):
            if j != i:
                weight = weight * (x[i] - x[j])
        num = num + values[i] / weight
        den = den + (-1.0) ** i / weight
    return num / den


def alternating_from_retry(rejected, this, h_rejected, h_try):
    """The period-2 part ``δ`` of each coordinate at a try's start, from two tries of one
    start (:func:`estimate`): a rejected try of ``H_a`` whose ``q₂ − q_c`` was ``d_a``, and
    this one of ``H_b`` with ``d_b``. The alternation adds ``2δ`` to both, the truncation
    error ``K H³`` (the midpoint rule's local error, to leading order), so

        d_a = 2δ + K H_a³,   d_b = 2δ + K H_b³   ⇒   δ = (d_b − ρ d_a) / (2 (1 − ρ)),

    ``ρ = (H_b/H_a)³``; its error is the truncation error's next order, ``O(H⁴)`` (a share
    ``~(1 − H_b/H_a)`` of ``K H⁴``'s coefficient), and ``1/(1 − ρ)`` amplifies the two
    estimates' own error: used with ``ρ ≤ 3/4`` only. Unlike :func:`alternating` it needs
    no step before the start, so it fits ``δ`` on the try after a corner (a switching
    instant), where the nodes before it are on another law."""
    rho = (h_try / h_rejected) ** 3
    return (this - rho * rejected) / (2.0 * (1.0 - rho))


def estimate(
    xp,
    q,
    steps,
    mus,
    c_prev,
    h_try,
    peaks,
    tolerances,
    hmax,
    base=0.0,
    delta=None,
    momenta=None,
    potentials_over_tmax=True,
    c_alternation=None,
) -> Estimate:
    """The step-doubling error of one try (module docstring), for the compiled loop
    (``xp = jax.numpy``) and the sparse host loop (``xp = numpy``) alike.

    ``steps = (q_c, q₁, q₂)``: the coarse step's end and the two fine steps' ends from
    ``q``; ``mus = (μ_c, μ₁, μ₂)`` their multipliers; ``peaks = (Q, V, Φ)``, or
    ``(Q, V, Φ, P)`` with the nodal momenta's running peak ``P``;
    ``tolerances = (share, rtol, atol_q, atol_v, atol_m)``; ``base``: what the positions
    are relative to (:mod:`.rebase`), added back for their running peaks.

    ``delta``: the period-2 part of each coordinate at ``q`` (:func:`alternating`), or
    None; ``Estimate.smooth`` is then the error with ``2δ`` taken out of ``q₂ − q_c``
    (else ``err`` again). A mode the midpoint rule does not damp — a loop of capacitors
    and voltage sources, whose charges the rule fixes only at the step midpoints; a
    stiff junction's ringing, amplification → −1 — carries an alternation ``δ(−1)^k`` of
    the node values. The coarse step flips it once, the fine ones twice, so
    ``q₂ − q_c = 2δ + 3e`` whatever ``H``: a floor that no shorter step lowers, which
    the growth law, written for ``e ∝ H³``, reads as a reason to stay short.

    ``momenta = (p_c, p₂, impulse, inertia)``: the coarse step's and the second fine
    step's end momenta, ``impulse(c) = A(q)ᵀc`` and the diagonal ``M_jj`` of ``∂²L/∂v²``
    per coordinate (0 where the Lagrangian has no velocity), or None. The nodal momentum
    ``p̂ = p − ½A(q)ᵀc`` of each end (the stepped one lags by half the step's impulse
    ``c``: :func:`~diracvi.discretization.equations.nodal_momentum`) is judged as a state,
    as the positions are, against its own running peak ``P`` — at least ``M_jj`` times
    its velocity's, ``V`` (:func:`node_momentum_error`): an inductor's flux, with its
    coupled windings' share.

    ``potentials_over_tmax``: the multipliers' error held to its mean over TMAX, as a
    rate's (:func:`over_tmax`); ``False`` judges each try's node potentials against the
    tolerance itself, as a state; a boolean per multiplier chooses (the compiled loop:
    held to TMAX only where the potential rings, :mod:`.adaptive`).

    ``c_alternation``: the period-2 part ``ε`` of the carried impulse ``c₋₁``
    (:func:`impulse_alternation`), or None. The impulses ``c_k = 2μ_k − c_{k−1}`` carry
    an alternation ``ε(−1)^k`` that no step damps and that is not in the state (the
    μ's are free of it): it moves the coarse potential ``φ_c`` by ``ε/H`` and leaves the
    fine ones' mean as it is, a floor that grows as the step shrinks. Given, the coarse
    potential is read from ``c₋₁ − ε``."""
    qc, q1, q2 = steps
    mu_c, mu1, mu2 = mus
    share, rtol, atol_q, atol_v, atol_m = tolerances
    half = 0.5 * h_try
    v1, v2 = (q1 - q) / half, (q2 - q1) / half
    q_peak = xp.maximum(peaks[0], xp.maximum(xp.abs(q1 + base), xp.abs(q2 + base)))
    v_peak = xp.maximum(peaks[1], xp.maximum(xp.abs(v1), xp.abs(v2)))
    # multipliers: the step-centred values φ = −c/h of the impulses c_k = 2μ_k − c_{k−1}
    # (node potentials of a circuit), coarse against the mean of the two fine ones
    c1 = 2.0 * mu1 - c_prev
    c2 = 2.0 * mu2 - c1
    c_start = c_prev if c_alternation is None else c_prev - c_alternation
    phi_c = -(2.0 * mu_c - c_start) / h_try
    phi1, phi2 = -c1 / half, -c2 / half
    diff_m = xp.abs(phi_c - 0.5 * (phi1 + phi2)) / (2.0**_ORDER - 1.0)
    m_peak = xp.maximum(peaks[2], xp.maximum(xp.abs(phi1), xp.abs(phi2)))
    e_m = diff_m / (share * rtol * m_peak + atol_m)
    if potentials_over_tmax is True:
        e_m = over_tmax(xp, e_m, h_try, hmax)
    elif potentials_over_tmax is not False:  # per multiplier
        e_m = xp.where(potentials_over_tmax, over_tmax(xp, e_m, h_try, hmax), e_m)

    e_p, p_peak = e_m[:0], None
    if momenta is not None:
        p_c, p2, impulse, inertia = momenta
        c_c = 2.0 * mu_c - c_prev
        gap_p = p2 - p_c - 0.5 * impulse(c2 - c_c)  # p̂₂ − p̂_c
        node = xp.abs(p2 - 0.5 * impulse(c2))  # |p̂₂|
        p_peak = node if len(peaks) < 4 else xp.maximum(peaks[3], node)
        # the flux's scale: its own peak, at least the winding's own inductance times
        # its current's (an uncoupled inductor's are one)
        scale = xp.maximum(p_peak, inertia * v_peak)
        e_p = node_momentum_error(xp, gap_p, inertia, share * rtol * scale + inertia * atol_v)

    def worst(gap):
        diff = xp.abs(gap) / (2.0**_ORDER - 1.0)
        e_q = diff / (share * rtol * q_peak + atol_q)
        e_v = diff / h_try / (share * rtol * v_peak + atol_v)
        e_v = over_tmax(xp, e_v, h_try, hmax)
        return xp.max(xp.concatenate([e_q, e_v, e_m, e_p]), initial=0.0)

    err = worst(q2 - qc)
    smooth = err if delta is None else worst(q2 - qc - 2.0 * delta)
    return Estimate(err, q_peak, v_peak, m_peak, c2, smooth, p_peak)


def impulse_alternation(rejected, this, h_rejected, h_try):
    """The period-2 part ``ε`` of the carried impulse ``c₋₁`` (one per multiplier), from
    two tries of one start: a rejected try of ``H_a`` and this one of ``H_b``, each
    giving ``m = c₋₁ + 2(μ₂ − μ_c)``, its coarse potential's step-doubling difference
    in impulse units, ``(φ_c − (φ₁ + φ₂)/2)·H``. The alternation of ``c₋₁`` adds ``ε`` to
    both (:func:`estimate`), the truncation error ``K H³`` (``φ_c − φ̄ = O(H²)``), so

        m_a = ε + K H_a³,   m_b = ε + K H_b³   ⇒   ε = (m_b − ρ m_a) / (1 − ρ),

    ``ρ = (H_b/H_a)³``: :func:`alternating_from_retry`'s fit (used with ``ρ ≤ 3/4``), of
    the multipliers. Where ``c`` carries no alternation it returns the next order of the
    truncation error, ``O(H⁴)``."""
    return 2.0 * alternating_from_retry(rejected, this, h_rejected, h_try)


def node_momentum_error(xp, gap, inertia, tolerance):
    """The step-doubling error of the nodal momenta, ``gap = p̂₂ − p̂_c`` at a try's end,
    for each coordinate with inertia ``M_jj > 0`` (0 elsewhere), against ``tolerance``
    in momentum units (:func:`estimate`: ``s·rtol·max(P_j, M_jj V_j) + M_jj atol_v,j``,
    ``P_j`` the nodal momentum's running peak, ``V_j`` its velocity's):

        e_p,j = |p̂₂ − p̂_c|_j / (3 tolerance_j).

    The positions alone do not judge a ringing mode: the midpoint rule's local error is
    ``(H³/12) d³x/dt³`` in each component of the state ``x = (q, p̂)``, and ``d³q/dt³``
    of an oscillation passes through zero twice a period, where the momentum's peaks.
    Judged on its charges only, an RLC circuit took tries up to twice as long there,
    with the inductor's current carrying up to 3.3 tolerances of local error
    (``es_rlc``: its ringing's phase then 1.04e-3 of the current's peak off). SPICE
    judges an inductor's flux as it judges a capacitor's charge (the truncation error of
    both states), relative to the flux itself (its ``reltol·max(|Φ₀|, |Φ₁|)``). A state,
    its local error ``O(H³)`` as the positions': judged per try, not as a rate (no
    :func:`over_tmax`), and against its own peak, as they are. A winding coupled to
    another carries the other's flux ``M₁₂ i₁``: judged as its own current instead
    (``L₂`` times that current's peak: in ``xy_minductors`` ~1/3000 of the secondary's
    flux), the local error of its stiff modes (both ``L(1 ± k)/R`` below the steps, the
    order reduced: ``H^2.3–2.6`` at 2–16 µs) held that deck to 22110 steps for 3514 —
    at 2 µs the secondary's flux 1.2e-8 of itself off, 0.73 tolerances of ``L₂ i₂`` —
    with no output any more accurate (0.00032 of peak on both)."""
    has = inertia > 0.0
    scaled = xp.abs(gap) / (2.0**_ORDER - 1.0)
    return xp.where(has, scaled / xp.where(has, tolerance, 1.0), 0.0)


def over_tmax(xp, e, h_try, hmax):
    """A rate's error judged as its mean over TMAX (``hmax``): ``min(e, e·H/hmax)``. A
    mode ringing at the midpoint's amplification −1 (a stiff junction) moves the end
    state by a fixed amount whatever ``H``, which read as a plain rate grows as ``1/H``
    and would drive the step to hmin."""
    return xp.minimum(e, e * h_try / hmax)


def growth(xp, err):
    """The next try's size over this one's: ``clip(0.9 e^{−1/3}, 0.2, 2)``."""
    return xp.clip(0.9 * xp.maximum(err, 1e-12) ** (-1.0 / (_ORDER + 1)), 0.2, 2.0)


def growth_of(err: float) -> float:
    """:func:`growth` of one number, for a host loop (NumPy's clip of a scalar costs
    more than the law itself)."""
    return min(2.0, max(0.2, 0.9 * max(err, 1e-12) ** (-1.0 / (_ORDER + 1))))


def gap_error(xs, ys):
    """How far the output's interpolant may be off in the gaps a try's first step centre
    closes (:mod:`diracvi.spice._resample`): with ``xs = (x₋₂, x₋₁, x₁, x₂)`` — the last
    try's two centres and this try's — and ``ys`` the values there (arrays, one entry
    per signal), the quadratic the output draws through ``(x₋₂, x₋₁, x₁)`` on
    ``(x₋₂, x₋₁)`` and through ``(x₋₁, x₁, x₂)`` on ``(x₋₁, x₁)``, each against the
    straight line between the gap's ends, at the gap's middle:

        max( |f[x₋₂, x₋₁, x₁]| (x₋₁ − x₋₂)²/4,  |f[x₋₁, x₁, x₂]| (x₁ − x₋₁)²/4 ).

    Two interpolants of different order that disagree say the signal is not resolved
    there (the difference of two stencils of the same order can miss a knee: both
    quadratics cut a diode's turn-off alike). A signal whose values alternate is left
    out (0), and where the two second differences have opposite signs, ``c ± a``, only
    their common part ``c`` is judged in both: an alternation on a trend (a stiff mode
    ringing under the midpoint rule) gives such a pair, and no cut lowers its part ``a``."""

    def second(a, b, c):  # the divided difference f[a, b, c]
        return ((c[1] - b[1]) / (c[0] - b[0]) - (b[1] - a[1]) / (b[0] - a[0])) / (c[0] - a[0])

    points = list(zip(xs, ys, strict=True))
    f_left, f_right = second(*points[:3]), second(*points[1:])
    # an alternation on a trend is one pattern on both sides: the differences within the
    # last try and within this one agree (to ALIKE) once scaled by their tries' steps —
    # times h where the alternation dominates (its amplitude in a step-centred value goes
    # as 1/h: a charge δ read as 2δ/h), over h where the trend does. A corner of a law
    # between two centres followed by the small alternation it excites is neither: one
    # large difference, then small ones (ng_mosamp's Meyer C_gb reaching C_ox: -5.7e-5,
    # +2.4e-6, -2.5e-6 A, 20 times apart on steps of 3.2 and 2.9 ps), and is judged
    # plainly, as a corner
    d1, d2, d3 = ys[1] - ys[0], ys[2] - ys[1], ys[3] - ys[2]
    h_l, h_r = xs[1] - xs[0], xs[3] - xs[2]

    def agree(a, b):
        return jnp.maximum(a, b) <= ALIKE * jnp.minimum(a, b)

    a1, a3 = jnp.abs(d1), jnp.abs(d3)
    alike = agree(a1 * h_l, a3 * h_r) | agree(a1 / h_l, a3 / h_r)
    # the same alternation riding on a trend (the differences all of one sign, the slopes
    # alternating: an inverter's load current while its input ramps) turns the two second
    # differences opposite, ``f = c ± a``: only their common part ``c``, the curvature,
    # is judged (the alternating part ``a`` is the ringing below again; judged, it held
    # the 4-stage inverter chain's first edge in a cycle of cut and retaken tries at
    # 2.4-2.7 tolerances whatever the cut)
    common = 0.5 * (f_left + f_right)
    flip = (f_left * f_right < 0.0) & alike
    f_left, f_right = jnp.where(flip, common, f_left), jnp.where(flip, common, f_right)
    left = abs(f_left) * 0.25 * (xs[1] - xs[0]) ** 2
    right = abs(f_right) * 0.25 * (xs[2] - xs[1]) ** 2
    # a signal alternating from centre to centre (its differences − + − or + − +) is a
    # stiff mode ringing under the midpoint rule, whose amplitude no shorter step
    # reduces (it grows as 1/h): not an interpolation error a cut could mend
    ringing = (d1 * d2 < 0.0) & (d2 * d3 < 0.0) & alike
    return jnp.where(ringing, 0.0, jnp.maximum(left, right))


__all__ = [
    "DEFAULT_ERROR",
    "ERRORS",
    "SAFETY",
    "Estimate",
    "alternating",
    "alternating_from_retry",
    "estimate",
    "gap_error",
    "growth",
    "growth_of",
    "impulse_alternation",
    "node_momentum_error",
    "over_tmax",
]
