r"""The level-1 MOSFET (Shichman–Hodges, SPICE ``M`` at ``LEVEL=1``) as a Lagrange–Dirac part.

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
gate–bulk branches; Meyer's bias-dependent gate capacitances are not modelled.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._junction import pn_current
from ._part import finite, positive
from .controlled import ControlledPart, coefficient

KINDS = {"nmos": 1.0, "pmos": -1.0}


def shichman_hodges(vgs, vds, vbs, vto, beta, gamma, phi, lambda_):
    r"""``I_D`` of an NMOS-oriented device in forward mode (``V_DS ≥ 0``); ``vto`` is
    ``type·VTO``. See the module docstring."""
    root = jnp.sqrt(phi)
    below = jnp.sqrt(phi - jnp.minimum(vbs, 0.0))
    above = jnp.maximum(0.0, root - vbs / (2.0 * root))
    sarg = jnp.where(vbs <= 0.0, below, above)
    von = vto + gamma * (sarg - root)
    vgst = vgs - von
    betap = beta * (1.0 + lambda_ * vds)
    saturation = 0.5 * betap * vgst * vgst
    linear = betap * vds * (vgst - 0.5 * vds)
    on = jnp.where(vgst <= vds, saturation, linear)
    return jnp.where(vgst <= 0.0, 0.0 * vgst, on)


def drain_current(vgs, vds, vbs, *, kind, vto, beta, gamma, phi, lambda_):
    """The channel current into the drain, through the channel, out of the source, for the
    true (signed) terminal voltages: polarity by ``kind``, source/drain swap for
    ``V_DS < 0``."""
    sign = KINDS[kind]
    gs, ds, bs = sign * vgs, sign * vds, sign * vbs
    forward = ds >= 0.0
    # in inverse mode the source is the drain: V_GD = V_GS − V_DS, V_BD = V_BS − V_DS
    g = jnp.where(forward, gs, gs - ds)
    b = jnp.where(forward, bs, bs - ds)
    d = jnp.abs(ds)
    i = shichman_hodges(g, d, b, sign * vto, beta, gamma, phi, lambda_)
    return sign * jnp.where(forward, i, -i)


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
    ld=0.0,
    is_=1e-14,
    m=1.0,
    cgso=0.0,
    cgdo=0.0,
    cgbo=0.0,
    gmin=1e-12,
    v0=(0.0, 0.0, 0.0),
    name: str,
) -> ControlledPart:
    r"""A level-1 MOSFET with pins ``d g s b`` (SPICE ``M``; defaults as ngspice's manual:
    ``VTO = 0``, ``KP = 2e-5`` A/V², ``λ = 0``, ``γ = 0``, ``Φ = 0.6`` V, ``W = L = 100 µm``,
    ``IS = 1e-14`` A).

    ``kind`` is ``"nmos"`` or ``"pmos"``; ``m`` is the parallel multiplier. ``vto``, ``kp``,
    ``lambda_`` and ``gamma`` may be traced JAX values (``jax.grad`` reaches them).
    Coordinates ``(q, w, sg, wg, qbs, wbs, qbd, wbd)`` (+ ``sgd, wgd``, ``sgb, wgb`` with
    overlap capacitances); see the module docstring. ``v0 = (V_GS, V_GD, V_GB)``: initial
    voltages across the overlap capacitances (their initial charges).
    """
    where = f"MOSFET {name!r}"
    if kind not in KINDS:
        raise ModelError(f"{where}: kind={kind!r} must be 'nmos' or 'pmos'.")
    vto = coefficient(where, "vto", vto)
    kp = coefficient(where, "kp", kp)
    lambda_ = coefficient(where, "lambda_", lambda_)
    gamma = coefficient(where, "gamma", gamma)
    phi = positive(where, "phi", phi)
    width = positive(where, "w", w)
    length = positive(where, "l", l)
    ld = finite(where, "ld", ld)
    leff = length - 2.0 * ld
    if leff <= 0.0:
        raise ModelError(f"{where}: the effective length L − 2·LD = {leff:g} m must be > 0.")
    mult = positive(where, "m", m)
    i_s = mult * finite(where, "is_", is_)
    g = positive(where, "gmin", gmin)
    caps = {
        "gs": finite(where, "cgso", cgso) * mult * width,
        "gd": finite(where, "cgdo", cgdo) * mult * width,
        "gb": finite(where, "cgbo", cgbo) * mult * leff,
    }
    if min(caps.values()) < 0.0 or i_s < 0.0:
        raise ModelError(f"{where}: overlap capacitances and is_ must be ≥ 0.")
    beta = kp * mult * width / leff
    sign = KINDS[kind]
    law = dict(kind=kind, vto=vto, beta=beta, gamma=gamma, phi=phi, lambda_=lambda_)

    coords = ["q", "w", "sg", "wg", "qbs", "wbs", "qbd", "wbd"]
    pins = [("d", "q", 1), ("s", "q", -1), ("g", "sg", 1), ("s", "sg", -1)]
    pins += [("b", "qbs", 1), ("s", "qbs", -1), ("b", "qbd", 1), ("d", "qbd", -1)]
    roles = [("sg", "current")]
    extra = [k for k in ("gd", "gb") if caps[k] > 0.0]
    for k in extra:
        coords += [f"s{k}", f"w{k}"]
        pins += [("g", f"s{k}", 1), ({"gd": "d", "gb": "b"}[k], f"s{k}", -1)]
        roles.append((f"s{k}", "capacitor"))
    idx = {c: j for j, c in enumerate(coords)}
    gyrators = [("w", "q"), ("wg", "sg"), ("wbs", "qbs"), ("wbd", "qbd")]
    gyrators += [(f"w{k}", f"s{k}") for k in extra]
    flux_caps = [("wg", caps["gs"])] + [(f"w{k}", caps[k]) for k in extra]

    def lagrangian(q, v):
        out = sum(q[idx[a]] * v[idx[b]] for a, b in gyrators)
        return out + sum(0.5 * c * v[idx[a]] ** 2 for a, c in flux_caps if c > 0.0)

    def force(q, v):
        vgs, vds, vbs, vbd = v[idx["wg"]], v[idx["w"]], v[idx["wbs"]], v[idx["wbd"]]
        f = jnp.zeros(len(coords), dtype=v.dtype)
        f = f.at[idx["w"]].set(-drain_current(vgs, vds, vbs, **law))
        f = f.at[idx["wbs"]].set(
            -(sign * pn_current(sign * vbs, i_s, reverse="constant") + g * vbs)
        )
        return f.at[idx["wbd"]].set(
            -(sign * pn_current(sign * vbd, i_s, reverse="constant") + g * vbd)
        )

    v0 = np.asarray(v0, dtype=np.float64).reshape(-1)
    if v0.shape != (3,) or not np.all(np.isfinite(v0)):
        raise ModelError(f"{where}: v0={v0!r} must be three finite voltages (V_GS, V_GD, V_GB).")
    initial_v = np.zeros(len(coords))
    initial_v[idx["wg"]] = v0[0]
    for k in extra:
        initial_v[idx[f"w{k}"]] = v0[1] if k == "gd" else v0[2]
    params = {"kp": kp, "vto": vto, "lambda": lambda_, "gamma": gamma, "phi": phi}
    return ControlledPart(
        tuple(coords),
        lagrangian,
        force=force,
        name=name,
        pins=tuple(pins),
        currents=(),
        initial_v=initial_v,
        role="transistor",
        branch_roles=tuple(roles),
        parameters={k: x for k, x in params.items() if isinstance(x, float)},
    )
