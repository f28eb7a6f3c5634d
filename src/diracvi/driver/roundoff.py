r"""The branch currents' round-off floor of a try: no current is judged below it.

A current source's law computed in floating point is known only to its round-off: a
law whose terms cancel (``ng_memristor``'s ``β y − ½β(|y + V_t| − |y − V_t|)``, exactly
0 below the threshold, ``β`` = 2e12) computes to values up to ``u`` times its terms,
~5e-4 A, scattered in sign from one evaluation to the next. Each of a try's three steps
evaluates it at its own state, so its step-doubling difference carries that scatter
whatever the step: at a rate's tolerance ``s·rtol·V + abstol`` (``V`` the current's
running peak, itself that scatter) no try passes, and the loop steps at ~5e-15 s until its
tries budget is spent. (SPICE judges only the reactive elements' charges and fluxes,
its truncation error, and never reads this current: ``Cx``'s charge, 7000 C, does not
notice 1e-19 C.)

So each part that sets a current by a law (:class:`~diracvi.components.ControlledPart`'s
``law_roundoff``: an I-form behavioural source) bounds that current's round-off at each of
the try's three steps (its running error bound, :mod:`diracvi.runtime.roundoff`, at the
step's mean velocities and centre time), and the floor of the try is

    N = max over the three steps of  Σ_parts E_part,

a bound on any branch current's round-off those laws cause — a current driven into a
network of positive resistances and capacitances is not amplified in any branch (the
no-gain property of such networks), and the parts' bounds add. The step-doubling
difference ``q₂ − q_c`` carries at most ``(H/2)N + (H/2)N + HN = 2HN`` of it, so the
currents' absolute tolerance is at least ``2N/3`` (the difference is read as ``/3``) and
the charges' at least ``2HN/3`` (:func:`floors`): ``max``, not a sum, so a circuit whose
laws round below ``abstol`` (every other deck's: ``u`` times their terms is ~1e-16 A
against 1e-12) steps bit for bit as before.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..model.roundoff import force_roundoff


def current_floor(system):
    """``N(nodes, h_try)``, the try's floor of the branch currents' round-off (module
    docstring), or None where no part has a law's bound. ``nodes = (t, q, q_c, q₁, q₂)``:
    the try's start and its three steps' ends (absolute positions)."""
    bound = force_roundoff(system)
    if bound is None:
        return None

    def floor(nodes, h_try):
        t, q, qc, q1, q2 = nodes
        half = 0.5 * h_try
        steps = (
            (0.5 * (q + qc), (qc - q) / h_try, t + half),
            (0.5 * (q + q1), (q1 - q) / half, t + 0.5 * half),
            (0.5 * (q1 + q2), (q2 - q1) / half, t + 1.5 * half),
        )
        return jnp.max(jnp.stack([jnp.sum(bound(*s)) for s in steps]))

    return floor


def floors(atol_q, atol_v, judged, floor, h_try):
    """The absolute tolerances of a try with the currents' round-off floor ``N``
    (:func:`current_floor`): on the ``judged`` coordinates (the branch charges)
    ``max(atol_v, 2N/3)`` for their currents and ``max(atol_q, 2 H N/3)`` for the
    charges; the others as they are."""
    share = 2.0 / 3.0 * floor
    atol_v = jnp.where(judged, jnp.maximum(atol_v, share), atol_v)
    atol_q = jnp.where(judged, jnp.maximum(atol_q, share * h_try), atol_q)
    return atol_q, atol_v


__all__ = ["current_floor", "floors"]
