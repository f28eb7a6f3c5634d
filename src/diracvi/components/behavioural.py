r"""A behavioural source (SPICE ``B``; ``E``/``G`` with ``VALUE=``): a nonlinear controlled port.

    V-form:  φ_p − φ_n = f(V_c, I_c, t, D)       I-form:  i = f(V_c, I_c, t, D) from p
                                                          through the source to n

with ``V_c`` voltages between pairs of nodes, ``I_c`` branch currents of other elements,
``D = (d g_k/dt)`` time derivatives of functions ``g_k(V_c, I_c, t)`` (ngspice's
``ddt``). It is :mod:`~diracvi.components.controlled`'s construction with a nonlinear
law: the controls are velocities of the part's own coordinates, the output is a force.

* each voltage ``V_c[k]`` is the velocity of the flux ``w_k`` of a sensing branch
  ``s_k`` between the pair's nodes, ``L += w_k ṡ_k`` (the branch draws no current);
* each current ``I_c[j]`` is the velocity of a pin-less ``c_j`` tied to the controlling
  element's branch charge by the circuit's row ``ċ_j − q̇_element = 0`` (its multiplier
  vanishes: no reaction on the controlling branch);
* each derivative: a pin-less position ``y_k = τ g_k`` held by the term
  ``−½ C_τ (g_k − y_k/τ)²`` in ``L`` (its ``y``-line is ``g_k = y_k/τ``, where the term
  and its derivatives in the velocities vanish), so that ``d g_k/dt = ẏ_k/τ`` — the
  construction of the MOSFET's Meyer voltages;
* the output: the V-form is a force ``F_q = −f`` on the output charge ``q`` (a
  :func:`~diracvi.components.VoltageSource` with a computed value); the I-form an
  output flux ``w_o`` with ``L += w_o q̇`` and ``F_{w_o} = −f`` (its ``w_o``-line reads
  ``q̇ = f``).

The only force is on the output, so ``⟨F, q̇⟩ = −f·q̇`` (V-form) or ``−f·ẇ_o = −f·V``
(I-form, with ``ẇ_o = φ_p − φ_n`` from the ``q``-line): minus the power the source
absorbs, which the discrete power balance accounts for like a resistor's.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..runtime.roundoff import corner_arguments, corner_rows, with_bound
from .controlled import ControlledPart

#: the default ``τ``: ``y_k`` holds ``τ·g_k``. Newton judges all positions by one norm
#: (its update must fall below ``10⁻¹³·‖q‖∞``), so ``y`` must be of the size of the
#: fluxes beside it (``V × the run's time span``) for ``g = y/τ`` to be resolved; a
#: netlist passes its TSTOP
TAU = 1.0
#: the weight ``C_τ`` of the term holding ``y_k`` (its ``y``-line reads
#: ``C_τ (g_k − y_k/τ)/τ = 0``)
HOLD = 1e-12


def BehaviouralSource(
    kind: str,
    law,
    *,
    name: str,
    pairs: int = 0,
    currents=(),
    derivatives=(),
    tau: float = TAU,
) -> ControlledPart:
    r"""A behavioural source of ``kind`` ``"V"`` or ``"I"`` (module docstring).

    Args:
        law: ``f(v, i, t, d)`` with ``v`` the ``pairs`` control voltages, ``i`` the
            controlling currents, ``d`` the derivatives (jax arrays); a scalar.
        pairs: the number of control voltages; their pins are ``c{k}p``, ``c{k}n``.
        currents: the elements whose currents ``i`` are, in order (``i(element)``).
        derivatives: functions ``g_k(v, i, t)`` whose time derivatives are ``d``.
        tau: the scale ``τ`` of the derivative positions ``y_k = τ g_k`` (seconds; about
            the run's time span, see :data:`TAU`).
    """
    if kind not in ("V", "I"):
        raise ModelError(f"BehaviouralSource {name!r}: kind={kind!r} must be 'V' or 'I'.")
    currents = tuple(str(c) for c in currents)
    derivatives = tuple(derivatives)
    out = ["q", "wo"] if kind == "I" else ["q"]
    sense = [c for k in range(pairs) for c in (f"s{k}", f"w{k}")]
    coords = (
        *out,
        *sense,
        *(f"c{j}" for j in range(len(currents))),
        *(f"y{k}" for k in range(len(derivatives))),
    )
    idx = {c: j for j, c in enumerate(coords)}
    iw = np.array([idx[f"w{k}"] for k in range(pairs)], dtype=int)
    ic = np.array([idx[f"c{j}"] for j in range(len(currents))], dtype=int)
    iy = np.array([idx[f"y{k}"] for k in range(len(derivatives))], dtype=int)
    n = len(coords)

    def controls(q, v):
        return v[iw], v[ic]

    def lagrangian(q, v, t):
        out_ = 0.0 * v[0]
        if kind == "I":
            out_ = out_ + q[1] * v[0]
        for k in range(pairs):
            out_ = out_ + q[idx[f"w{k}"]] * v[idx[f"s{k}"]]
        if derivatives:
            vc, cc = controls(q, v)
            for k, g in enumerate(derivatives):
                gap = g(vc, cc, t) - q[iy[k]] / tau
                out_ = out_ - 0.5 * HOLD * gap**2
        return out_

    def force(q, v, t):
        vc, cc = controls(q, v)
        d = v[iy] / tau
        value = jnp.asarray(law(vc, cc, t, d), dtype=v.dtype)
        f = jnp.zeros(n, dtype=v.dtype)
        return f.at[1 if kind == "I" else 0].set(-value)

    def law_roundoff(q, v, t):
        # the bound on the output current's round-off (runtime/roundoff.py): a law whose
        # terms cancel (ng_memristor's 2e12*y - 1e12*(|y+Vt| - |y-Vt|), exactly 0 below
        # the threshold) computes to u times its terms, which no step judges below
        # (per coordinate: the output flux's line, index 1, reads q̇ = f)
        vc, cc = controls(q, v)
        _, bound = with_bound(
            lambda a, b, s, e: jnp.asarray(law(a, b, s, e)), vc, cc, t, v[iy] / tau
        )
        return jnp.zeros(n, dtype=v.dtype).at[1].set(jnp.reshape(bound, ()))

    def corner_law(a, b, s, e):
        return jnp.asarray(law(a, b, s, e))

    def law_corners(q, v, dv, t):
        # the law's corners (runtime/roundoff.py: corner_rows): each argument g, how far
        # the inputs' absolute tolerances move it, and its terms
        vc, cc = controls(q, v)
        args = (vc, cc, t, v[iy] / tau)
        return corner_rows(corner_law, args, (dv[iw], dv[ic], 0.0 * t, dv[iy] / tau))

    zeros = (np.zeros(pairs), np.zeros(len(currents)), 0.0, np.zeros(len(derivatives)))
    has_corners = corner_arguments(corner_law, zeros, zeros)[0].shape[0] > 0

    pins = [("p", "q", 1), ("n", "q", -1)]
    for k in range(pairs):
        pins += [(f"c{k}p", f"s{k}", 1), (f"c{k}n", f"s{k}", -1)]
    roles = [("q", "voltage" if kind == "V" else "current")]
    roles += [(f"s{k}", "current") for k in range(pairs)]
    return ControlledPart(
        coords,
        lagrangian,
        force=force,
        name=name,
        pins=tuple(pins),
        currents=(("", "q"),),
        role="voltage" if kind == "V" else "current",
        branch_roles=tuple(roles),
        senses=tuple((f"c{j}", c) for j, c in enumerate(currents)),
        mirrors=tuple(f"y{k}" for k in range(len(derivatives))),
        pinned=tuple(f"y{k}" for k in range(len(derivatives))),
        law_roundoff=law_roundoff if kind == "I" else None,
        law_corners=law_corners if has_corners else None,
    )
