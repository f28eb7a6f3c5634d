r"""Electromechanical transducers: gyrators between a branch charge and a flange.

``L = K φ q̇`` with ``q`` the branch charge (pins ``p``, ``n``) and ``φ`` the flange
coordinate. Linear in velocity, hence degenerate and energy-free (``E = 0``). Its
Euler–Lagrange equations give the back-emf ``V = φ_p − φ_n = K φ̇`` on the electrical
side and the force (torque) ``K i`` delivered at the flange — the coupling of the DC
motor in :func:`diracvi.problems.dc_motor`.
"""

from __future__ import annotations

from ._part import ROTATIONAL, TRANSLATIONAL, Part, finite


def _gyrator(kind, constant, name, label):
    k = finite(f"{label} {name!r}", "constant", constant)
    return Part(
        ("q", "phi"),
        lambda q, v: k * q[1] * v[0],
        name=name,
        pins=(("p", "q", 1), ("n", "q", -1)),
        flanges=(("flange", "phi", kind),),
    )


def EMF(constant, *, name: str) -> Part:
    """A rotary motor/generator coupling: torque ``K i``, back-emf ``K θ̇`` (``L = K θ q̇``)."""
    return _gyrator(ROTATIONAL, constant, name, "EMF")


def VoiceCoil(force_factor, *, name: str) -> Part:
    """A voice-coil actuator: force ``Bl·i`` on a translational flange, back-emf ``Bl·ẋ``
    (``L = Bl x q̇``). Add the coil's resistance and inductance and the moving mass as
    parts of their own."""
    return _gyrator(TRANSLATIONAL, force_factor, name, "VoiceCoil")
