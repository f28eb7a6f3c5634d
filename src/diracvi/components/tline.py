r"""SPICE's lossless transmission line ``T``: two resistive-like ports joined by a delay.

The method of characteristics (Branin 1967). With the port voltages ``v₁, v₂`` and the
currents ``i₁, i₂`` *into* the line (each at its ``+`` pin), characteristic impedance
``Z₀`` and one-way delay ``T_D``,

    v₁(t) − Z₀ i₁(t) = v₂(t − T_D) + Z₀ i₂(t − T_D),
    v₂(t) − Z₀ i₂(t) = v₁(t − T_D) + Z₀ i₁(t − T_D):

each port is a resistance ``Z₀`` in series with a source ``e₁(t) = w₂(t − T_D)``, the
*outgoing wave* ``w = v + Z₀ i`` of the other port one delay earlier. In the
Lagrange–Dirac structure a port is therefore a resistive-like port, as the controlled
sources are (:mod:`diracvi.components.controlled`): ``L = 0`` and the force

    F = −(Z₀ q̇₁ + e₁,  Z₀ q̇₂ + e₂)

on the two branch charges ``(q₁, q₂)``. ``e = (e₁, e₂)`` is known history, not a function
of a step's unknowns, whenever the step is no longer than ``T_D`` (its centre less
``T_D`` then lies before the step's start). It is a leaf of the force
(:class:`Incident`) which the driver sets before each step from the waves it recorded
(:mod:`diracvi.driver.delay`), as it sets a switch's state; the part itself knows no
history.

**Energy.** Split each port into the wave going in, ``a = (v + Z₀ i)/2 = w/2``, and the
wave coming out, ``b = (v − Z₀ i)/2 = e/2``; then ``v i = (a² − b²)/Z₀``, and
``b₁(t) = a₂(t − T_D)``. The power into the two ports is the rate of change of the
energy of the waves in flight,

    E_line(t) = (1/Z₀) ∫_{t−T_D}^{t} (a₁² + a₂²) dτ,
    dE_line/dt = (a₁² + a₂² − b₁² − b₂²)/Z₀ = v₁ i₁ + v₂ i₂.

Under the midpoint rule a step's work on the ports is ``h (Z₀ i + e)·i`` with
``i = Δq/h`` and ``e`` the step's incident value, i.e. exactly ``h Σ (a² − b²)/Z₀`` with
``a = Z₀ i + e/2`` — the identity above per step, with the step's ``a`` recorded as the
history. When ``T_D`` is a whole number ``m`` of steps the incident ``b`` of step ``k`` is
the recorded ``a`` of step ``k − m`` and the discrete power balance closes to round-off
with ``E_line = Σ_{last m steps} h (a₁² + a₂²)/Z₀``; otherwise ``b`` is interpolated and
the balance closes to the interpolation's error (``tests/test_tline.py`` checks both).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..errors import ModelError
from ._part import Part, finite, positive


class Incident(eqx.Module):
    """The incident sources ``e = (e₁, e₂)`` of a line for the step being taken (V), set by
    the driver from the other port's wave ``T_D`` earlier; ``z0`` and ``delay`` are the
    line's, read by the driver; ``coordinates`` its two branch charges."""

    e: jax.Array
    z0: float = eqx.field(static=True)
    delay: float = eqx.field(static=True)
    coordinates: tuple[str, str] = eqx.field(static=True, default=("q1", "q2"))


class _LineForce(eqx.Module):
    """``F = −(Z₀ q̇ + e)`` on the two ports' charges."""

    z0: jax.Array
    incident: Incident

    def __call__(self, q, v):
        return -(self.z0 * v + self.incident.e)


class _NoEnergy(eqx.Module):
    """``L = 0``: the line's energy is in its waves, carried by the driver."""

    def __call__(self, q, v):
        return 0.0 * v[0]


def TransmissionLine(z0, delay, *, name: str, initial=(0.0, 0.0, 0.0, 0.0)) -> Part:
    r"""A lossless line of characteristic impedance ``z0`` (Ω) and one-way ``delay`` (s).

    Pins ``p1, n1`` (port 1) and ``p2, n2`` (port 2); coordinates ``(q1, q2)``, the two
    port currents into the line at ``p1`` and ``p2`` (``i(name.1)``, ``i(name.2)``).
    ``L = 0``, ``F = −(Z₀ q̇ + e)`` with ``e`` the :class:`Incident` leaf (0 as built).
    ``initial = (v1, i1, v2, i2)``: the port values before ``t0`` (SPICE's ``IC=``,
    used under ``UIC``).
    """
    where = f"TransmissionLine {name!r}"
    z = positive(where, "z0", z0)
    td = positive(where, "delay", delay)
    if len(initial) != 4:
        raise ModelError(
            f"{where}: initial={tuple(initial)!r} must be (v1, i1, v2, i2), four numbers."
        )
    init = tuple(finite(where, "initial", x) for x in initial)
    return Part(
        ("q1", "q2"),
        _NoEnergy(),
        force=_LineForce(jnp.asarray(z, float), Incident(jnp.zeros(2), z, td)),
        name=name,
        pins=(("p1", "q1", 1), ("n1", "q1", -1), ("p2", "q2", 1), ("n2", "q2", -1)),
        role="resistor",
        parameters={
            "z0": z,
            "delay": td,
            "v1": init[0],
            "i1": init[1],
            "v2": init[2],
            "i2": init[3],
        },
    )


__all__ = ["Incident", "TransmissionLine"]
