r"""A DC motor's electromechanical coupling across a revolute joint of a :class:`Multibody`.

The part is the 1-D :func:`~diracvi.components.EMF` gyrator on its own shaft angle
``θ_m``, tied to the joint by one nonholonomic one-form::

    L = K θ_m q̇                                   (q the branch charge, pins p and n)
    θ̇_m − e₃·(ω_b − ω_a) = 0,   ω = ½ Σᵢ dᵢ × ḋᵢ   (the shaft turns with the joint)

with ``e₃`` the joint's axis (frame a's third axis in world axes) and ``ω_a``, ``ω_b``
the angular velocities of the stator's and the rotor's bodies from their directors. The
gyrator gives the back-emf ``K θ̇_m = K e₃·ω_rel`` between the pins and the torque
``K i`` on the shaft; the one-form's reaction carries that torque to the bodies as
``+K i e₃`` on the rotor and ``−K i e₃`` on the stator — the covector
``(0, ½ τ × d₁, ½ τ × d₂, ½ τ × d₃)`` of a pure torque, since the row's coefficient on
``ḋᵢ`` is ``∓½ e₃ × dᵢ``. Nothing else acts: no torque across the axis, no force.

Why this form and not ``L = −K q (e₃·ω_rel)`` on the directors: on the joint manifold
``e₃·ω_rel = θ̇`` (the joint angle), so that Lagrangian equals the EMF's ``K θ q̇`` up to
the total derivative ``d/dt(K θ q)`` and gives the same motion. But its Euler–Lagrange
equations on the directors also carry ``K q ω_a × e₃`` — a torque across the axis, equal
and opposite on the two bodies, absorbed by the joint's reaction (a changed multiplier),
and cubic in the coordinates (``q``, ``dᵢ``, ``ḋᵢ``). The one-form keeps the EMF's
bilinear Lagrangian (stores no energy, ``E = 0``) and puts the torque exactly along the
axis; its reaction does no work on any velocity the row allows (``λ A v = 0``).

A rotor inertia ``J_m`` adds ``½ J_m θ̇_m²`` to the part's Lagrangian: the shaft's
momentum ``J_m θ̇_m`` is then the rotor's, and the row's reaction carries ``J_m θ̈_m`` to
the two bodies as it carries ``K i`` — the joint's inertia grows by ``J_m`` (the rotor's
moment about its own axis only: its mass and its moments across the axis belong to the
stator's body). It stores ``½ J_m θ̇_m²``, the rotor's kinetic energy on the joint's
relative rate — MuJoCo's joint ``armature``; the stator's own turning about the axis is
left out, as in the reflected inertia of a geared rotor.

Only ``θ̇_m`` enters the equations (``K θ_m q̇`` changes by a total derivative when
``θ_m`` is shifted), so ``θ_m`` starts at 0 and need not equal the joint angle. The part's
coordinates are ``(q, theta, <body>_<x, y, z, d1x, …>)``: massless copies of the
bodies' coordinates, joined to the bodies by :func:`~diracvi.connect` when
:meth:`Multibody.build` is given the circuit (:func:`join_circuit`).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.interaction import connect
from ..model.interconnect import interconnect
from ._part import Part, finite, traced
from .rigid_body import COORDS


def _axis(frame, q):
    """World third axis ``e₃`` of a joint frame on a body with coordinates ``q``."""
    if frame.body is None:
        return jnp.asarray(frame.axes)[:, 2]
    return q[3:12].reshape(3, 3).T @ jnp.asarray(frame.axes)[:, 2]


def _spin_row(q, e3):
    """Coefficients of ``e₃·ω`` on one body's 12 velocities: ``e₃·(½ Σ dᵢ × ḋᵢ) =
    Σ ḋᵢ·(½ e₃ × dᵢ)`` (nothing on the reference point's velocity)."""
    d = q[3:12].reshape(3, 3)
    return jnp.concatenate([jnp.zeros(3), (0.5 * jnp.cross(e3[None, :], d)).reshape(9)])


class MotorLink:
    """What the motor part needs of its joint: the two frames and their bodies."""

    def __init__(self, joint: str, a, b):
        self.joint, self.a, self.b = joint, a, b
        self.bodies = tuple(dict.fromkeys(f.body for f in (a, b) if f.body is not None))

    def form(self, x):
        """The row ``(0, 1, −coefficients of e₃·(ω_b − ω_a))`` on ``(q, θ, copies…)``."""
        qs = {b: x[2 + 12 * i : 14 + 12 * i] for i, b in enumerate(self.bodies)}
        e3 = _axis(self.a, qs.get(self.a.body))
        parts = [jnp.array([0.0, 1.0])]
        for body in self.bodies:
            sign = (body == self.b.body) - (body == self.a.body)  # rotor +, stator −
            parts.append(-float(sign) * _spin_row(qs[body], e3))
        return jnp.concatenate(parts)[None, :]

    def rate(self, states: dict) -> float:
        """``e₃·(ω_b − ω_a)`` at the bodies' initial ``{body: (q, v)}``."""
        x = np.concatenate([[0.0, 0.0], *(states[b][0] for b in self.bodies)])
        v = np.concatenate([[0.0, 0.0], *(states[b][1] for b in self.bodies)])
        return float(-(np.asarray(self.form(jnp.asarray(x)))[0] @ v))


def motor_part(constant, link: MotorLink, states: dict, name: str, inertia=0.0) -> Part:
    r"""The motor part: ``L = K θ q̇ + ½ J_m θ̇²`` and the row ``θ̇ − e₃·(ω_b − ω_a) = 0``
    (module docstring), its copies starting at the bodies' initial ``states``
    (``{body: (q, v)}``). ``J_m`` (``inertia``, kg m², ≥ 0) is the rotor's moment about its
    shaft: it rides on the shaft angle, so the row carries its reaction ``J_m θ̈`` to the
    joint like the torque ``K i``, and the joint sees ``J_m`` added to its inertia."""
    where = f"Multibody.motor({name!r})"
    k = finite(where, "constant", constant)
    jm = finite(where, "inertia", inertia)
    if not traced(jm) and jm < 0.0:
        raise ModelError(
            f"{where}: inertia={inertia!r} is negative; give the rotor's moment about its "
            "shaft in kg m² (≥ 0, 0 for none)."
        )
    coords = ("q", "theta", *(f"{b}_{c}" for b in link.bodies for c in COORDS))
    q0 = np.concatenate([[0.0, 0.0], *(states[b][0] for b in link.bodies)])
    v0 = np.concatenate([[0.0, link.rate(states)], *(states[b][1] for b in link.bodies)])
    return Part(
        coords,
        (lambda q, v: k * q[1] * v[0] + 0.5 * jm * v[1] ** 2)
        if traced(jm) or jm != 0.0
        else (lambda q, v: k * q[1] * v[0]),  # no J_m: the Lagrangian stays bilinear
        name=name,
        pins=(("p", "q", 1), ("n", "q", -1)),
        initial_q=q0,
        initial_v=v0,
        parameters={"constant": k, "inertia": jm},
        constraints=link.form,
        constraint_names=("shaft",),
    )


def join_circuit(model, mb_name: str, circuit, motors: dict):
    r"""The bodies' system and the circuit's, joined: each motor's copies ``dq_copy −
    dq_body`` (constant one-forms, kept exactly at position level by every step).
    Returns ``model`` with the joined system and state and ``circuit`` set."""
    names = {p.name for p in circuit.parts}
    missing = sorted(set(motors) - names)
    if missing:
        raise ModelError(
            f"Multibody {mb_name!r}: motors {missing} are not in circuit {circuit.name!r}; "
            f"add each to it, circuit.add(motor, p=…, n=…)."
        )
    if circuit.name == mb_name:
        raise ModelError(
            f"Multibody.build(circuit=…): the circuit and the multibody are both named "
            f"{mb_name!r}; give them different names (they prefix the coordinates)."
        )
    assembly = circuit.build()
    if not hasattr(assembly.system, "subsystems"):
        raise ModelError(
            f"circuit {circuit.name!r} holds only its motor; close the motor's loop with "
            "a source or a resistor."
        )
    links = [
        connect(f"{mb_name}.{b}.{c}", f"{circuit.name}.{name}.{b}_{c}")
        for name, link in motors.items()
        for b in link.bodies
        for c in COORDS
    ]
    system = interconnect([model.system, assembly.system], links, name=mb_name)
    return dataclasses.replace(
        model,
        system=system,
        q0=np.concatenate([model.q0, assembly.q0]),
        p0=np.concatenate([model.p0, assembly.p0]),
        circuit=assembly,
        circuit_name=circuit.name,
    )


__all__ = ["MotorLink", "join_circuit", "motor_part"]
