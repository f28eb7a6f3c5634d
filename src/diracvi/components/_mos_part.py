r"""The MOSFET part shared by the levels (:mod:`~diracvi.components.mosfet` for level 1,
:mod:`~diracvi.components.mosfet6` for level 6): everything but the channel's law.

A level is a **forward law** ``forward(V_GS, V_DS, V_BS) -> (I_D, von, vdsat)`` of an
NMOS-oriented device in its forward mode (``V_DS ≥ 0``, voltages already multiplied by
``type``): the drain current and the threshold and saturation voltage that Meyer's gate
capacitances read. This module applies it as ngspice's ``mos1load``/``mos6load`` do: the
polarity, the source/drain swap for ``V_DS < 0`` (``V_GD``, ``V_BD``, ``−V_DS`` in the law,
the current reversed), the bulk junctions (diodes with ngspice's constant ``−I_S`` below
``−3 V_T`` — ``mos3load``'s cubic ``−I_S (1 + (3V_T/(eV))³)`` at level 3 — plus
``G_min``), their depletion charges, the overlap capacitances, RD/RS, and Meyer's
capacitances (:mod:`~diracvi.components._mos1`) with the mode's ``von``, ``vdsat``.

The Lagrange–Dirac form (branches, sense branches, Meyer's voltage coordinates) is
described in :mod:`~diracvi.components.mosfet`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._junction import THERMAL_VOLTAGE, depletion_coenergy, pn_current
from ._mos1 import meyer_half, mode_weight
from ._part import array_module, finite, positive
from .controlled import ControlledPart

KINDS = {"nmos": 1.0, "pmos": -1.0}
#: the gate-voltage coordinates hold ``τ·V`` (V·s, like the fluxes beside them): Newton
#: judges all positions by one norm, and ``V = Δw/h`` is only known to ``ε‖w‖/h``
TAU = 1e-12


def _oriented(vgs, vds, vbs, sign):
    """NMOS-oriented ``(V_GS, V_DS, V_BS)`` of the mode (source and drain swapped when
    ``type·V_DS < 0``) and whether the mode is forward."""
    gs, ds, bs = sign * vgs, sign * vds, sign * vbs
    forward = ds >= 0.0
    # in inverse mode the source is the drain: V_GD = V_GS − V_DS, V_BD = V_BS − V_DS
    return jnp.where(forward, gs, gs - ds), jnp.abs(ds), jnp.where(forward, bs, bs - ds), forward


def channel_current(vgs, vds, vbs, sign, forward):
    """The channel current into the drain, out of the source, for the true (signed)
    terminal voltages: polarity ``sign`` = ±1, the forward law ``forward``, the
    source/drain swap for ``V_DS < 0``."""
    g, d, b, is_forward = _oriented(vgs, vds, vbs, sign)
    i = forward(g, d, b)[0]
    return sign * jnp.where(is_forward, i, -i)


def _meyer(gs, gd, laws, phi, cox):
    """Meyer's capacitances from the law's ``(von, vdsat)`` of the forward mode (source at
    ``gs``) and of the inverse one, NMOS-oriented gate voltages (see
    :func:`gate_capacitances`)."""
    (von_f, sat_f), (von_i, sat_i) = laws
    f_gs, f_gd, f_gb = meyer_half(gs, gd, von_f, sat_f, phi, cox)
    i_gd, i_gs, i_gb = meyer_half(gd, gs, von_i, sat_i, phi, cox)
    a = mode_weight(gs - gd)
    return tuple(
        2.0 * (a * f + (1.0 - a) * i) for f, i in ((f_gs, i_gs), (f_gd, i_gd), (f_gb, i_gb))
    )


def channel_and_gates(vgs, vds, vbs, gates, sign, forward, phi, cox):
    """:func:`channel_current` at ``(vgs, vds, vbs)`` and :func:`gate_capacitances` at
    ``gates = (V_GS, V_GD, V_GB)`` with the law evaluated once, on the three voltage
    triples stacked (the channel's mode and Meyer's two): one copy of the law in the
    compiled program instead of three."""
    g, d, b, is_forward = _oriented(vgs, vds, vbs, sign)
    gs, gd, gb = (sign * x for x in gates)
    current, von, vdsat = forward(
        jnp.stack([g, gs, gd]), jnp.stack([d, gs - gd, gd - gs]), jnp.stack([b, gs - gb, gd - gb])
    )
    i = sign * jnp.where(is_forward, current[0], -current[0])
    return i, _meyer(gs, gd, ((von[1], vdsat[1]), (von[2], vdsat[2])), phi, cox)


def gate_capacitances(vgs, vgd, vgb, sign, forward, phi, cox):
    """Meyer's ``(C_GS, C_GD, C_GB)`` at the true terminal voltages (``cox`` = ``C'_ox W
    L_eff``): twice :func:`~diracvi.components._mos1.meyer_half` of each mode, with that
    mode's ``von`` and ``vdsat`` from the law (the inverse mode swaps the roles of source
    and drain), the two modes blended across ``V_DS = 0`` by
    :func:`~diracvi.components._mos1.mode_weight`."""
    gs, gd, gb = sign * vgs, sign * vgd, sign * vgb
    # a mode: the source is the side at g_source
    laws = [forward(g, g - other, g - gb)[1:] for g, other in ((gs, gd), (gd, gs))]
    return _meyer(gs, gd, laws, phi, cox)


#: the keywords every level takes beside its law's and ``W``, ``L``, with ngspice's
#: defaults (:func:`~diracvi.components.MOSFET` says what each is)
SHARED = {
    "ld": 0.0, "m": 1.0, "is_": 1e-14, "cgso": 0.0, "cgdo": 0.0, "cgbo": 0.0, "cox": 0.0,
    "rd": 0.0, "rs": 0.0, "cbd": 0.0, "cbs": 0.0, "cbdsw": 0.0, "cbssw": 0.0, "pb": 0.8,
    "mj": 0.5, "mjsw": 0.5, "fc": 0.5, "gmin": 1e-12, "v0": (0.0, 0.0, 0.0),
    "emission": 1.0,
}  # fmt: skip


def polarity(where: str, kind: str) -> float:
    """``type`` = +1 for ``"nmos"``, −1 for ``"pmos"``; another ``kind`` is refused."""
    if kind not in KINDS:
        raise ModelError(f"{where}: kind={kind!r} must be 'nmos' or 'pmos'.")
    return KINDS[kind]


def bulk_limits(sign, saturation: dict):
    """The bulk junctions Newton limits as ngspice's ``mos1load``/``mos2load`` do
    (``pnjlim`` on ``V_BS``, ``V_BD`` with ``V_T`` and ``V_crit = V_T ln(V_T/(√2 I_S))``),
    as ``(coordinates, rows)`` for :mod:`diracvi.solvers.limiting`: polarity ``type``,
    and the operating point starts them at −1 V (``MODEINITJCT``: ``V_BS = −1``,
    ``V_DS = 0``). A junction with ``I_S = 0`` (a VDMOS's) is GMIN alone, linear: not
    declared."""
    names, rows = [], []
    for name, i_s in saturation.items():
        if isinstance(i_s, float) and i_s <= 0.0:
            continue
        xp = array_module(i_s, sign)
        vcrit = THERMAL_VOLTAGE * xp.log(THERMAL_VOLTAGE / (np.sqrt(2.0) * i_s))
        names.append(name)
        rows.append(xp.stack([xp.asarray(x, float) for x in
                              (THERMAL_VOLTAGE, vcrit, np.inf, sign, -1.0)]))  # fmt: skip
    return tuple(names), (array_module(*rows).stack(rows) if rows else None)


class Device(NamedTuple):
    """A MOSFET's checked kind and size (``L_eff = L − 2·LD``, ``M``) and the rest of its
    shared keywords (:data:`SHARED`), for :func:`build`."""

    where: str
    name: str
    kind: str
    width: float
    leff: float
    mult: float
    shared: dict


def pins_and_kcl(branches: dict, idx: dict, internal: list) -> tuple[list, list]:
    """A transistor's branches ``{key: ((charge, …), plus, minus)}`` joined: the pins
    ``(node, charge, ±1)`` of the ends at terminals, and for each internal node (behind
    RD or RS) its KCL row ``Σ ±q̇_branch = 0`` over the coordinates ``idx``."""
    pins, rows = [], []
    for names, plus, minus in branches.values():
        for node, s in ((plus, 1), (minus, -1)):
            if node not in internal:
                pins.append((node, names[0], s))
    for node in internal:
        row = np.zeros(len(idx))
        for names, plus, minus in branches.values():
            row[idx[names[0]]] += (plus == node) - (minus == node)
        rows.append(row)
    return pins, rows


def device(label: str, kind, w, l, name: str, keywords: dict, defaults=SHARED) -> Device:  # noqa: E741
    """The :class:`Device` of a level's function ``label`` called with ``keywords`` (its
    ``**shared``) over the level's ``defaults``: a name not among them is refused as Python
    refuses an unknown keyword; ``L_eff`` must be > 0."""
    where = f"{label} {name!r}"
    polarity(where, kind)
    unknown = sorted(set(keywords) - set(defaults))
    if unknown:
        raise TypeError(f"{label}() got an unexpected keyword argument {unknown[0]!r}")
    shared = defaults | keywords
    width = positive(where, "w", w)
    leff = positive(where, "l", l) - 2.0 * finite(where, "ld", shared.pop("ld"))
    if leff <= 0.0:
        raise ModelError(f"{where}: the effective length L − 2·LD = {leff:g} m must be > 0.")
    return Device(where, name, kind, width, leff, positive(where, "m", shared.pop("m")), shared)


def build(device: Device, forward, phi, params: dict, **override) -> ControlledPart:
    """The part of ``device`` whose channel obeys ``forward`` (its parameters already
    scaled by ``W/L_eff`` and ``M``); ``override``: shared keywords the level sets itself
    (level 2's ``cox`` from ``TOX``; level 3's ``reverse="cubic"`` junction branch),
    ``params`` the part's recorded parameters."""
    return _assemble(
        device.where, device.kind, forward, phi, width=device.width, leff=device.leff,
        mult=device.mult, params=params, name=device.name, **(device.shared | override),
    )  # fmt: skip


def _assemble(
    where,
    kind,
    forward,
    phi,
    *,
    width,
    leff,
    mult,
    is_,
    cgso,
    cgdo,
    cgbo,
    cox,
    rd,
    rs,
    cbd,
    cbs,
    cbdsw,
    cbssw,
    pb,
    mj,
    mjsw,
    fc,
    gmin,
    v0,
    params,
    name,
    emission=1.0,
    reverse="constant",
) -> ControlledPart:
    """The part of a MOSFET with pins ``d g s b`` (:func:`build`'s)."""
    sign = KINDS[kind]
    pair = is_ if isinstance(is_, (tuple, list)) else (is_, is_)  # (bulk–drain, bulk–source)
    i_sd, i_ss = (mult * finite(where, "is_", x) for x in pair)
    g = positive(where, "gmin", gmin) * mult  # ngspice's load scales GMIN by M too
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
    # the depletion charge divides by 1 − M and its co-energy by 2 − M (ngspice's level-2
    # cards grade steeper than 1: xy_mosrect's MJ = 1.067)
    if not (0.0 <= fc < 1.0 and all(0.0 <= x < 2.0 and x != 1.0 for x in (mj, mjsw))):
        raise ModelError(
            f"{where}: mj={mj}, mjsw={mjsw} must lie in [0, 2) but not be 1, fc={fc} in [0, 1)."
        )

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
    pins, rows = pins_and_kcl(branches, idx, internal)
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
        if meyer_on:  # Meyer's currents i_x = C_x(y) ẏ_x: a port on each gate flux
            y = [q[idx[f"y{k}"]] / TAU for k in meyer_branches]
            i_ch, cs = channel_and_gates(vgs, vds, vbs, y, sign, forward, phi, c_ox)
            for k, c in zip(meyer_branches, cs, strict=True):
                f = f.at[idx[flux[k]]].add(-c * v[idx[f"y{k}"]] / TAU)
        else:
            i_ch = channel_current(vgs, vds, vbs, sign, forward)
        f = f.at[idx["w"]].set(-i_ch)
        f = f.at[idx["wbs"]].set(
            -(sign * pn_current(sign * vbs, i_ss, emission, reverse=reverse) + g * vbs)
        )
        f = f.at[idx["wbd"]].set(
            -(sign * pn_current(sign * vbd, i_sd, emission, reverse=reverse) + g * vbd)
        )
        for k in "ds":
            if res[k] > 0.0:
                f = f.at[idx[f"qr{k}"]].set(-res[k] * v[idx[f"qr{k}"]])
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
    junctions, limits = bulk_limits(sign, {"wbs": i_ss, "wbd": i_sd})
    return ControlledPart(
        tuple(coords),
        lagrangian,
        force=force,
        junctions=junctions,
        junction_limits=limits,
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
