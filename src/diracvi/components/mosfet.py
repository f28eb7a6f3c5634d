r"""The level-1 MOSFET (Shichman–Hodges, SPICE ``M`` at ``LEVEL=1``) as a Lagrange–Dirac part.

The part's structure below is :mod:`~diracvi.components._mos_part`'s, shared with level 6
(:mod:`~diracvi.components.mosfet6`); this module gives level 1's law to it.

Drain current, as ngspice's level 1 computes it (voltages multiplied by ``type`` = +1
for NMOS, −1 for PMOS, so that both read as an NMOS; ``β = KP·W/L_eff``,
``L_eff = L − 2 LD``):

    von  = type·VTO + γ (s − √Φ),  s = √(Φ − V_BS)  (V_BS ≤ 0),  max(0, √Φ − V_BS/(2√Φ)) else
    I_D  = 0                                        V_GS − von ≤ 0         (cutoff)
         = β (1 + λ V_DS) (V_GS − von)²/2           0 < V_GS − von ≤ V_DS  (saturation)
         = β (1 + λ V_DS) V_DS (V_GS − von − V_DS/2)  otherwise            (linear)

For ``V_DS < 0`` source and drain swap roles (``V_GD``, ``V_BD``, ``−V_DS`` in the formula,
and the current reverses). The bulk–drain and bulk–source junctions are diodes with
``I_S`` (ngspice's constant ``−I_S`` below ``−3 V_T``) plus ``G_min`` across each, as ngspice
adds. The gate draws no DC current.

**Lagrange–Dirac form** (as the controlled sources, :mod:`~diracvi.components.controlled`):
the channel is a voltage-controlled current, so it carries a branch charge ``q`` (drain
to source) and a flux ``w`` with ``L = w q̇`` and the force ``F_w = −I_D(ẇ_g, ẇ, ẇ_bs)``;
the gate voltage is the velocity of the flux ``w_g`` of a sensing branch ``s_g`` (gate to
source, ``L = w_g ṡ_g``, no force: it draws no current); the junctions are diode branches
``q_bs``, ``q_bd`` with fluxes ``w_bs``, ``w_bd`` (``ẇ_bs = V_BS``). The power of the forces,
``⟨F, q̇⟩ = −I_D V_DS − I_BS V_BS − I_BD V_BD``, is minus the power the device dissipates.
Optional overlap capacitances ``CGSO·W``, ``CGDO·W``, ``CGBO·L_eff`` are linear capacitors
in the flux form, ``L += ½ C ẇ²`` on the gate–source sense branch and on gate–drain and
gate–bulk branches; the bulk junctions' depletion charges (bottom and sidewall, ngspice's
``FC`` continuation) are co-energies of ``ẇ_bs``, ``ẇ_bd``. ``RD``, ``RS`` > 0 are resistor
branches (``F = −R q̇``) to internal nodes ``d′``, ``s′`` (the part's own KCL rows), which
the channel, the junctions and the gate branches then join, as in ngspice.

**Meyer's gate capacitances** (``cox`` > 0; :mod:`~diracvi.components._mos1`) have no
co-energy (``∂C_GS/∂V_GD ≠ ∂C_GD/∂V_GS``): each gate branch ``x`` gets a position
``y_x = τ V_x`` tied to its flux velocity by ``−½ C_ox (ẇ_x − y_x/τ)²`` in ``L`` (the
``y``-line is ``ẇ_x = y_x/τ``, where the term vanishes) and the force ``F_w = −C_x(y/τ)
ẏ_x/τ``: a port whose current is ``C_x(V) dV_x/dt``, its work ``Σ_x V_x i_x`` neither
stored nor dissipated (docs/circuits.md, "Transistors").
"""

from __future__ import annotations

import jax.numpy as jnp

from ._mos_part import KINDS, TAU, build, channel_current, device, gate_capacitances, law
from ._part import positive
from .controlled import ControlledPart, coefficient

__all__ = ["KINDS", "MOSFET", "TAU", "drain_current", "meyer_capacitances", "threshold"]


def threshold(vbs, vto, gamma, phi):
    """``von = type·VTO + γ (s − √Φ)`` of the module docstring (NMOS-oriented ``vbs``)."""
    root = jnp.sqrt(phi)
    below = jnp.sqrt(phi - jnp.minimum(vbs, 0.0))
    above = jnp.maximum(0.0, root - vbs / (2.0 * root))
    sarg = jnp.where(vbs <= 0.0, below, above)
    return vto + gamma * (sarg - root)


def shichman_hodges(vgs, vds, vbs, vto, beta, gamma, phi, lambda_):
    r"""``I_D`` of an NMOS-oriented device in forward mode (``V_DS ≥ 0``); ``vto`` is
    ``type·VTO``. See the module docstring."""
    vgst = vgs - threshold(vbs, vto, gamma, phi)
    betap = beta * (1.0 + lambda_ * vds)
    saturation = 0.5 * betap * vgst * vgst
    linear = betap * vds * (vgst - 0.5 * vds)
    on = jnp.where(vgst <= vds, saturation, linear)
    return jnp.where(vgst <= 0.0, 0.0 * vgst, on)


def level1(vto, beta, gamma, phi, lambda_):
    """Level 1's forward law ``(V_GS, V_DS, V_BS) -> (I_D, von, vdsat)`` (``vto`` is
    ``type·VTO``): ngspice's ``mos1load`` passes Meyer ``vdsat = max(V_GS − von, 0)``."""

    def forward(vgs, vds, vbs):
        von = threshold(vbs, vto, gamma, phi)
        i = shichman_hodges(vgs, vds, vbs, vto, beta, gamma, phi, lambda_)
        return i, von, jnp.maximum(vgs - von, 0.0)

    return forward


def drain_current(vgs, vds, vbs, *, kind, vto, beta, gamma, phi, lambda_):
    """The channel current into the drain, through the channel, out of the source, for the
    true (signed) terminal voltages: polarity by ``kind``, source/drain swap for
    ``V_DS < 0``."""
    sign = KINDS[kind]
    law = level1(sign * vto, beta, gamma, phi, lambda_)
    return channel_current(vgs, vds, vbs, sign, law)


def meyer_capacitances(vgs, vgd, vgb, *, kind, vto, gamma, phi, cox):
    """Meyer's ``(C_GS, C_GD, C_GB)`` of level 1 at the true terminal voltages (``cox`` =
    ``C'_ox W L_eff``; :func:`~diracvi.components._mos_part.gate_capacitances`)."""
    sign = KINDS[kind]
    law = level1(sign * vto, 0.0, gamma, phi, 0.0)
    return gate_capacitances(vgs, vgd, vgb, sign, law, phi, cox)


def MOSFET(
    kind="nmos",
    vto=0.0,
    kp=2e-5,
    lambda_=0.0,
    w=100e-6,
    l=100e-6,  # noqa: E741  (SPICE's name)
    gamma=0.0,
    phi=0.6,
    *,
    name: str,
    **shared,
) -> ControlledPart:
    r"""A level-1 MOSFET with pins ``d g s b`` (SPICE ``M``; defaults as ngspice's manual:
    ``VTO = 0``, ``KP = 2e-5`` A/V², ``λ = 0``, ``γ = 0``, ``Φ = 0.6`` V, ``W = L = 100 µm``).

    ``kind`` is ``"nmos"`` or ``"pmos"``. ``vto``, ``kp``, ``lambda_`` and ``gamma`` may be
    traced JAX values (``jax.grad`` reaches them).

    ``shared``: the keywords every level takes (:data:`~diracvi.components._mos_part.SHARED`
    holds them with ngspice's defaults): ``ld`` (the lateral diffusion, ``L_eff = L −
    2 LD``), ``m`` the parallel multiplier, ``is_`` (``1e-14`` A, or a pair: bulk–drain,
    bulk–source), ``cgso``, ``cgdo``, ``cgbo`` the overlap capacitances per width and
    length, ``cox`` the oxide capacitance per area ``ε_ox/TOX`` (F/m²; 0: no Meyer
    capacitances), ``rd``, ``rs`` the drain and source resistances (Ω, 0: none), ``cbd``,
    ``cbs`` the bulk junctions' zero-bias bottom capacitances and ``cbdsw``, ``cbssw``
    their sidewall ones (F, graded by ``mj`` and ``mjsw``, ``pb = 0.8`` V, ``mj = mjsw =
    fc = 0.5``), all before ``m``, ``gmin`` across each junction, ``emission`` (1: the bulk
    junctions' ``V_T`` is 27 °C's; ``V_T(T)/V_T(27 °C)`` for a device at ``T``), and
    ``v0 = (V_GS, V_GD, V_GB)``: the initial gate voltages (the overlap capacitors'
    charges and Meyer's voltage coordinates); see the module docstring for the coordinates.
    """
    dev = device("MOSFET", kind, w, l, name, shared)
    where = dev.where
    vto = coefficient(where, "vto", vto)
    kp = coefficient(where, "kp", kp)
    lambda_ = coefficient(where, "lambda_", lambda_)
    gamma = coefficient(where, "gamma", gamma)
    phi = positive(where, "phi", phi)
    beta = kp * dev.mult * dev.width / dev.leff
    # the law as data (its numbers a vector): devices of other sizes share one program
    forward = law(level1, vto=KINDS[kind] * vto, beta=beta, gamma=gamma, phi=phi, lambda_=lambda_)
    params = {"kp": kp, "vto": vto, "lambda": lambda_, "gamma": gamma, "phi": phi}
    return build(dev, forward, phi, params)
