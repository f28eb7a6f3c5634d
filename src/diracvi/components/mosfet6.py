r"""The level-6 MOSFET (Sakurai and Newton's n-th power law, SPICE ``M`` at ``LEVEL=6``,
ngspice's ``mos6``) as a Lagrange–Dirac part: level 1's structure
(:mod:`~diracvi.components._mos_part`: junctions, overlap and Meyer capacitances, RD/RS,
the source/drain swap) with level 6's drain current.

Drain current, as ngspice 39's ``mos6load`` computes it, for an NMOS-oriented device in
its forward mode (voltages times ``type``; ``V_DS ≥ 0``, else source and drain swap):

    s     = √(Φ − V_BS)  (V_BS ≤ 0),   max(0, √Φ − V_BS/(2√Φ))  else
    von   = type·VTO + γ (s − √Φ) − γ₁ V_BS − σ V_DS
    V_GON = V_GS − von;     I_D = 0 for V_GON ≤ 0                      (cutoff)
    V_DSAT = KV · V_GON^NV,   I_DSAT = KC (W/L_eff) · V_GON^NC,   λ = λ₀ − λ₁ V_BS
    I_D = I_DSAT (1 + λ V_DS)                                V_DS ≥ V_DSAT (saturation)
        = I_DSAT (1 + λ V_DS) (2 − V_DS/V_DSAT) V_DS/V_DSAT    V_DS < V_DSAT  (linear)

ngspice 39 reads NVTH and PS but its load never uses them; here too. Meyer's gate
capacitances (with ``TOX``) take this ``von`` and ``V_DSAT`` of the mode, as ``mos6load``
passes them to ``DEVqmeyer``.
"""

from __future__ import annotations

import jax.numpy as jnp

from ..errors import ModelError
from ._mos_part import KINDS, build, device, law
from ._part import positive
from .controlled import ControlledPart, coefficient


def sakurai_newton(vto, betac, kv, nv, nc, gamma, gamma1, sigma, phi, lambda0, lambda1):
    """Level 6's forward law ``(V_GS, V_DS, V_BS) -> (I_D, von, V_DSAT)`` for the NMOS-
    oriented forward mode (module docstring); ``vto`` is ``type·VTO``, ``betac`` is
    ``KC·W/L_eff`` (times ``M``)."""
    root = jnp.sqrt(phi)

    def forward(vgs, vds, vbs):
        below = jnp.sqrt(phi - jnp.minimum(vbs, 0.0))
        above = jnp.maximum(0.0, root - vbs / (2.0 * root))
        sarg = jnp.where(vbs <= 0.0, below, above)
        von = vto + gamma * (sarg - root) - gamma1 * vbs - sigma * vds
        vgon = vgs - von
        on = vgon > 0.0
        # the powers as exp(n log V_GON) on a positive stand-in off the conducting
        # branch (JAX evaluates both; a log of 0 would poison the derivatives)
        log_vgon = jnp.log(jnp.where(on, vgon, 1.0))
        vdsat = kv * jnp.exp(nv * log_vgon)
        idsat = betac * jnp.exp(nc * log_vgon)
        sat = idsat * (1.0 + (lambda0 - lambda1 * vbs) * vds)
        x = vds / vdsat
        current = jnp.where(vdsat > vds, sat * (2.0 - x) * x, sat)
        return jnp.where(on, current, 0.0 * vgon), von, jnp.where(on, vdsat, 0.0 * vgon)

    return forward


def MOSFET6(
    kind="nmos",
    vto=0.0,
    kc=5e-5,
    nc=1.0,
    kv=2.0,
    nv=0.5,
    w=100e-6,
    l=100e-6,  # noqa: E741  (SPICE's name)
    *,
    gamma=0.0,
    gamma1=0.0,
    sigma=0.0,
    phi=0.6,
    lambda0=0.0,
    lambda1=0.0,
    name: str,
    **shared,
) -> ControlledPart:
    r"""A level-6 MOSFET with pins ``d g s b`` (defaults as ngspice 39's ``mos6set``:
    ``VTO = 0``, ``KC = 5e-5`` A/V^NC, ``NC = 1``, ``KV = 2`` V, ``NV = 0.5``, ``γ = γ₁ = σ
    = λ₀ = λ₁ = 0``, ``Φ = 0.6`` V, ``W = L = 100 µm``).

    The law is the module docstring's; ``shared`` are the keywords every level takes, as
    :func:`~diracvi.components.MOSFET`'s (``cox`` = ``ε_ox/TOX`` gives Meyer's
    capacitances). ``vto``, ``kc``, ``nc``, ``kv``, ``nv``, ``gamma``, ``gamma1``,
    ``sigma``, ``lambda0`` and ``lambda1`` may be traced JAX values.
    """
    dev = device("MOSFET6", kind, w, l, name, shared)
    where = dev.where
    card = {
        k: coefficient(where, k, x)
        for k, x in (("vto", vto), ("kc", kc), ("nc", nc), ("kv", kv), ("nv", nv),
                     ("gamma", gamma), ("gamma1", gamma1), ("sigma", sigma),
                     ("lambda0", lambda0), ("lambda1", lambda1))
    }  # fmt: skip
    if isinstance(card["kv"], float) and card["kv"] <= 0.0:
        raise ModelError(f"{where}: kv={kv!r} must be > 0 (V_DSAT = KV·V_GON^NV).")
    phi = positive(where, "phi", phi)
    # the law as data (its numbers a vector): devices of other sizes share one program
    betac = card["kc"] * dev.mult * dev.width / dev.leff
    forward = law(
        sakurai_newton, vto=KINDS[kind] * card["vto"], betac=betac, kv=card["kv"],
        nv=card["nv"], nc=card["nc"], gamma=card["gamma"], gamma1=card["gamma1"],
        sigma=card["sigma"], phi=phi, lambda0=card["lambda0"], lambda1=card["lambda1"],
    )  # fmt: skip
    return build(dev, forward, phi, card | {"phi": phi})
