r"""The discrete Dirac equations of a staged rule (``"lobatto"``), checked on a trajectory.

A staged rule's step ``(q_k, p_k) → (q_{k+1}, p_{k+1})`` is a two-point discrete Dirac
relation once its internal stages are eliminated: with ``S`` the stage positions and
``ν`` their multipliers (see :class:`~diracvi.discretization.rules.Lobatto`), the (+) relation is

    p_k     = −D_{q_k}L_d − f_d^− − r_k(μ, ν)      (the known end's momentum line)
    0       =  D_S L_d + f_S + r_S(μ, ν)            (stage lines)
    0       =  c_a, c_b                             (stage rows of the one-forms)
    0       =  c_end                                (the new end's rows, ω_{d+})
    p_{k+1} =  D_{q_{k+1}}L_d + f_d^+ + r_{k+1}(μ, ν)

where the reactions ``r`` are the stage one-forms ``A(Q_j)ᵀ`` pulled back to the step's
variables: the stage-reduced analogue of ``P⁻ − p_k ∈ Δ°(q_k)``. A trajectory does not
store ``(μ, S, ν)``, so they are *re-solved* from the stored ``(q_k, p_k, q_{k+1})``: the
first three lines are ``n + 2n + 2m`` equations in the ``m + 2n + 2m`` unknowns
``(μ, S, ν)``, solved by Gauss–Newton (least squares, as the two-point diagnostic's
multipliers are). What is left is the residual:

- ``fiber``: the least-squares residual of those lines — the part of the momentum
  mismatch that no reaction explains (zero for a trajectory of the rule);
- ``constraint``: ``c_end`` at the re-solved stages;
- ``base``: ``p_{k+1} − (D_{q_{k+1}}L_d + f_d^+ + r_{k+1})``, the new end's momentum.

The (−) relation is the same with the roles of the ends exchanged.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.equations import first_guess, new_momentum, residual

#: Gauss–Newton iterations: the stage equations are close to linear at a trajectory's
#: data (the starting stages are O(h) off), so a handful reach round-off
ITERATIONS = 8


def staged_parts(system, rule, side: str, h: float, q0, p0, q1, p1, tk) -> dict:
    """``{constraint, base, fiber, multipliers}`` of every step (arrays over steps)."""
    arrays = (jnp.asarray(a) for a in (q0, p0, q1, p1, tk))
    constraint, base, fiber, mu = (np.asarray(a) for a in _batched(system, rule, side, h, *arrays))
    return {"constraint": constraint, "base": base, "fiber": fiber, "multipliers": mu}


@eqx.filter_jit  # one compilation per system, rule, side, h and number of steps
def _batched(system, rule, side, h, q0, p0, q1, p1, tk):
    n, m = int(system.n), int(system.m)

    def one(qk, pk, qk1, pk1, t):
        known, p_known, other, p_new = (qk, pk, qk1, pk1) if side == "plus" else (qk1, pk1, qk, pk)

        def step_x(z):
            return jnp.concatenate([other, z])

        def lines(z):  # momentum line, stage lines, stage rows (without c_end)
            r = residual(system, rule, side, h, known, p_known, step_x(z), t)
            return jnp.concatenate([r[:n], r[n + m :]])

        z = first_guess(system, rule, known, other, jnp.zeros(m, qk.dtype))[n:]
        for _ in range(ITERATIONS):
            z = z + jnp.linalg.lstsq(jax.jacfwd(lines)(z), -lines(z))[0]
        r = residual(system, rule, side, h, known, p_known, step_x(z), t)
        base = new_momentum(system, rule, side, h, known, step_x(z), t) - p_new
        return r[n : n + m], base, jnp.concatenate([r[:n], r[n + m :]]), z[:m]

    return jax.vmap(one)(q0, p0, q1, p1, tk)
