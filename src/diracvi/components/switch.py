r"""Switches (SPICE ``S`` and ``W``): a resistor whose resistance is a discrete state.

The branch force is a resistor's, ``F_q = −R(σ) q̇``, with ``R(1) = RON`` (closed) and
``R(0) = ROFF`` (open). The state ``σ`` is a **hysteresis relay** on a control value
``u`` (ngspice's ``sw``/``csw`` model):

    σ⁺ = 1   if u > VT + VH,
    σ⁺ = 0   if u < VT − VH,
    σ⁺ = σ   otherwise (the window keeps the previous state).

``u`` is read from the part's coordinates as the controlled sources read theirs
(:mod:`~diracvi.components.controlled`): for ``S`` through a sensing branch ``s``
between the control pins with the flux ``w`` (``L = w ṡ``: ``ẇ = φ_cp − φ_cn``, and the
sensing branch draws no current), for ``W`` as the velocity of the copy ``c`` of the
controlling source's branch charge (``ċ = i(control)``). In a discrete step ``S``'s
control is a KCL impulse, not a velocity: the midpoint rule's ``s``-line gives
``p_{s,k+1} − p_{s,k} = ½ (e_{k−1} + e_k)`` with ``e_k ≈ h_k (φ_cp − φ_cn)(t_{k+½})``
the step's own impulse (the lag of :mod:`diracvi.spice._resample`), while ``w`` itself
alternates about ``p_s``. The step-centred control is therefore
``u_{k+½} = e_k/h_k`` with ``e_k = 2 Δp_{s,k} − e_{k−1}`` (``e_{−1} = 0``), exact at
the step's centre to second order whatever the step sizes; ``Δw_k/h_k`` is not (a
change of step size excites ``w``'s alternation).

Within a step ``σ`` is a constant: each step is an ordinary discrete Dirac step of a
circuit with a resistor of value ``R(σ)``. ``σ`` is a leaf of the part
(:class:`Relay`), which the variable-step driver carries from step to step and changes
at located events (:mod:`diracvi.driver.events`). A resistive switch changes no stored
energy when it flips (the state ``q, p`` is continuous across the event; only the
dissipation law changes), so the discrete power balance holds on every step, the steps
on either side of an event included.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..errors import ModelError
from ._part import finite, positive
from .controlled import ControlledPart, _control

_OUT = (("p", "q", 1), ("n", "q", -1))
_SENSE = (("cp", "s", 1), ("cn", "s", -1))


class Relay(eqx.Module):
    r"""A hysteresis relay: the discrete state ``closed`` (1.0 closed, 0.0 open) and its
    law ``σ⁺ = 1 if u > on, 0 if u < off, σ otherwise`` (``on = VT + VH``,
    ``off = VT − VH``). ``u`` is read from the part's coordinate ``coordinate``: its
    velocity, or, when ``impulse`` is set, its momentum increments (the step's impulse,
    see the module doc)."""

    closed: jax.Array
    on: float = eqx.field(static=True)
    off: float = eqx.field(static=True)
    coordinate: str = eqx.field(static=True)
    impulse: bool = eqx.field(static=True, default=False)

    def next(self, closed, u):
        """The state after a control value ``u``, from the state ``closed``."""
        return jnp.where(u > self.on, 1.0, jnp.where(u < self.off, 0.0, closed))


class _SwitchForce(eqx.Module):
    """``F_q = −R(σ) q̇`` on the branch, 0 on the sensing coordinates."""

    r_on: jax.Array
    r_off: jax.Array
    relay: Relay

    def __call__(self, q, v):
        r = jnp.where(self.relay.closed > 0.5, self.r_on, self.r_off)
        return jnp.concatenate([-r * v[:1], 0.0 * v[1:]])


class _Gyrator(eqx.Module):
    """``L = w ṡ`` (the sensing branch of a voltage control)."""

    def __call__(self, q, v):
        return q[2] * v[1] + 0.0 * v[0]


class _Nothing(eqx.Module):
    """``L = 0`` (a current-controlled switch stores no energy)."""

    def __call__(self, q, v):
        return 0.0 * v[0] + 0.0 * q[0]


def _check(where, r_on, r_off, threshold, hysteresis):
    r_on = positive(where, "RON", r_on)
    r_off = positive(where, "ROFF", r_off)
    vt = finite(where, "threshold", threshold)
    vh = finite(where, "hysteresis", hysteresis)
    if not isinstance(vh, jax.core.Tracer) and vh < 0.0:
        raise ModelError(
            f"{where}: hysteresis={vh!r} is negative; ngspice runs a smooth transition "
            "for a negative VH/IH, which diracvi does not build: give VH ≥ 0."
        )
    return jnp.asarray(r_on, float), jnp.asarray(r_off, float), vt, vh


def VoltageSwitch(
    r_on=1.0, r_off=1e12, threshold=0.0, hysteresis=0.0, *, name: str, closed: bool = False
) -> ControlledPart:
    r"""SPICE ``S``: a resistor ``RON``/``ROFF`` between ``p`` and ``n``, closed when
    ``φ_cp − φ_cn > VT + VH``, open below ``VT − VH`` (ngspice's defaults: ``RON = 1``,
    ``ROFF = 1e12``, ``VT = VH = 0``); ``closed`` is the state before the first decision.

    Coordinates ``(q, s, w)``: branch charge, sensing branch, its flux; ``L = w ṡ``,
    ``F = (−R(σ) q̇, 0, 0)``. Pins ``p, n`` (the switch), ``cp, cn`` (the control).
    """
    where = f"VoltageSwitch {name!r}"
    r_on, r_off, vt, vh = _check(where, r_on, r_off, threshold, hysteresis)
    relay = Relay(jnp.asarray(1.0 if closed else 0.0), vt + vh, vt - vh, "s", impulse=True)
    return ControlledPart(
        ("q", "s", "w"),
        _Gyrator(),
        force=_SwitchForce(r_on, r_off, relay),
        name=name,
        pins=_OUT + _SENSE,
        currents=(("", "q"),),
        role="resistor",
        branch_roles=(("q", "resistor"), ("s", "current")),
        parameters={"threshold": vt, "hysteresis": vh},
    )


def CurrentSwitch(
    r_on=1.0,
    r_off=1e12,
    threshold=0.0,
    hysteresis=0.0,
    *,
    control: str,
    name: str,
    closed: bool = False,
) -> ControlledPart:
    r"""SPICE ``W``: a resistor ``RON``/``ROFF`` between ``p`` and ``n``, closed when
    ``i(control) > IT + IH``, open below ``IT − IH`` (``i(control)`` as for
    :func:`~diracvi.components.CCCS`; defaults as ngspice's: ``RON = 1``, ``ROFF = 1e12``,
    ``IT = IH = 0``).

    Coordinates ``(q, c)``: branch charge, the copy of the controlling charge; ``L = 0``,
    ``F = (−R(σ) q̇, 0)``. Pins ``p, n``.
    """
    where = f"CurrentSwitch {name!r}"
    r_on, r_off, it, ih = _check(where, r_on, r_off, threshold, hysteresis)
    relay = Relay(jnp.asarray(1.0 if closed else 0.0), it + ih, it - ih, "c")
    return ControlledPart(
        ("q", "c"),
        _Nothing(),
        force=_SwitchForce(r_on, r_off, relay),
        name=name,
        pins=_OUT,
        currents=(("", "q"),),
        role="resistor",
        senses=(("c", _control(where, control)),),
        parameters={"threshold": it, "hysteresis": ih},
    )
