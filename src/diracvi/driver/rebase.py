r"""Growing coordinates stepped from zero: each step solved relative to its start.

A coordinate ``j`` on which the Lagrangian depends only through a term linear in it
and in the velocities,

    L(q, v, t) = q_j (a_j · v) + L'(q without q_j, v, t),

and on which neither the force ``F`` nor a constraint row depends — a source's or a
resistor's charge (``a_j = 0``: cyclic), a sensing branch's flux ``w`` of a controlled
or behavioural source (``L = w ṡ``, ``a_j = e_s``), a diode's flux without junction
charge — is fixed by the equations only up to a constant: ``q_j → q_j + W`` changes
``L`` by ``W a_j · v``, a total time derivative, whose discrete counterpart
``W a_j · (q_{k+1} − q_k)`` adds ``W a_j`` to every momentum and leaves the step's
equations as they are. Such coordinates grow over a run (a flux ``∫ 15 V dt``, a
supply's charge), and in floating point a step that solves for ``q_{j,k+1}`` resolves
it only to ``ulp(q_j)``: its velocity ``Δq_j/h`` — a sensed voltage, a current — and the
multipliers the step reads from ``p − D₁L_d`` (differences of two ``O(q_j)`` numbers)
are off by ``~ulp(q_j)/h``, an error that grows with the run and as the step shrinks
(``xy_sandler1``: a node at 0 V in exact arithmetic read 3.2 µV at the 22 ps steps of its
input's edge, EBAL's flux ``w`` being 1.5e-2 V·s by then).

So the variable-step loop solves every try in the gauge of its start: the base ``W``
= the start's values of those coordinates, the step from ``q − W`` (zero there) with
the momentum ``p̃ = p − G q`` (``G = Σ_j a_j e_jᵀ``, the constant ``∂²L/∂v∂q_j``
columns): the momentum of that gauge at its own start. The step's unknowns, its
velocities, multipliers and the error estimate's differences are then all formed from
numbers of the size of one step's increments, resolved to their own ulps. The carried
state is the positions ``W + Δq`` (rounded: they enter no velocity) and the gauge
momentum ``p̃ = p_end − G Δq`` of the new start, formed from the increments alone; the
recorded momenta are ``p = p̃ + G q``. In exact arithmetic every step is the same step:
nothing but round-off changes.

Which coordinates qualify is read from the system by autodiff at random points, as
:mod:`.algebraic` reads its own (an exact zero means no dependence):
``∂²L/∂q_j∂q = 0``, ``∂L/∂q_j = 0`` at ``v = 0``, ``∂²L/∂q_j∂v`` the same everywhere,
``∂F/∂q_j = 0``, and no constraint row or holonomic constraint reads ``q_j``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..runtime.compile import run_once_jit

#: random points at which the derivatives are probed
_PROBES = 3


def _dldq(system, q, v, t):
    return jax.grad(lambda a: system.lagrangian(a, v, t))(q)


def _probe(system, q, v, t, mu):
    """The derivatives :func:`rebase_map` reads, at one point."""
    n = system.n
    hqq = jax.jacfwd(lambda a: _dldq(system, a, v, t))(q)  # (i, j) = ∂²L/∂q_i∂q_j
    hqv = jax.jacfwd(lambda b: _dldq(system, q, b, t))(v)  # (j, i) = ∂²L/∂q_j∂v_i
    at_rest = _dldq(system, q, jnp.zeros_like(v), t)
    out = [hqq, hqv, at_rest]
    if system.has_force:
        out.append(jax.jacfwd(lambda a: system.force(a, v, t))(q))
    else:
        out.append(jnp.zeros((n, n)))
    if system.m:
        out.append(jax.jacfwd(lambda a: system.multiplier_force(a, mu, t))(q))
    else:
        out.append(jnp.zeros((n, n)))
    if system.has_offset:
        out.append(jax.jacfwd(lambda a: system.constraint_offset(a, t))(q))
    else:
        out.append(jnp.zeros((1, n)))
    if system.has_holonomic:
        out.append(jax.jacfwd(lambda a: system.position_constraints(a, t))(q))
    else:
        out.append(jnp.zeros((1, n)))
    return tuple(out)


@run_once_jit
def _probes(system, qs, vs, ts, mus):
    """:func:`_probe` at each of the points: one program per system's structure, kept
    (a closure traced afresh at every run cost ~0.15 CPU s a call on the bridge
    rectifier, more than its compiled loop's steps)."""
    return jax.vmap(lambda q, v, t, mu: _probe(system, q, v, t, mu))(qs, vs, ts, mus)


def rebase_map(system, q0, t0=0.0, seed=1):
    """``(mask, G)``: a boolean per coordinate (the coordinates stepped from zero,
    module docstring) and the ``(n, n)`` matrix ``G`` whose column ``j`` is ``a_j =
    ∂²L/∂v∂q_j`` for those (zero for the others): ``p̃ = p − G q``."""
    n, m = system.n, system.m
    q0 = np.asarray(q0, dtype=np.float64)
    rng = np.random.default_rng(seed)
    scale = np.maximum(np.abs(q0), 1.0)

    qs = q0 + 1e-3 * scale * rng.standard_normal((_PROBES, n))
    vs = rng.standard_normal((_PROBES, n))
    ts = t0 + rng.uniform(0.0, 1.0, _PROBES)
    mus = rng.standard_normal((_PROBES, m))
    hqq, hqv, at_rest, df, da, db, dg = (np.asarray(a) for a in _probes(system, qs, vs, ts, mus))
    free = np.all(hqq == 0.0, axis=(0, 1))  # column j of ∂²L/∂q∂q
    free &= np.all(hqv == hqv[:1], axis=(0, 2))  # ∂²L/∂q_j∂v the same everywhere
    free &= np.all(at_rest == 0.0, axis=0)
    for jac in (df, da, db, dg):
        free &= np.all(jac == 0.0, axis=(0, 1))
    g = np.where(free[None, :], hqv[0].T, 0.0)  # column j: a_j = ∂²L/∂v∂q_j
    return free, g


__all__ = ["rebase_map"]
