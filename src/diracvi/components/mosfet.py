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
import numpy as np

from ..errors import ModelError
from ._junction import depletion_coenergy, pn_current
from ._mos1 import meyer_half, mode_weight
from ._part import finite, positive
from .controlled import ControlledPart, coefficient

KINDS = {"nmos": 1.0, "pmos": -1.0}
#: the gate-voltage coordinates hold ``τ·V`` (V·s, like the fluxes beside them): Newton
#: judges all positions by one norm, and ``V = Δw/h`` is only known to ``ε‖w‖/h``
TAU = 1e-12


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


def _oriented(vgs, vds, vbs, sign):
    """NMOS-oriented ``(V_GS, V_DS, V_BS)`` of the mode (source and drain swapped when
    ``type·V_DS < 0``) and whether the mode is forward."""
    gs, ds, bs = sign * vgs, sign * vds, sign * vbs
    forward = ds >= 0.0
    # in inverse mode the source is the drain: V_GD = V_GS − V_DS, V_BD = V_BS − V_DS
    return jnp.where(forward, gs, gs - ds), jnp.abs(ds), jnp.where(forward, bs, bs - ds), forward


def drain_current(vgs, vds, vbs, *, kind, vto, beta, gamma, phi, lambda_):
    """The channel current into the drain, through the channel, out of the source, for the
    true (signed) terminal voltages: polarity by ``kind``, source/drain swap for
    ``V_DS < 0``."""
    sign = KINDS[kind]
    g, d, b, forward = _oriented(vgs, vds, vbs, sign)
    i = shichman_hodges(g, d, b, sign * vto, beta, gamma, phi, lambda_)
    return sign * jnp.where(forward, i, -i)


def meyer_capacitances(vgs, vgd, vgb, *, kind, vto, gamma, phi, cox):
    """Meyer's ``(C_GS, C_GD, C_GB)`` at the true terminal voltages (``cox`` = ``C'_ox W
    L_eff``): twice :func:`~diracvi.components._mos1.meyer_half` of the mode, with
    ngspice's ``von`` and ``vdsat = max(V_GST, 0)`` of that mode (the inverse mode swaps
    the roles of source and drain), the two modes blended across ``V_DS = 0`` by
    :func:`~diracvi.components._mos1.mode_weight`."""
    sign = KINDS[kind]
    gs, gd, gb = sign * vgs, sign * vgd, sign * vgb

    def half(g_source, g_drain):  # a mode: the source is the side at g_source
        von = threshold(g_source - gb, sign * vto, gamma, phi)
        return meyer_half(g_source, g_drain, von, jnp.maximum(g_source - von, 0.0), phi, cox)

    f_gs, f_gd, f_gb = half(gs, gd)
    i_gd, i_gs, i_gb = half(gd, gs)
    a = mode_weight(gs - gd)
    return tuple(
        2.0 * (a * f + (1.0 - a) * i) for f, i in ((f_gs, i_gs), (f_gd, i_gd), (f_gb, i_gb))
    )


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
    cox=0.0,
    rd=0.0,
    rs=0.0,
    cbd=0.0,
    cbs=0.0,
    cbdsw=0.0,
    cbssw=0.0,
    pb=0.8,
    mj=0.5,
    mjsw=0.5,
    fc=0.5,
    gmin=1e-12,
    v0=(0.0, 0.0, 0.0),
    name: str,
) -> ControlledPart:
    r"""A level-1 MOSFET with pins ``d g s b`` (SPICE ``M``; defaults as ngspice's manual:
    ``VTO = 0``, ``KP = 2e-5`` A/V², ``λ = 0``, ``γ = 0``, ``Φ = 0.6`` V, ``W = L = 100 µm``,
    ``IS = 1e-14`` A (or a pair: bulk–drain, bulk–source), ``PB = 0.8`` V,
    ``MJ = MJSW = FC = 0.5``).

    ``kind`` is ``"nmos"`` or ``"pmos"``; ``m`` is the parallel multiplier. ``cox`` is the
    oxide capacitance per area ``ε_ox/TOX`` (F/m²; 0: no Meyer capacitances), ``rd``,
    ``rs`` the drain and source resistances (Ω, 0: none), ``cbd``, ``cbs`` the bulk
    junctions' zero-bias bottom capacitances and ``cbdsw``, ``cbssw`` their sidewall ones
    (F, graded by ``mj`` and ``mjsw``), all before ``m``. ``vto``, ``kp``, ``lambda_`` and
    ``gamma`` may be traced JAX values (``jax.grad`` reaches them). ``v0 = (V_GS, V_GD,
    V_GB)``: the initial gate voltages (the overlap capacitors' charges and Meyer's
    voltage coordinates); see the module docstring for the coordinates.
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
    pair = is_ if isinstance(is_, (tuple, list)) else (is_, is_)  # (bulk–drain, bulk–source)
    i_sd, i_ss = (mult * finite(where, "is_", x) for x in pair)
    g = positive(where, "gmin", gmin)
    caps = {
        "gs": finite(where, "cgso", cgso) * mult * width,
        "gd": finite(where, "cgdo", cgdo) * mult * width,
        "gb": finite(where, "cgbo", cgbo) * mult * leff,
    }
    c_ox = finite(where, "cox", cox) * mult * width * leff
    res = {"d": finite(where, "rd", rd) / mult, "s": finite(where, "rs", rs) / mult}
    bulk = {
        "bd": (finite(where, "cbd", cbd) * mult, finite(where, "cbdsw", cbdsw) * mult),
        "bs": (finite(where, "cbs", cbs) * mult, finite(where, "cbssw", cbssw) * mult),
    }
    pb, mj, mjsw = positive(where, "pb", pb), finite(where, "mj", mj), finite(where, "mjsw", mjsw)
    fc = finite(where, "fc", fc)
    values = [*caps.values(), c_ox, *res.values(), *(c for pair in bulk.values() for c in pair)]
    if min(values) < 0.0 or min(i_sd, i_ss) < 0.0:
        raise ModelError(
            f"{where}: capacitances, cox, rd, rs and is_ must be ≥ 0 (got {values}, {is_})."
        )
    if not (0.0 <= mj < 1.0 and 0.0 <= mjsw < 1.0 and 0.0 <= fc < 1.0):
        raise ModelError(f"{where}: mj={mj}, mjsw={mjsw}, fc={fc} must lie in [0, 1).")
    beta = kp * mult * width / leff
    sign = KINDS[kind]
    law = dict(kind=kind, vto=vto, beta=beta, gamma=gamma, phi=phi, lambda_=lambda_)

    # branches: name -> (coordinates, + node, − node); "D", "S" are the internal drain
    # and source behind RD and RS (the outer pins themselves when those are 0)
    inner = {k: k.upper() if res[k] > 0.0 else k for k in "ds"}
    meyer_on = c_ox > 0.0
    gate = [k for k in ("gd", "gb") if caps[k] > 0.0 or meyer_on]
    branches = {
        "ch": (("q", "w"), inner["d"], inner["s"]),
        "gs": (("sg", "wg"), "g", inner["s"]),
        "bs": (("qbs", "wbs"), "b", inner["s"]),
        "bd": (("qbd", "wbd"), "b", inner["d"]),
    }
    for k in gate:
        branches[k] = ((f"s{k}", f"w{k}"), "g", {"gd": inner["d"], "gb": "b"}[k])
    for k in "ds":
        if res[k] > 0.0:
            branches[f"r{k}"] = ((f"qr{k}",), k, inner[k])
    coords = [c for names, _, _ in branches.values() for c in names]
    meyer_branches = ("gs", "gd", "gb") if meyer_on else ()
    for k in meyer_branches:  # the gate voltages as positions: y = ẇ (see lagrangian)
        coords.append(f"y{k}")
    idx = {c: j for j, c in enumerate(coords)}
    internal = [inner[k] for k in "ds" if res[k] > 0.0]
    pins, rows = [], []
    for names, plus, minus in branches.values():
        for node, s in ((plus, 1), (minus, -1)):
            if node not in internal:
                pins.append((node, names[0], s))
    for node in internal:
        row = np.zeros(len(coords))
        for names, plus, minus in branches.values():
            row[idx[names[0]]] += (plus == node) - (minus == node)
        rows.append(row)
    roles = [("sg", "current")] + [(f"s{k}", "capacitor") for k in gate]
    flux = {k: branches[k][0][1] for k in branches if len(branches[k][0]) == 2}
    flux_caps = [(flux[k], caps[k]) for k in ("gs", *gate) if caps[k] > 0.0]
    junction_caps = {k: c for k, c in bulk.items() if c[0] > 0.0 or c[1] > 0.0}

    def stored(vn, k):  # the bulk junction's depletion co-energy (NMOS-oriented V)
        bottom, side = junction_caps[k]
        out = 0.0 * vn
        if bottom > 0.0:
            out = out + depletion_coenergy(vn, bottom, pb, mj, fc)
        if side > 0.0:
            out = out + depletion_coenergy(vn, side, pb, mjsw, fc)
        return out

    def lagrangian(q, v):
        out = sum(q[idx[w_]] * v[idx[names[0]]] for names, _, _ in branches.values()
                  for w_ in names[1:])  # fmt: skip
        out = out + sum(0.5 * c * v[idx[a]] ** 2 for a, c in flux_caps)
        for k in junction_caps:
            out = out + stored(sign * v[idx[flux[k]]], k)
        for k in meyer_branches:  # −½ C_ox (ẇ − y/τ)²: its y-line is y = τ ẇ, where it is 0
            out = out - 0.5 * c_ox * (v[idx[flux[k]]] - q[idx[f"y{k}"]] / TAU) ** 2
        return out + 0.0 * v[0]

    def force(q, v):
        vgs, vds, vbs, vbd = v[idx["wg"]], v[idx["w"]], v[idx["wbs"]], v[idx["wbd"]]
        f = jnp.zeros(len(coords), dtype=v.dtype)
        f = f.at[idx["w"]].set(-drain_current(vgs, vds, vbs, **law))
        f = f.at[idx["wbs"]].set(
            -(sign * pn_current(sign * vbs, i_ss, reverse="constant") + g * vbs)
        )
        f = f.at[idx["wbd"]].set(
            -(sign * pn_current(sign * vbd, i_sd, reverse="constant") + g * vbd)
        )
        for k in "ds":
            if res[k] > 0.0:
                f = f.at[idx[f"qr{k}"]].set(-res[k] * v[idx[f"qr{k}"]])
        if meyer_on:  # i_x = C_x(y) ẏ_x: Meyer's currents, a port on each gate flux
            y = [q[idx[f"y{k}"]] / TAU for k in meyer_branches]
            cs = meyer_capacitances(*y, kind=kind, vto=vto, gamma=gamma, phi=phi, cox=c_ox)
            for k, c in zip(meyer_branches, cs, strict=True):
                f = f.at[idx[flux[k]]].add(-c * v[idx[f"y{k}"]] / TAU)
        return f

    v0 = np.asarray(v0, dtype=np.float64).reshape(-1)
    if v0.shape != (3,) or not np.all(np.isfinite(v0)):
        raise ModelError(f"{where}: v0={v0!r} must be three finite voltages (V_GS, V_GD, V_GB).")
    start = {"gs": v0[0], "gd": v0[1], "gb": v0[2]}
    initial_v = np.zeros(len(coords))
    initial_q = np.zeros(len(coords))
    for k in ("gs", *gate):
        initial_v[idx[flux[k]]] = start[k]
    for k in meyer_branches:
        initial_q[idx[f"y{k}"]] = TAU * start[k]
    params = {"kp": kp, "vto": vto, "lambda": lambda_, "gamma": gamma, "phi": phi}
    return ControlledPart(
        tuple(coords),
        lagrangian,
        force=force,
        constraints=np.array(rows) if rows else None,
        constraint_names=tuple(f"KCL({n.lower()}')" for n in internal) if rows else None,
        name=name,
        pins=tuple(pins),
        currents=(),
        initial_q=initial_q,
        initial_v=initial_v,
        role="transistor",
        branch_roles=tuple(roles),
        mirrors=tuple(f"y{k}" for k in meyer_branches),
        parameters={k: x for k, x in params.items() if isinstance(x, float)},
    )
