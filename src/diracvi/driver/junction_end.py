r"""A try judged at its end: each junction's law where no step centre samples it.

The midpoint rule samples a junction's law ``f(V)`` (a diode's current, the force on its
flux linkage ``w``, whose velocity is the junction voltage ``V``) at step centres only,
and step doubling compares centres with centres: the coarse step's ``t + H/2`` against
the fine ones' ``t + H/4`` and ``t + 3H/4``. A junction that turns on in the last
quarter of a try — after the last centre — is off at all three, so the coarse and fine
steps agree and the try is accepted, with the charge the junction should have passed in
that quarter missing from its end state (a half-wave rectifier on a pulse train stepped
500 → 520 µs with its diode off at every centre, though it turns on at 517.8 µs: its
output 0.23 of its peak off; SPICE's trapezoidal rule evaluates the law at the step's
end and cuts the step there).

So each junction's law is evaluated at the try's end too, at the state the two fine
steps extrapolate to (the velocities ``v_e = v₂ + (v₂ − v₁)/2`` through their mean
velocities at ``t + H/4``, ``t + 3H/4``, the positions alike: the end velocity is not a
state of the midpoint rule), and compared with the straight line through its two centre
values, ``f_e^lin = f₂ + (f₂ − f₁)/2``. For a law smooth in time (``f = f₀ + f't + f''t²/2``)

    f(t + H) − f_e^lin = (3/32) f'' H²,

nine times the rate error of the two fine steps' quadrature of ``f`` (``f'' H²/96``: what
step doubling's Richardson estimate ``|q_f − q_c|/(3H)`` gives for the velocity the law
drives). So ``|f_e − f_e^lin|/9`` is judged as that velocity's rate error, at the same
tolerance as :func:`~.step_error.estimate`'s (``s·rtol·V + atol_v`` of the coordinate whose
velocity the junction's law sets, held to its mean over TMAX alike): where the law is
smooth the check asks no more than step doubling does, to leading order, and where the
junction turns on after the last centre (the exponential's growth unseen by any centre)
its mismatch is many orders above it and the try is cut.

The coordinate a junction drives is read from the Lagrangian: the law is the force on
``w``, and the Euler–Lagrange row of ``w``, ``d/dt ∂L/∂ẇ = ∂L/∂w + f``, sets the velocity
of the coordinate ``k`` with ``g = ∂²L/∂w∂q̇_k ≠ 0`` (a diode's ``L = w q̇``: its branch
charge, ``g = 1``, ``q̇ = −f``); a mismatch ``δf`` moves that velocity by ``δf/|g|``.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..solvers.limiting import junctions
from .step_error import over_tmax


class Pairs(NamedTuple):
    """Per junction: its coordinate, the coordinate whose velocity its law sets, and
    ``|g| = |∂²L/∂w∂q̇_k|`` (module docstring); ``None`` from :func:`pairs` without
    junctions."""

    junction: object
    driven: object
    gain: object


def pairs(system, q, t) -> Pairs | None:
    """The junctions of ``system`` and the coordinates they drive, read at ``(q, 0, t)``
    (one Jacobian-vector product of ``∂L/∂q̇`` per junction; traceable: the compiled loop
    reads them once per call, inside its program, where an eager evaluation took 1.5–5 s
    of dispatch on the corpus's transistor decks); ``None`` without junctions. A
    junction whose row is zero (no velocity it sets) gets gain ``inf``: not judged."""
    found = junctions(system)
    if found is None:
        return None
    index = np.asarray(found[0], dtype=np.int64)
    q = jnp.asarray(q, dtype=jnp.float64)
    v0 = jnp.zeros_like(q)

    def momenta(qq):
        return jax.grad(lambda v: system.lagrangian(qq, v, t))(v0)

    def row(j):
        return jax.jvp(momenta, (q,), (jnp.zeros_like(q).at[j].set(1.0),))[1]

    rows = jax.vmap(row)(jnp.asarray(index))
    driven = jnp.argmax(jnp.abs(rows), axis=1)
    gain = jnp.abs(jnp.take_along_axis(rows, driven[:, None], axis=1)[:, 0])
    gain = jnp.where(gain > 0.0, gain, jnp.inf)
    return Pairs(index, driven, gain)


def end_error(force, nodes, h_try, hmax, pair, tolerance):
    r"""The junctions' end mismatch of one try, in tolerances (module docstring):

        max_j  |f_j(x_e) − (f_j(x₂) + (f_j(x₂) − f_j(x₁))/2)| / (9 |g_j| tol_k),

    held to the mean over TMAX like a rate (``· min(1, H/hmax)``). ``force(q, v, t)`` is
    the system's force; ``nodes = (t, q, q₁, q₂)`` the try's start and its fine steps'
    ends (absolute positions); ``pair = (junction, driven, gain)`` arrays (:class:`Pairs`);
    ``tolerance``: per coordinate, ``s·rtol·V + atol_v``."""
    t, q, q1, q2 = nodes
    junction, driven, gain = pair
    half = 0.5 * h_try
    v1, v2 = (q1 - q) / half, (q2 - q1) / half
    m1, m2 = 0.5 * (q + q1), 0.5 * (q1 + q2)
    # the three evaluations as one batched one
    qs = jnp.stack([m1, m2, m2 + 0.5 * (m2 - m1)])
    vs = jnp.stack([v1, v2, v2 + 0.5 * (v2 - v1)])
    ts = t + jnp.stack([0.5 * half, 1.5 * half, h_try])
    f1, f2, fe = jax.vmap(lambda a, b, c: force(a, b, c)[junction])(qs, vs, ts)
    miss = jnp.abs(fe - (f2 + 0.5 * (f2 - f1))) / (9.0 * gain)
    e = miss / tolerance[driven]
    e = over_tmax(jnp, e, h_try, hmax)
    # a law that overflows at the extrapolated end is as far off as can be
    e = jnp.where(jnp.isnan(e), jnp.inf, e)
    return jnp.max(e, initial=0.0)


__all__ = ["Pairs", "end_error", "pairs"]
