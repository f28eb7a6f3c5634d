r"""A try of the variable-step loop: one step of ``H`` and two of ``H/2`` from one start.

The compiled loop (:mod:`diracvi.driver.adaptive`) judges a step size by step doubling:
from ``(q, p)`` at ``t`` the coarse step of ``H`` and the two fine ones of ``H/2`` are
each an ordinary discrete Dirac step, ``StepEquations(…, h)`` solved by Newton;
:func:`three_steps` takes them, with the pinned positions re-pinned at each end
(:mod:`.pinned`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from ..discretization.equations import StepEquations, first_guess, split
from . import pinned as pinned_positions


def one_step(system, rule, solver, h, t, q, p, q_guess, mu_guess, atol=None):
    """One discrete Dirac step of size ``h`` from ``(q, p)`` at ``t`` (the (+) midpoint
    equations solved by ``solver`` from the guess ``q_guess``, ``mu_guess``): ``(q₁, p₁,
    μ, ok, Newton iterations)``, ``ok`` when Newton converged to finite values.
    ``atol`` (optional, one per unknown ``(q₁, μ)``): the absolute accuracy the solve
    may stop at (:meth:`~diracvi.NewtonSolver.solve`); by default it converges to
    round-off."""
    eqs = StepEquations(system, rule, "plus", h, q, p, t)
    guess = first_guess(system, rule, q, q_guess, mu_guess)
    res = solver.solve(eqs, guess, solver.init(eqs), atol)
    q1, mu = split(system, res.x)
    p1 = solver.momentum(eqs, res.x, res.state)
    ok = (res.status == 0) & jnp.all(jnp.isfinite(q1)) & jnp.all(jnp.isfinite(p1))
    return q1, p1, mu[: system.m], ok, res.iterations


def three_steps(
    step, modes, h_try, t, q, p, vel, mu_g, pin=None, *, last, predict, coarse_atol=None
):
    """A try's three steps from ``(q, p)`` at ``t``: the coarse one of ``H``, the first
    fine one of ``H/2``, the second fine one of ``H/2`` from the first's end. ``(q ends,
    p ends, μ's, oks, Newton iterations, means)``, the first four stacked in that order;
    ``means``: each step's mean of its ends as solved (for the pinned coordinates,
    :mod:`.pinned`).

    Each step's Newton starts from a prediction of its end, ``q + h v``, with ``v`` its
    mean velocity: the coarse step's ``vel`` (the caller's); the first fine step's
    ``v(t + H/4)`` on the line through the last velocity ``v(t − lag)`` (``last = (v,
    lag)``) and the coarse step's mean velocity ``(q_c −
    q)/H``, which stands at ``t + H/2``: both ends of that line are already solved, so
    the guess is off by ``O(H³)`` instead of the ``O(H²)`` of ``q + (H/2)·vel``; the
    second fine step's end is guessed as the coarse step's end ``q_c`` — the two differ
    by the step-doubling difference, about three times the local error the try is
    judged by (the linear extrapolation ``q₁ + (q₁ − q)`` is off by ``O(H²)``). On the
    bridge rectifier of :mod:`diracvi.spice._ngspice` at its own tolerances this took
    the Newton iterations from 5.2 to 2.9 a solve (49 195 → 27 823 over 3156 tries),
    the steps and their results unchanged. (The multipliers' guesses stay as they were:
    they enter the step linearly and each solve factors its Jacobian at its first
    iterate, so their error is gone after one update.) ``predict=False`` guesses as
    before, every step from ``vel`` and the second fine one on from the first's increment:
    the variable-step loop does so in a circuit with switches, where the predicted starts
    moved a switch ring's shortest step from 3.6e-14 to 9.0e-15 s
    (``tests/test_switches.py``; the cause was not found).

    ``pin = (mask, (m₋₂, m₋₁), h_last, use)``: the pinned coordinates, the means of the
    last two recorded steps (each ``h_last`` long) and whether they may be used (no
    corner since); each step's end is re-pinned from the two steps before it (the coarse
    and the first fine one: the last two recorded; the second fine one: the last recorded
    and the first fine one).

    ``coarse_atol`` (optional, one per unknown ``(q_c, μ_c)``): the accuracy the coarse
    step is solved to (read only through the step-doubling difference, it need not be
    solved to round-off: :mod:`diracvi.driver.adaptive`); ``step`` then takes it as its
    last argument, and 0 for the two fine steps, which are recorded and converge to
    round-off.

    One step solve in a loop of three iterations, each picking its inputs, rather than
    three solves written out: the step (Newton, its Jacobian, the limiting) is then
    traced, lowered and compiled once instead of three times — most of a first call's
    compilation of this program (the steps run in the same order on the same values)."""
    half = 0.5 * h_try
    n, m = q.shape[0], mu_g.shape[0]

    v_back, lag = last

    def v_fine1(q_c):
        # the first fine step's mean velocity v(t + H/4), on the line through the last
        # step's mean velocity (v(t − lag)) and the coarse step's (v(t + H/2))
        v_c = (q_c - q) / h_try
        return v_back + (v_c - v_back) * ((0.25 * h_try + lag) / (half + lag))

    def one(k, out):
        qs, ps, mus, oks, its, means = out
        fine2 = k == 2
        h = jnp.where(k == 0, h_try, half)
        # the second fine step starts where the first ended
        start_q, start_p = jnp.where(fine2, qs[1], q), jnp.where(fine2, ps[1], p)
        if pin is not None:
            # the pinned positions start the step below their node value by their
            # curvature's h²/8, so that the step's ddt is the derivative at its centre
            # (.pinned.start_value): from the last two recorded means, or for the second
            # fine step from the last one and the first fine step's
            mask, (m2, m1), h_last, use = pin
            before = (jnp.where(fine2, m1, m2), jnp.where(fine2, means[1], m1))
            spans = (h_last, jnp.where(fine2, half, h_last))
            shifted = pinned_positions.start_value(start_q, before, spans, h)
            start_q = jnp.where(mask & use, shifted, start_q)
        if predict:
            dq = jnp.where(k == 0, h * vel, jnp.where(fine2, qs[0] - qs[1], half * v_fine1(qs[0])))
        else:  # each from the last velocity, the second fine step on from the first's
            dq = jnp.where(fine2, qs[1] - q, h * vel)
        guess_mu = jnp.where(fine2, mus[1], jnp.where(k == 0, mu_g, 0.5 * mu_g))
        extra = () if coarse_atol is None else (jnp.where(k == 0, coarse_atol, 0.0),)
        qk, pk, muk, okk, itk = step(modes, h, t + jnp.where(fine2, half, 0.0), start_q, start_p,
                                dq, guess_mu, *extra)  # fmt: skip
        mean = 0.5 * (start_q + qk)
        if pin is not None:
            mask, (m2, m1), h_last, use = pin
            history = (jnp.where(fine2, m1, m2), jnp.where(fine2, means[1], m1))
            sizes = (h_last, jnp.where(fine2, half, h_last), h)
            qk, _ = pinned_positions.repin(mask & use, start_q, qk, history, sizes)
        return (qs.at[k].set(qk), ps.at[k].set(pk), mus.at[k].set(muk), oks.at[k].set(okk),
                its + itk, means.at[k].set(mean))  # fmt: skip

    dtype = q.dtype
    init = (jnp.zeros((3, n), dtype), jnp.zeros((3, n), dtype), jnp.zeros((3, m), dtype),
            jnp.zeros(3, bool), jnp.asarray(0), jnp.zeros((3, n), dtype))  # fmt: skip
    qs, ps, mus, oks, its, means = jax.lax.fori_loop(0, 3, one, init)
    return (qs[0], qs[1], qs[2]), (ps[0], ps[1], ps[2]), (mus[0], mus[1], mus[2]), oks, its, means


__all__ = ["one_step", "three_steps"]
