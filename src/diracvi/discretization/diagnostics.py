r"""Per-step diagnostics of an interconnection, evaluated group by group.

``E = Σ_i E^i(q̄_i, v_i)`` and the stacked ``ω^i_{d±}`` written as a Python sum over
subsystems trace once per subsystem: a chain torn into 10⁴ pieces would compile 10⁴
copies. Subsystems that are alike (the same PyTree structure and leaf shapes — see
:func:`~diracvi.model.stacked.structure_key`) are instead stacked once and
evaluated with one ``jax.vmap``, exactly as the partitioned solver steps them.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..model.interconnect import InterconnectedSystem
from ..model.stacked import structure_key as _structure_key
from .maps import discrete_constraints, interaction_constraints

#: below this many subsystems the plain per-subsystem sum traces quickly enough
GROUPED_MIN_SUBSYSTEMS = 8


def _plain(system, rule, scheme, h):
    def one(a, b, tk=0.0, stage=None):
        energy = rule.step_energy(system.energy, a, b, h, tk, stage)
        if stage is not None:  # a staged rule: its end rows (the stage rows are internal)
            return energy, discrete_constraints(rule, system, scheme, a, b, h, tk, stage)[0]
        return energy, discrete_constraints(rule, system, scheme, a, b, h, tk)

    return one


def step_diagnostics(system, rule, scheme: str, h):
    """``(q_k, q_{k+1}, t_k, Q) ↦ (E, ω_d)`` for one step (traceable, vmappable over steps);
    ``Q`` holds the internal stages of a staged rule (``None`` otherwise)."""
    subs = getattr(system, "subsystems", ())
    if not isinstance(system, InterconnectedSystem) or len(subs) < GROUPED_MIN_SUBSYSTEMS:
        return _plain(system, rule, scheme, h)
    if system.packed:  # its own sums are vmapped group by group already
        return _plain(system, rule, scheme, h)
    offsets = np.cumsum([0] + [s.n for s in subs])
    own = np.cumsum([0] + [s.m for s in subs])
    keys: dict = {}
    for i, sub in enumerate(subs):
        keys.setdefault(_structure_key(sub), []).append(i)
    groups = []
    for members in keys.values():
        first = subs[members[0]]
        arrays = [eqx.partition(subs[i], eqx.is_array)[0] for i in members]
        stacked = None
        if len(members) > 1:  # stack leaf by leaf under the first's structure (names differ)
            leaves = zip(*(jax.tree.leaves(a) for a in arrays), strict=True)
            stacked = jax.tree.unflatten(
                jax.tree.structure(arrays[0]), [jnp.stack(xs) for xs in leaves]
            )
        rest = eqx.partition(first, eqx.is_array)[1]
        q_index = np.stack([np.arange(offsets[i], offsets[i + 1]) for i in members])
        c_index = np.stack([np.arange(own[i], own[i + 1]) for i in members])
        groups.append((members, stacked, arrays[0], rest, q_index, c_index))

    def one(a, b, tk=0.0, stage=None):
        energy = jnp.zeros((), a.dtype)
        con = jnp.zeros(system.m, a.dtype)
        for _, stacked, single, rest, q_index, c_index in groups:

            def local(arrays, x, y, s, rest=rest):
                sub = eqx.combine(arrays, rest)
                e = rule.step_energy(sub.energy, x, y, h, tk, s)
                if s is not None:
                    return e, discrete_constraints(rule, sub, scheme, x, y, h, tk, s)[0]
                return e, discrete_constraints(rule, sub, scheme, x, y, h, tk)

            s = None if stage is None else stage[q_index]
            if stacked is None:
                e, c = local(single, a[q_index[0]], b[q_index[0]], None if s is None else s[0])
                e, c = e[None], c[None]
            else:
                e, c = jax.vmap(local)(stacked, a[q_index], b[q_index], s)
            energy = energy + jnp.sum(e)
            if c_index.size:
                con = con.at[c_index.ravel()].set(c.reshape(-1))
        inter = interaction_constraints(rule, system, scheme, a, b, h, tk, stage)
        con = con.at[own[-1] :].set(inter if stage is None else inter[0])
        return energy, con

    return one
