r"""The round-off of a system's forces: each part that computes a force by a law bounds it.

A :class:`~diracvi.components.ControlledPart` may carry ``law_roundoff(q, v, t=t)``: per
coordinate of the part, a bound on the absolute round-off of its force there (an I-form
behavioural source: its law's running error bound, :mod:`diracvi.runtime.roundoff`, on
its output flux ``w_o``, whose line reads ``q̇ = f``: a current). :func:`force_roundoff`
places the parts' bounds in an interconnection's coordinates. Read by Newton's test of a
residual at round-off (:meth:`~diracvi.discretization.equations.StepEquations.force_sizes`)
and by the variable-step loop's floor of the branch currents
(:mod:`diracvi.driver.roundoff`): a quantity is neither solved nor judged below its own
evaluation's round-off.

:func:`force_corners` gathers the parts' ``law_corners`` alike: the corners of their laws
(an ``abs``, a comparison), which the variable-step loop locates
(:mod:`diracvi.driver.law_corners`).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp


def law_parts(system, attribute: str = "law_roundoff") -> list:
    """``(part, offset)`` of each member of ``system`` (an interconnection, packed or not)
    with a ``law_roundoff`` (or another ``attribute``), or ``system`` itself at offset 0;
    empty where none has one."""
    if getattr(system, attribute, None) is not None:
        return [(system, 0)]
    subsystems = getattr(system, "subsystems", None)
    offsets = getattr(system, "_offsets", None)
    if subsystems is None or offsets is None:
        return []
    # a packed system's placeholders hold no arrays (the lifted bound's constants among
    # them): each such part in full
    member = getattr(system, "_member", lambda i: subsystems[i])
    return [
        (member(i), int(offsets[i]))
        for i, sub in enumerate(subsystems)
        if getattr(sub, attribute, None) is not None
    ]


def force_roundoff(system):
    """``E(q, v, t)``: per coordinate of ``system``, the bound on its force's round-off
    (0 where no part bounds it); None where no part has a bound (a static answer: the
    callers trace nothing more for such a system)."""
    found = law_parts(system)
    if not found:
        return None

    def bound(q, v, t):
        out = jnp.zeros_like(q)
        for part, start in found:
            n = part.n
            local = part.law_roundoff(q[start : start + n], v[start : start + n], t=t)
            out = out.at[start : start + n].add(jnp.abs(local))
        return out

    return bound


class Corners(eqx.Module):
    """``K(q, v, dv, t)`` of :func:`force_corners`: each part's ``law_corners`` on its
    span of the coordinates, concatenated. A Module, so that its programs (static, keyed
    by what they compute) and their constants (array leaves) split: a program built on it
    is compiled once per kind of law, not per netlist read
    (:func:`diracvi.driver.law_corners.corner_nodes`)."""

    functions: tuple
    spans: tuple = eqx.field(static=True)  # (start, n) of each part

    def __call__(self, q, v, dv, t):
        out = [
            fn(q[s : s + n], v[s : s + n], dv[s : s + n], t=t)
            for fn, (s, n) in zip(self.functions, self.spans, strict=True)
        ]
        return jnp.concatenate(out, axis=1)


def force_corners(system):
    """``K(q, v, dv, t)``: the corners of the parts' laws in ``system``'s coordinates, a
    ``(3, k)`` array — each corner's argument ``g``, the bound by which the velocities'
    absolute tolerances ``dv`` (per coordinate) move it, and its terms — gathered over
    the parts with a ``law_corners``
    (:class:`~diracvi.components.ControlledPart`), as a :class:`Corners`; None where no
    part has one."""
    found = law_parts(system, "law_corners")
    if not found:
        return None
    return Corners(
        tuple(part.law_corners for part, _ in found),
        tuple((start, part.n) for part, start in found),
    )


__all__ = ["Corners", "force_corners", "force_roundoff", "law_parts"]
