r"""The Shockley diode, ``i = I_S (e^{V/(N V_T)} − 1) + G_min V``, as a Lagrange–Dirac part.

A diode is *voltage-controlled*: its current is a function of its voltage, while a
force ``F(q, q̇)`` can only give a voltage as a function of current. The part therefore
carries, beside its branch charge ``q``, the flux linkage ``w = ∫ V dt`` of the branch
and the Lagrangian ``L = w q̇`` (linear in velocity, like a gyrator; energy ``E = 0``),
with the force ``F = (0, −g(ẇ))``. Its Euler–Lagrange equations are

    ẇ = φ_p − φ_n = V              (the q-line: d/dt ∂L/∂q̇ = ẇ equals the KCL force),
    0 = q̇ − g(ẇ)  ⇒  i = g(V)       (the w-line),

exactly the diode law, with power ``⟨F, v⟩ = −g(V) V ≤ 0`` (it dissipates). ``G_min``
(default 1e-12 S, as ngspice adds across every junction) keeps ``g`` strictly
increasing. Above ``V = 40 N V_T`` the exponential is continued linearly (C¹), so that a
Newton iterate cannot overflow; the forward currents there exceed ``I_S e^{40}``
(thousands of amperes for ``I_S = 10⁻¹⁴``), far outside any solution it is used for.
"""

from __future__ import annotations

import jax.numpy as jnp

from ._part import Part, positive

#: kT/q at ngspice's nominal 27 °C (CONSTboltz, CHARGE of ngspice's const.h)
THERMAL_VOLTAGE = 1.38064852e-23 * 300.15 / 1.6021766208e-19
_LIMIT = 40.0


def shockley_current(v, saturation_current, emission, gmin):
    """``I_S (e^{V/(N V_T)} − 1) + G_min V`` with the linear continuation above 40 N V_T."""
    nvt = emission * THERMAL_VOLTAGE
    x = v / nvt
    capped = jnp.minimum(x, _LIMIT)
    expo = jnp.exp(capped) * (1.0 + (x - capped))  # e^x, continued by its tangent
    return saturation_current * (expo - 1.0) + gmin * v


def Diode(saturation_current=1e-14, emission=1.0, *, name: str, gmin=1e-12) -> Part:
    r"""A junction diode from anode ``p`` to cathode ``n`` (SPICE ``D`` with ``IS``, ``N``).

    Coordinates ``(q, w)``: branch charge and flux linkage; see the module docstring.
    """
    where = f"Diode {name!r}"
    i_s = positive(where, "saturation_current", saturation_current)
    n = positive(where, "emission", emission)
    g = positive(where, "gmin", gmin)

    def lagrangian(q, v):
        return q[1] * v[0]

    def force(q, v):
        return jnp.stack([0.0 * v[0], -shockley_current(v[1], i_s, n, g)])

    return Part(
        ("q", "w"),
        lagrangian,
        force=force,
        name=name,
        pins=(("p", "q", 1), ("n", "q", -1)),
    )
