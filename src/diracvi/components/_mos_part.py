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

import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.validate import check_name
from ._junction import THERMAL_VOLTAGE, depletion_coenergy, pn_current
from ._mos1 import meyer_half, mode_weight
from ._part import array_module, fields, finite, positive, replaced, traced
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
        if not traced(i_s) and i_s <= 0.0:
            continue
        xp = array_module(i_s, sign)
        vcrit = THERMAL_VOLTAGE * xp.log(THERMAL_VOLTAGE / (np.sqrt(2.0) * i_s))
        names.append(name)
        rows.append((THERMAL_VOLTAGE, vcrit, np.inf, sign, -1.0))
    if not rows:
        return tuple(names), None
    xp = array_module(sign, *saturation.values())
    if xp is np:
        # host numbers (every device but one differentiated): one NumPy array from the
        # rows (≈ 0.1 ms a transistor less than stacking each row)
        return tuple(names), np.array(rows, dtype=np.float64)
    return tuple(names), xp.stack([xp.stack([xp.asarray(x, float) for x in r]) for r in rows])


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


_HOST_NUMBERS = frozenset((float, int, np.float64))


def law_vector(numbers: dict, names) -> object:
    """The numbers ``numbers[k]`` in ``names``' order as one vector: NumPy where every one
    is a number (so alike devices share a program), a JAX array where a parameter is
    being differentiated (kept traced)."""
    values = [numbers[k] for k in names]
    if all(type(x) in _HOST_NUMBERS for x in values):  # (the common case, without a scan)
        return np.array(values, dtype=np.float64)
    if any(traced(x) for x in values):
        return jnp.stack([jnp.asarray(x, dtype=jnp.float64) for x in values])
    return np.array([float(x) for x in values], dtype=np.float64)


def _on_device(vector):
    """A number vector as a part computes with it: a NumPy vector put on the device (an
    eager call, or one differentiated by ``jax.jacfwd``, then computes with JAX's
    operations throughout, as the closures' constants did — NumPy scalars would compute
    a power in a junction's depletion charge with C's ``pow``, one ulp off XLA's in the
    Jacobians); a traced one (inside a compiled or stacked program) as it is. Done when
    the part is called, not when it is built: a ``device_put`` per vector was ≈ 0.2 ms
    of every transistor's reading, and a stacked run never reads a member's own vector."""
    if isinstance(vector, np.ndarray):
        with jax.ensure_compile_time_eval():
            return jax.device_put(vector)
    return vector


class Law(eqx.Module):
    r"""A level's forward law ``(V_GS, V_DS, V_BS) -> (I_D, von, vdsat)`` as data:
    ``make(**numbers, **flags)`` is the law, where ``make`` is a top-level function of the
    law's constants (:func:`~diracvi.components.mosfet.level1`,
    :func:`~diracvi.components.mosfet6.sakurai_newton`, …), ``flags`` its choices made
    in Python when the part is built (ngspice's branches on the card: NFS ≠ 0, VMAX > 0,
    …; static) and ``numbers`` the constants as one float64 vector (leaves). Devices
    whose laws have one ``make`` and equal flags compute one function of different
    numbers: its form is read once (:func:`~diracvi.model.system._user_function`), not
    traced per device, and they stack into one ``vmap``."""

    make: Callable = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)
    flags: tuple = eqx.field(static=True)
    numbers: Any

    def __call__(self, vgs, vds, vbs):
        numbers = _on_device(self.numbers)
        values = {k: numbers[j] for j, k in enumerate(self.names)}
        return self.make(**values, **dict(self.flags))(vgs, vds, vbs)


def law(make: Callable, flags: dict | None = None, **numbers) -> Law:
    """The :class:`Law` ``make(**numbers, **flags)``: ``numbers`` are its constants (floats,
    or traced values that ``jax.grad`` reaches), ``flags`` its static choices."""
    names = tuple(numbers)
    flags = tuple((flags or {}).items())
    vector = law_vector(numbers, names)
    if isinstance(vector, jax.Array):  # traced: Equinox's construction, as any Module
        return Law(make, names, flags, vector)
    # its fields set directly (as renamed() sets a part's): Equinox's construction of a
    # Module costs ≈ 0.1 ms, and a deck of 10⁴ distinct transistors builds 10⁴ laws
    out = object.__new__(Law)
    fields(out).update(make=make, names=names, flags=flags, numbers=vector)
    return out


class Layout(NamedTuple):
    """What a MOSFET part's Lagrangian and force compute, decided in Python when the part
    is built (static: parts of equal layouts are one function of their numbers)."""

    n: int  # the part's coordinate count
    pairs: tuple  # (charge, flux) indices of the two-coordinate branches: L's Σ w q̇
    flux_caps: tuple  # (flux index, number) of the linear gate capacitors (the overlaps)
    junction_caps: tuple  # (junction, flux index, bottom on, sidewall on): depletion charges
    meyer: tuple  # (flux index, y index) of Meyer's gate branches (empty: no oxide)
    terminals: tuple  # the indices of w_g, w, w_bs, w_bd (V_GS, V_DS, V_BS, V_BD)
    resistors: tuple  # (charge index, number) of RD, RS
    reverse: str  # the bulk junctions' reverse branch (pn_current's)
    names: tuple  # the numbers' names, in the vector's order


def _named(layout: Layout, numbers) -> dict:
    numbers = _on_device(numbers)
    return {k: numbers[j] for j, k in enumerate(layout.names)}


class MosLagrangian(eqx.Module):
    r"""``L = Σ w_b q̇_b + Σ ½ C_x ẇ_x² + Σ C*_J(type·ẇ_J) − Σ ½ C_ox (ẇ_x − y_x/τ)²`` of
    the module docstring of :mod:`~diracvi.components.mosfet` (the flux-form branches,
    the overlap capacitors, the bulk junctions' depletion co-energies, Meyer's ties), its
    structure the static :class:`Layout`, its numbers one vector."""

    layout: Layout = eqx.field(static=True)
    numbers: Any

    def __call__(self, q, v):
        lay, p = self.layout, _named(self.layout, self.numbers)
        out = sum(q[w] * v[c] for c, w in lay.pairs)
        out = out + sum(0.5 * p[c] * v[a] ** 2 for a, c in lay.flux_caps)
        for k, a, bottom, side in lay.junction_caps:  # NMOS-oriented junction voltage
            vn = p["sign"] * v[a]
            stored = 0.0 * vn
            if bottom:
                stored = stored + depletion_coenergy(vn, p[f"cj_{k}"], p["pb"], p["mj"], p["fc"])
            if side:
                stored = stored + depletion_coenergy(
                    vn, p[f"cjsw_{k}"], p["pb"], p["mjsw"], p["fc"]
                )
            out = out + stored
        for a, y in lay.meyer:  # −½ C_ox (ẇ − y/τ)²: its y-line is y = τ ẇ, where it is 0
            out = out - 0.5 * p["c_ox"] * (v[a] - q[y] / p["tau"]) ** 2
        return out + 0.0 * v[0]


class MosForce(eqx.Module):
    r"""``F``: minus the channel current (the level's :class:`Law`, the polarity and the
    source/drain swap), the bulk junctions' currents with ``G_min``, the resistors'
    ``R q̇``, and Meyer's port currents ``C_x(y/τ) ẏ_x/τ`` on the gate fluxes; its
    structure the static :class:`Layout`, its numbers one vector beside the law's."""

    layout: Layout = eqx.field(static=True)
    numbers: Any
    law: Callable

    def __call__(self, q, v):
        lay, p = self.layout, _named(self.layout, self.numbers)
        sign = p["sign"]
        ig, iw, ibs, ibd = lay.terminals
        vgs, vds, vbs, vbd = v[ig], v[iw], v[ibs], v[ibd]
        f = jnp.zeros(lay.n, dtype=v.dtype)
        if lay.meyer:  # Meyer's currents i_x = C_x(y) ẏ_x: a port on each gate flux
            y = [q[j] / p["tau"] for _, j in lay.meyer]
            i_ch, cs = channel_and_gates(vgs, vds, vbs, y, sign, self.law, p["phi"], p["c_ox"])
            for (a, j), c in zip(lay.meyer, cs, strict=True):
                f = f.at[a].add(-c * v[j] / p["tau"])
        else:
            i_ch = channel_current(vgs, vds, vbs, sign, self.law)
        f = f.at[iw].set(-i_ch)
        emission, g, reverse = p["emission"], p["g"], lay.reverse
        f = f.at[ibs].set(
            -(sign * pn_current(sign * vbs, p["i_ss"], emission, reverse=reverse) + g * vbs)
        )
        f = f.at[ibd].set(
            -(sign * pn_current(sign * vbd, p["i_sd"], emission, reverse=reverse) + g * vbd)
        )
        for a, r in lay.resistors:
            f = f.at[a].set(-p[r] * v[a])
        return f


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
    """The part of a MOSFET with pins ``d g s b`` (:func:`build`'s).

    Everything decided in Python (which branches exist, Meyer on or off, RD/RS, the
    junctions' charges) is the static :class:`Layout` of its :class:`MosLagrangian` and
    :class:`MosForce`, every number one vector: devices that differ only in their
    numbers (W, L, the card's values) are one function of different numbers, read once
    and stacked, not traced per device."""
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

    # every number one vector (its names in order), every choice the static layout
    # (τ too: as a literal of the code, XLA fuses x/τ otherwise than the closure's lifted
    # constant did, one ulp off in the compiled Meyer lines)
    numbers = {"sign": sign, "tau": TAU, "phi": phi, "c_ox": c_ox, "i_sd": i_sd, "i_ss": i_ss,
               "g": g, "emission": emission, "pb": pb, "mj": mj, "mjsw": mjsw,
               "fc": fc}  # fmt: skip
    numbers.update({f"c_{k}": c for k, c in caps.items()})
    numbers.update({f"r_{k}": r for k, r in res.items()})
    for k, (bottom, side) in bulk.items():
        numbers.update({f"cj_{k}": bottom, f"cjsw_{k}": side})
    shape = _structure(
        tuple(caps[k] > 0.0 for k in ("gs", "gd", "gb")),
        c_ox > 0.0,
        tuple(res[k] > 0.0 for k in "ds"),
        tuple((c[0] > 0.0, c[1] > 0.0) for c in bulk.values()),
        reverse,
        tuple(numbers),
    )
    vector = law_vector(numbers, shape.layout.names)

    if not (type(v0) is tuple and len(v0) == 3 and all(type(x) is float for x in v0)):
        v0 = np.asarray(v0, dtype=np.float64).reshape(-1)  # (a tuple of floats as it is)
    if len(v0) != 3 or not all(math.isfinite(x) for x in v0):
        raise ModelError(f"{where}: v0={v0!r} must be three finite voltages (V_GS, V_GD, V_GB).")
    start = {"gs": float(v0[0]), "gd": float(v0[1]), "gb": float(v0[2])}
    initial_v = [0.0] * shape.layout.n
    initial_q = [0.0] * shape.layout.n
    for j, k in shape.start_v:
        initial_v[j] = start[k]
    for j, k in shape.start_q:
        initial_q[j] = TAU * start[k]
    junctions, limits = bulk_limits(sign, {"wbs": i_ss, "wbd": i_sd})
    parameters = {k: x for k, x in params.items() if isinstance(x, float)}
    key = _template_key(kind, shape, junctions, limits, vector, forward)
    template = _TEMPLATES.get(key) if key is not None else None
    if template is not None:
        return _from_template(
            template, name, vector, forward, limits, initial_q, initial_v, parameters
        )
    part = ControlledPart(
        shape.coords,
        MosLagrangian(shape.layout, vector),
        force=MosForce(shape.layout, vector, forward),
        junctions=junctions,
        junction_limits=limits,
        constraints=np.array(shape.rows) if shape.rows else None,
        constraint_names=shape.constraint_names,
        name=name,
        pins=shape.pins,
        currents=(),
        initial_q=initial_q,
        initial_v=initial_v,
        role="transistor",
        branch_roles=shape.roles,
        mirrors=shape.mirrors,
        parameters=parameters,
    )
    if key is not None:
        if len(_TEMPLATES) >= _TEMPLATES_LIMIT:
            _TEMPLATES.clear()
        _TEMPLATES[key] = part
    return part


#: the first MOSFET part of each structure (:func:`_template_key`): later ones are its
#: copies with their own name, numbers and initial state (:func:`_from_template`)
_TEMPLATES: dict = {}
_TEMPLATES_LIMIT = 256


class _Structure(NamedTuple):
    """A MOSFET part's form, decided by which of its branches exist (:func:`_structure`)."""

    layout: Layout
    coords: tuple  # coordinate names
    pins: tuple  # (pin, charge, ±1)
    rows: tuple  # the internal nodes' KCL rows over the coordinates (tuples: hashable)
    constraint_names: tuple | None
    roles: tuple  # (coordinate, role) for the topology checks
    mirrors: tuple  # Meyer's voltage coordinates
    start_v: tuple  # (index, "gs" | "gd" | "gb"): velocities set from v0
    start_q: tuple  # (index, …): Meyer's y = τ·v0


@functools.lru_cache(maxsize=256)
def _structure(caps_on, meyer_on, res_on, bulk_on, reverse, names) -> _Structure:
    """The coordinates, pins, KCL rows and :class:`Layout` of a MOSFET part whose overlap
    capacitors ``gs, gd, gb``, oxide (Meyer), RD, RS and bulk junctions' bottom and
    sidewall charges (``bd``, ``bs``) are on or off as given: the same for every device
    of one structure, so worked out once (a deck of 10⁴ transistors has a few)."""
    caps = dict(zip(("gs", "gd", "gb"), caps_on, strict=True))
    res = dict(zip("ds", res_on, strict=True))
    bulk = dict(zip(("bd", "bs"), bulk_on, strict=True))
    # branches: name -> (coordinates, + node, − node); "D", "S" are the internal drain
    # and source behind RD and RS (the outer pins themselves when those are 0)
    inner = {k: k.upper() if res[k] else k for k in "ds"}
    gate = [k for k in ("gd", "gb") if caps[k] or meyer_on]
    branches = {
        "ch": (("q", "w"), inner["d"], inner["s"]),
        "gs": (("sg", "wg"), "g", inner["s"]),
        "bs": (("qbs", "wbs"), "b", inner["s"]),
        "bd": (("qbd", "wbd"), "b", inner["d"]),
    }
    for k in gate:
        branches[k] = ((f"s{k}", f"w{k}"), "g", {"gd": inner["d"], "gb": "b"}[k])
    for k in "ds":
        if res[k]:
            branches[f"r{k}"] = ((f"qr{k}",), k, inner[k])
    coords = [c for names_, _, _ in branches.values() for c in names_]
    meyer_branches = ("gs", "gd", "gb") if meyer_on else ()
    for k in meyer_branches:  # the gate voltages as positions: y = ẇ (see MosLagrangian)
        coords.append(f"y{k}")
    idx = {c: j for j, c in enumerate(coords)}
    internal = [inner[k] for k in "ds" if res[k]]
    pins, rows = pins_and_kcl(branches, idx, internal)
    flux = {k: branches[k][0][1] for k in branches if len(branches[k][0]) == 2}
    layout = Layout(
        n=len(coords),
        pairs=tuple((idx[ns[0]], idx[ns[1]]) for ns, _, _ in branches.values() if len(ns) == 2),
        flux_caps=tuple((idx[flux[k]], f"c_{k}") for k in ("gs", *gate) if caps[k]),
        junction_caps=tuple((k, idx[flux[k]], c[0], c[1]) for k, c in bulk.items() if c[0] or c[1]),
        meyer=tuple((idx[flux[k]], idx[f"y{k}"]) for k in meyer_branches),
        terminals=(idx["wg"], idx["w"], idx["wbs"], idx["wbd"]),
        resistors=tuple((idx[f"qr{k}"], f"r_{k}") for k in "ds" if res[k]),
        reverse=reverse,
        names=names,
    )
    return _Structure(
        layout=layout,
        coords=tuple(coords),
        pins=tuple(pins),
        rows=tuple(tuple(float(x) for x in row) for row in rows),
        constraint_names=tuple(f"KCL({n.lower()}')" for n in internal) if rows else None,
        roles=(("sg", "current"), *((f"s{k}", "capacitor") for k in gate)),
        mirrors=tuple(f"y{k}" for k in meyer_branches),
        start_v=tuple((idx[flux[k]], k) for k in ("gs", *gate)),
        start_q=tuple((idx[f"y{k}"], k) for k in meyer_branches),
    )


def _template_key(kind, shape, junctions, limits, vector, forward):
    """What a MOSFET part is made of besides its numbers, name and initial state — its
    :class:`_Structure` (layout, coordinates, pins, KCL rows), the junctions Newton
    limits, the law's maker, names and flags, and the shapes of the numbers — or
    ``None`` when a number is traced (``jax.grad`` through a parameter: the part is
    built)."""
    if not (
        isinstance(vector, np.ndarray)
        and isinstance(forward, Law)
        and isinstance(fields(forward)["numbers"], np.ndarray)
        and (limits is None or isinstance(limits, np.ndarray))
    ):
        return None
    law_ = fields(forward)
    return (
        kind, shape, junctions, None if limits is None else limits.shape, vector.shape,
        law_["make"], law_["names"], law_["flags"], law_["numbers"].shape,
    )  # fmt: skip


def _from_template(template, name, vector, forward, limits, initial_q, initial_v, parameters):
    r"""The part :class:`ControlledPart` would build for a device of ``template``'s
    structure (:func:`_template_key`) with these numbers: the template's fields with the
    name, the two number vectors (in the wrapped Lagrangian's and force's array leaves),
    the junctions' limits, the initial state and the recorded parameters replaced.

    Equal to the constructed part field for field (``tests/test_mos_module.py``): every
    other field — the coordinates, pins, KCL rows, the wrapped functions' static parts
    and the forms the constructor read from them (their output shapes and signatures) —
    is a function of the structure alone. Building a ControlledPart (Equinox's
    construction of the part and its wrapped functions, their forms' keys) was ≈ 2/3 of
    a distinct transistor's reading."""
    own = fields(template)
    lagrangian, force = own["_lagrangian"], own["_force"]
    arrays = fields(force)["arrays"]  # (MosForce's arrays: its vector, its law's)
    law_numbers = fields(forward)["numbers"]
    arrays = replaced(
        arrays, numbers=vector, law=replaced(fields(arrays)["law"], numbers=law_numbers)
    )
    return replaced(
        template,
        name=check_name("name", name),
        _lagrangian=replaced(
            lagrangian, arrays=replaced(fields(lagrangian)["arrays"], numbers=vector)
        ),
        _force=replaced(force, arrays=arrays),
        junction_limits=limits,
        initial_q=tuple(float(x) for x in initial_q),
        initial_v=tuple(float(x) for x in initial_v),
        parameters=tuple((str(k), float(x)) for k, x in parameters.items()),
    )
