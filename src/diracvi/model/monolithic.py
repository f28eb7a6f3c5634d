r"""``InterconnectedSystem.monolithic()``: the single system ``(Σ L^i, (⊕Δ_i) ∩ Σ, Σ π_i^* F_i)``
on the interconnection's coordinates, for checking the paper's theorem (interconnected
equations = the monolithic system's)."""

from __future__ import annotations

import jax.numpy as jnp

from ..errors import ModelError
from .system import LagrangeDiracSystem, with_row_order


def monolithic(system) -> LagrangeDiracSystem:
    r"""The single system ``(Σ L^i, (⊕Δ_i) ∩ Σ, Σ π_i^* F_i)`` on the same coordinates.

    Its one-forms are the stacked ``[⊕A_i; B]`` (with the subsystems' affine terms),
    its holonomic constraints the stacked ``g_i``, its rows in the interconnection's
    order, and its step equations are formed by differentiating the summed discrete
    Lagrangian in one piece — a different computation from the per-subsystem
    assembly, which is what makes the comparison a check of the paper's theorem.
    """
    subsystems, split = system._members(), system._split
    ported = [s.name for s in subsystems if hasattr(type(s), "discrete_momenta")]
    if ported:  # their momenta are not ∂L/∂v: Σ L^i would drop their own terms
        raise ModelError(
            f"monolithic(): subsystems {ported} give their own discrete momenta (a charge "
            "port, a charge that is no Lagrangian's momentum), which Σ L^i cannot express; "
            "simulate the interconnection itself."
        )
    timed = system.time_dependent

    def lagrangian(q, v, t=0.0):
        return sum(
            s.lagrangian(a, b, t) for s, a, b in zip(subsystems, split(q), split(v), strict=True)
        )

    mask = system.holonomic_mask
    m_forms = mask.count(False)
    q_probe = jnp.zeros(system.n)
    with_offset = system.constraint_offset(q_probe) is not None
    forms, offset, held, force = (
        system.one_forms,
        system.constraint_offset,
        system.position_constraints,
        system.force,
    )
    if timed:  # the driven forms take t; autonomous ones keep the two-argument form
        parts = dict(
            lagrangian=lambda q, v, t: lagrangian(q, v, t),
            constraints=lambda q, t: forms(q, t),
            constraint_offset=lambda q, t: offset(q, t),
            holonomic=lambda q, t: held(q, t),
            force=lambda q, v, t: force(q, v, t),
        )
    else:
        parts = dict(
            lagrangian=lambda q, v: lagrangian(q, v),
            constraints=lambda q: forms(q),
            constraint_offset=lambda q: offset(q),
            holonomic=lambda q: held(q),
            force=lambda q, v: force(q, v),
        )
    names = system.constraint_names
    mono = LagrangeDiracSystem(
        system.coords,
        parts["lagrangian"],
        constraints=parts["constraints"] if m_forms else None,
        force=parts["force"] if system.has_force else None,
        name=system.name,
        constraint_names=[c for c, h in zip(names, mask, strict=True) if not h] or None,
        constraint_offset=parts["constraint_offset"] if with_offset else None,
        holonomic=parts["holonomic"] if any(mask) else None,
        holonomic_names=[c for c, h in zip(names, mask, strict=True) if h] or None,
    )
    if any(mask):
        # keep the interconnection's row order: its j-th row is the monolithic
        # system's next one-form row, or (holonomic) its next g row after all forms
        forms_seen, held_seen, order = 0, 0, []
        for flag in mask:
            order.append(m_forms + held_seen if flag else forms_seen)
            held_seen += flag
            forms_seen += not flag
        mono = with_row_order(mono, order, names)
    return mono
