r"""The BSIM3v3 MOSFET (SPICE ``M`` at ``LEVEL=8`` or ``49``; ngspice's ``bsim3`` for
VERSION 3.3.0, ``bsim3v32`` for 3.2–3.2.4) as a Lagrange–Dirac part with a charge port.

Branches in flux form (``L = w q̇`` on each: ``ẇ`` is the branch voltage), as the other
levels (:mod:`~diracvi.components._mos_part`): the channel ``d′→s′``, the gate ``g→s′``,
the bulk junctions ``b→s′`` and ``b→d′``, and ``RD``/``RS`` (``RSH`` times the line's
``NRD``/``NRS``) to internal nodes ``d′``, ``s′`` when not 0, their KCL as constraints.

**Currents** (the forces): the channel carries ``type·I_ds`` of
:func:`~diracvi.components._bsim3.evaluate` in the mode (``V_DS ≥ 0``; for ``V_DS < 0``
the source and drain swap: ``V_GD``, ``V_BD``, ``−V_DS`` in the law, the current reversed),
the substrate current ``I_sub`` flows from the mode's drain to the bulk, and each bulk
junction carries ngspice's BSIM3 diode ``I_S(e^{V/N V_t} − 1) + G_min V``, continued by its
tangent above ``V_jsm = N V_t ln(IJTH/I_S + 1)`` (VERSION 3.2: the line through
``(V_jsm, IJTH)`` of slope ``(I_S + IJTH)/N V_t``), ``I_S = JS·AS + JSW·PS`` (1e-14 A when
both are 0).

**Charges** (the port, :class:`~diracvi.components._charge_port.ChargePortPart`): the
terminal charges ngspice integrates, ``type·Q(type·V)``,

    Q_G = Q_g + Q_gso(V_GS) + Q_gdo(V_GD) + CGBO L_eff,CV V_GB
    Q_D = Q_d − Q_gdo(V_GD) − Q_bd(V_BD)           (the mode's: Q_s = −Q_g − Q_b − Q_d when swapped)
    Q_B = Q_b − CGBO L_eff,CV V_GB + Q_bs(V_BS) + Q_bd(V_BD)

on the gate, channel and source-junction lines (a line's charge flows through its branch
into its + node), ``Q_bd`` on the drain junction's; ``(Q_g, Q_b, Q_d)`` are capMod 2's or
3's intrinsic charges, the overlaps ``Q_gso = (CGSO + CF) W_eff,CV V_GS`` (with CGSL's
bias-dependent part for capMod ≥ 1), the junction charges ngspice's depletion charge
(``MJ``, ``MJSW``, ``MJSWG`` on bottom, field-side and gate-side walls; linear in ``C``
above 0 V).
"""

from __future__ import annotations

from collections.abc import Mapping

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from . import _bsim3 as b3
from ._charge_port import ChargePortPart
from ._junction import depletion_charge
from ._mos_part import bulk_limits, law_vector, pins_and_kcl, polarity
from ._part import array_module, finite, positive, traced

__all__ = ["BSIM3", "bsim3_current"]


def _overlap(v, cgo, weffcv, cgl, ckappa, capmod, off=None):
    """The overlap charge ``Q_gxo(V)`` (``b3ld.c``): ``cgo·V`` for capMod 0; with CGSL/CGDL
    the lightly doped overlap's ``−W CGL κ/2 (√(1 − 4V/κ) − 1)`` below 0 (capMod 1) or
    its smoothed form (capMod 2, 3). ``off``: CGL is a known 0 (decided from ``cgl``'s
    value when not given)."""
    if off is None:
        off = isinstance(cgl, float) and cgl == 0.0
    if capmod == 0 or off:
        return cgo * v
    t3 = weffcv * cgl
    if capmod == 1:
        neg = v < 0.0
        t1 = jnp.sqrt(1.0 - 4.0 * jnp.minimum(v, 0.0) / ckappa)
        return jnp.where(neg, cgo * v - 0.5 * t3 * ckappa * (t1 - 1.0), (t3 + cgo) * v)
    t0 = v + 0.02
    t2 = 0.5 * (t0 - jnp.sqrt(t0 * t0 + 0.08))
    t4 = jnp.sqrt(1.0 - 4.0 * t2 / ckappa)
    return (cgo + t3) * v - t3 * (t2 + 0.5 * ckappa * (t4 - 1.0))


def _junction_form(i_s, nvtm, ijth):
    """The bulk diode's form and its constants, decided once: ``("off", 0, 0)`` for
    ``I_S ≤ 0`` (G_min alone), ``("plain", 0, 0)`` for IJTH = 0 (no continuation), else
    ``("limited", V_jsm, I_S e^{V_jsm/N V_t})``."""
    if isinstance(i_s, float) and i_s <= 0.0:
        return "off", 0.0, 0.0
    if isinstance(ijth, float) and ijth == 0.0:
        return "plain", 0.0, 0.0
    xp = array_module(i_s, nvtm, ijth)
    vjm = nvtm * xp.log(ijth / i_s + 1.0)
    return "limited", vjm, i_s * xp.exp(vjm / nvtm)


def _junction(v, form, i_s, nvtm, ijth, vjm, is_evjm, gmin, revision):
    """ngspice's BSIM3 bulk diode (module docstring) with ``G_min``, in the ``form`` of
    :func:`_junction_form`."""
    if form == "off":
        return gmin * v
    if form == "plain":
        return i_s * jnp.expm1(v / nvtm) + gmin * v
    below = i_s * jnp.expm1(jnp.minimum(v, vjm) / nvtm)
    if revision >= 322:
        above = is_evjm - i_s + is_evjm / nvtm * (v - vjm)
    else:
        above = ijth + (i_s + ijth) / nvtm * (v - vjm)
    return jnp.where(v < vjm, below, above) + gmin * v


def _mode(vgs, vds, vbs, sign):
    """NMOS-oriented ``(V_GS, V_DS, V_BS)`` of the mode and whether it is forward."""
    gs, ds, bs = sign * vgs, sign * vds, sign * vbs
    forward = ds >= 0.0
    return jnp.where(forward, gs, gs - ds), jnp.abs(ds), jnp.where(forward, bs, bs - ds), forward


def bsim3_current(params: dict, kind: str, vgs, vds, vbs, mobmod=1):
    """The channel current into the drain for true (signed) terminal voltages of a
    device with :func:`~diracvi.components._bsim3.size_dependent`'s ``params``."""
    sign = polarity("bsim3_current", kind)
    g, d, b, fwd = _mode(vgs, vds, vbs, sign)
    i = b3.evaluate(params, g, d, b, mobmod=mobmod)[0]
    return sign * jnp.where(fwd, i, -i)


def _known(x, value: float) -> bool:
    """``x`` is a number (not traced) equal to ``value``."""
    return not traced(x) and float(np.asarray(x)) == value


class _Lagrangian(eqx.Module):
    """``L = Σ w_b q̇_b`` over the flux-form branches ``(charge, flux)`` (coordinate
    indices): each line's ``ẇ`` is its branch voltage."""

    pairs: tuple = eqx.field(static=True)

    def __call__(self, q, v):
        return sum(q[j] * v[i] for i, j in self.pairs)


class _Named(Mapping):
    """The numbers of a :class:`_Law` by name (``numbers[k]`` read when asked for), with
    the static ``branches`` and ``revision`` that :func:`~._bsim3.evaluate` reads."""

    def __init__(self, layout: dict, numbers):
        self._index = {k: j for j, k in enumerate(layout["names"])}
        self._numbers = numbers
        self._static = {"branches": layout["form"], "revision": layout["revision"]}

    def __getitem__(self, key):
        if key in self._static:
            return self._static[key]
        return self._numbers[self._index[key]]

    def __contains__(self, key) -> bool:
        return key in self._static or key in self._index

    def __iter__(self):
        return iter((*self._static, *self._index))

    def __len__(self) -> int:
        return len(self._static) + len(self._index)


class _Law(eqx.Module):
    r"""The part's force ``F(q, v)`` or charge ``Q(q, v)`` (``what``; the module
    docstring's) as data: ``layout`` is everything decided in Python when the part is
    built — its coordinates, polarity, capMod, mobMod, XPART, VERSION, the forms of
    :func:`~._bsim3.branches`, which junction, overlap and resistor terms are on, the
    names of the numbers — as ``(name, value)`` pairs (hashable: static), ``numbers``
    one float64 vector (the size-dependent parameters, M, GMIN, the junctions' and
    resistors' values). Parts of equal layouts are one function of different vectors:
    its form is read once per layout (:func:`~diracvi.model.system._user_function`), not
    traced per device, and alike devices stack into one ``vmap``."""

    what: str = eqx.field(static=True)
    layout: tuple = eqx.field(static=True)
    numbers: jax.Array

    def __call__(self, q, v):
        layout = dict(self.layout)
        p = _Named(layout, self.numbers)
        idx = {c: j for j, c in enumerate(layout["coords"])}
        return (_force if self.what == "force" else _charge)(layout, p, idx, q, v)


def _force(layout, p, idx, q, v):
    """``F``: minus the channel, junction (with I_sub) and resistor currents (×M)."""
    sign, mult, g, rev = layout["sign"], p["mult"], p["gmin"], layout["revision"]
    vgs, vds, vbs, vbd = v[idx["wg"]], v[idx["w"]], v[idx["wbs"]], v[idx["wbd"]]
    gm, dm, bm, fwd = _mode(vgs, vds, vbs, sign)
    ids, isub, _ = b3.evaluate(p, gm, dm, bm, mobmod=layout["mobmod"])
    i_ch = sign * jnp.where(fwd, ids, -ids)
    i_sub = sign * isub  # from the mode's drain into the bulk
    f = jnp.zeros(len(idx), dtype=v.dtype)
    f = f.at[idx["w"]].set(-mult * i_ch)
    bulk = {}
    for k, form in layout["junctions"]:
        vb = sign * (vbs if k == "s" else vbd)
        bulk[k] = sign * _junction(
            vb, form, p[f"isat_{k}"], p["nvtm"], p["ijth"], p[f"vjm_{k}"], p[f"isevjm_{k}"], g, rev
        )
    # I_sub leaves the mode's drain and enters the bulk: a b→(drain) branch current of −I_sub
    f = f.at[idx["wbs"]].set(-mult * (bulk["s"] - jnp.where(fwd, 0.0, i_sub)))
    f = f.at[idx["wbd"]].set(-mult * (bulk["d"] - jnp.where(fwd, i_sub, 0.0)))
    for k in layout["resistors"]:
        f = f.at[idx[f"qr{k}"]].set(-p[f"r_{k}"] / mult * v[idx[f"qr{k}"]])
    return f


def _charge(layout, p, idx, q, v):
    """``Q``: the terminal charges on the gate, channel and junction lines (×M)."""
    sign, capmod = layout["sign"], layout["capmod"]
    vgs, vds, vbs, vbd = v[idx["wg"]], v[idx["w"]], v[idx["wbs"]], v[idx["wbd"]]
    gm, dm, bm, fwd = _mode(vgs, vds, vbs, sign)
    _, _, intrinsic = b3.evaluate(
        p, gm, dm, bm, mobmod=layout["mobmod"], capmod=capmod, xpart=layout["xpart"],
        charges_only=True,
    )  # fmt: skip
    vgd, vgb = vgs - vds, vgs - vbs
    off_s, off_d = layout["overlap_off"]
    qgso = _overlap(sign * vgs, p["cgso_eff"], p["weffcv"], p["cgsl"], p["ckappa"], capmod, off_s)
    qgdo = _overlap(sign * vgd, p["cgdo_eff"], p["weffcv"], p["cgdl"], p["ckappa"], capmod, off_d)
    qgbo = p["cgbo_eff"] * sign * vgb
    if intrinsic is None:
        qg = qb = qd = 0.0 * vgs
    else:
        qg, qb, qmode = intrinsic
        qd = jnp.where(fwd, qmode, -(qg + qb + qmode))  # swapped: the mode's Q_d is Q_s
    junction = {"s": 0.0 * vbs, "d": 0.0 * vbd}
    for k, j in layout["caps"]:
        vn = sign * (vbs if k == "s" else vbd)
        junction[k] = junction[k] + depletion_charge(
            vn, p[f"c{j}_{k}"], p[f"pb{j}_{k}"], p[f"mj{j}_{k}"], 0.0
        )
    out = jnp.zeros(len(idx), dtype=v.dtype)
    out = out.at[idx["wg"]].set(sign * (qg + qgso + qgdo + qgbo))
    out = out.at[idx["w"]].set(sign * (qd - qgdo))
    out = out.at[idx["wbs"]].set(sign * (qb - qgbo + junction["s"]))
    # Q_bd on b→d′: on the bulk, off the drain (Q_D = Q_d − Q_gdo − Q_bd)
    return p["mult"] * out.at[idx["wbd"]].set(sign * junction["d"])


_INSTANCE = {"ad": 0.0, "as_": 0.0, "pd": 0.0, "ps": 0.0, "nrd": 1.0, "nrs": 1.0, "m": 1.0,
             "delvto": 0.0, "mulu0": 1.0}  # fmt: skip


def initial_velocities(where: str, v0, idx: dict, n: int) -> np.ndarray:
    """The part's initial velocities from ``v0 = (V_GS, V_GD, V_GB)``: ``wg = V_GS``,
    ``w = V_GS − V_GD`` (V_DS), ``wbs = V_GS − V_GB``, ``wbd = V_GD − V_GB``, the rest 0;
    ``v0`` that is not three finite voltages is refused, naming the part."""
    vg0 = np.asarray(v0, dtype=np.float64).reshape(-1)
    if vg0.shape != (3,) or not np.all(np.isfinite(vg0)):
        raise ModelError(f"{where}: v0={v0!r} must be three finite voltages (V_GS, V_GD, V_GB).")
    initial_v = np.zeros(n)
    initial_v[idx["wg"]] = vg0[0]
    initial_v[idx["w"]] = vg0[0] - vg0[1]
    initial_v[idx["wbs"]] = vg0[0] - vg0[2]
    initial_v[idx["wbd"]] = vg0[1] - vg0[2]
    return initial_v


def BSIM3(
    kind="nmos",
    *,
    w=5e-6,
    l=5e-6,  # noqa: E741  (SPICE's name)
    name: str,
    version="3.3.0",
    gmin=1e-12,
    v0=(0.0, 0.0, 0.0),
    model: dict | None = None,
    **instance,
) -> ChargePortPart:
    r"""A BSIM3v3 MOSFET with pins ``d g s b`` (module docstring) of drawn ``w`` × ``l``
    (m; ngspice's defaults 5 µm), its card's **given** parameters ``model`` (ngspice's
    lower-case names, :data:`~diracvi.components._bsim3.NAMES`: ``{"vth0": 0.38, "tox":
    4.1e-9, …}``; what is absent takes ngspice's default or is derived as ``b3set.c`` and
    ``b3temp.c`` derive it), ``version`` the card's VERSION (3.3.0, or 3.2, 3.2.2, 3.2.3,
    3.2.4), and the line's ``ad``, ``as_``, ``pd``, ``ps`` (m², m), ``nrd``, ``nrs``
    (squares, default 1), ``m``, ``delvto``, ``mulu0``. The card's values may be traced
    JAX values. Simulated at the card's TNOM (27 °C unless given); capMod 2 and 3 (3 the
    default), NQSMOD = 0, ACM = 0: others are refused. ``m`` devices in parallel scale
    every current and charge by ``m`` and divide RD, RS by it, as ngspice's stamps do."""
    where = f"BSIM3 {name!r}"
    sign = polarity(where, kind)
    unknown = sorted(set(instance) - set(_INSTANCE))
    if unknown:
        raise TypeError(f"BSIM3() got an unexpected keyword argument {unknown[0]!r}")
    inst = _INSTANCE | instance
    card = dict(model or {})
    bad = sorted(set(card) - b3.NAMES)
    if bad:
        raise ModelError(f"{where}: {bad[0]!r} is not a BSIM3 model parameter of ngspice.")
    revision = b3.version_code(version)
    m = {k: card.get(k, x) for k, x in b3.MODEL.items()}
    for key, allowed in (("capmod", (2.0, 3.0)), ("nqsmod", (0.0,)), ("acnqsmod", (0.0,)),
                         ("acm", (0.0,)), ("mobmod", (1.0, 2.0, 3.0))):  # fmt: skip
        if float(m[key]) not in allowed:
            raise ModelError(
                f"{where}: {key.upper()}={m[key]:g} is not supported; diracvi's BSIM3 has "
                f"{key.upper()} = {', '.join(f'{a:g}' for a in allowed)}."
            )
    mult = positive(where, "m", inst["m"])  # M devices in parallel: ngspice scales every stamp
    w, l = positive(where, "w", w), positive(where, "l", l)  # noqa: E741
    p = b3.size_dependent(card, sign, l, w, inst["delvto"], inst["mulu0"], revision)
    m = p["model"]  # the card's model parameters with their derived defaults
    capmod, mobmod, xpart = int(m["capmod"]), int(m["mobmod"]), float(m["xpart"])
    g = positive(where, "gmin", gmin)
    # the junctions: saturation currents, zero-bias capacitances (b3temp.c, b3ld.c)
    nvtm = p["vtm"] * m["nj"]
    area = {"d": finite(where, "ad", inst["ad"]), "s": finite(where, "as_", inst["as_"])}
    perim = {"d": finite(where, "pd", inst["pd"]), "s": finite(where, "ps", inst["ps"])}
    i_sat, caps = {}, {}
    weff = float(p["weff"])
    for k in "ds":
        if area[k] <= 0.0 and perim[k] <= 0.0:
            i_sat[k] = 1.0e-14
        else:
            i_sat[k] = area[k] * m["js"] + perim[k] * m["jsw"]
        bottom = m["cj"] * area[k]
        if perim[k] < weff:
            side, gate_side = 0.0, m["cjswg"] * perim[k]
        else:
            side, gate_side = m["cjsw"] * (perim[k] - weff), m["cjswg"] * weff
        caps[k] = ((bottom, m["pb"], m["mj"]), (side, m["pbsw"], m["mjsw"]),
                   (gate_side, m["pbswg"], m["mjswg"]))  # fmt: skip
    for pb_name in ("pb", "pbsw", "pbswg"):
        if m[pb_name] < 0.1:
            raise ModelError(f"{where}: {pb_name.upper()}={m[pb_name]:g} must be ≥ 0.1 V.")
    res = {"d": m["rsh"] * inst["nrd"], "s": m["rsh"] * inst["nrs"]}
    for k, r in res.items():
        if r < 0.0:
            raise ModelError(f"{where}: RSH·NR{k.upper()} = {r:g} Ω must be ≥ 0.")

    inner = {k: k.upper() if res[k] > 0.0 else k for k in "ds"}
    branches = {
        "ch": (("q", "w"), inner["d"], inner["s"]),
        "gs": (("sg", "wg"), "g", inner["s"]),
        "bs": (("qbs", "wbs"), "b", inner["s"]),
        "bd": (("qbd", "wbd"), "b", inner["d"]),
    }
    for k in "ds":
        if res[k] > 0.0:
            branches[f"r{k}"] = ((f"qr{k}",), k, inner[k])
    coords = [c for names, _, _ in branches.values() for c in names]
    idx = {c: j for j, c in enumerate(coords)}
    internal = [inner[k] for k in "ds" if res[k] > 0.0]
    pins, rows = pins_and_kcl(branches, idx, internal)

    # Everything decided in Python is the laws' static layout, every number one vector:
    # alike devices (one card kind, the same forms, other W, L, AD, …) are then one
    # function of different numbers — traced once per kind when read, stacked and
    # stepped with one vmap per kind (model/stacked.py) when run.
    numbers = {k: x for k, x in p.items() if k not in ("model", "revision")}
    numbers.update(mult=mult, gmin=g, nvtm=nvtm, ijth=m["ijth"])
    junction_forms, present = [], []
    for k in "ds":
        form, vjm, is_evjm = _junction_form(i_sat[k], nvtm, m["ijth"])
        junction_forms.append((k, form))
        numbers.update({f"isat_{k}": i_sat[k], f"vjm_{k}": vjm, f"isevjm_{k}": is_evjm})
        # a wall's term is on unless the card's coefficient is a known 0 (CJ, CJSW,
        # CJSWG: the card's choice); a device whose area or perimeter leaves it 0 carries
        # it at C = 0, which adds exactly 0, so other sizes stay one kind of part — but
        # for a grading of 1, whose charge divides by 1 − M (0/0 at C = 0: ngspice skips
        # a wall of zero size)
        for j, (c, pb, mj) in enumerate(caps[k]):
            coefficient = m[("cj", "cjsw", "cjswg")[j]]
            known_zero = isinstance(coefficient, float) and coefficient == 0.0
            if not known_zero and not (_known(mj, 1.0) and _known(c, 0.0)):
                present.append((k, j))
                numbers.update({f"c{j}_{k}": c, f"pb{j}_{k}": pb, f"mj{j}_{k}": mj})
        if res[k] > 0.0:
            numbers[f"r_{k}"] = res[k]
    names = tuple(numbers)
    layout = (
        ("coords", tuple(coords)),
        ("sign", sign),
        ("capmod", capmod),
        ("mobmod", mobmod),
        ("xpart", xpart),
        ("revision", revision),
        ("form", b3.branches(p)),
        ("junctions", tuple(junction_forms)),
        ("caps", tuple(present)),
        ("resistors", tuple(k for k in "ds" if res[k] > 0.0)),
        ("overlap_off", tuple(isinstance(p[c], float) and p[c] == 0.0 for c in ("cgsl", "cgdl"))),
        ("names", names),
    )
    vector = law_vector(numbers, names)
    pairs = tuple((idx[ns[0]], idx[ns[1]]) for ns, _, _ in branches.values() if len(ns) == 2)

    initial_v = initial_velocities(where, v0, idx, len(coords))
    junctions, limits = bulk_limits(sign, {"wbs": 1.0e-14, "wbd": 1.0e-14})
    return ChargePortPart(
        tuple(coords),
        _Lagrangian(pairs),
        force=_Law("force", layout, vector),
        charge=_Law("charge", layout, vector),
        junctions=junctions,
        junction_limits=limits,
        constraints=np.array(rows) if rows else None,
        constraint_names=tuple(f"KCL({n.lower()}')" for n in internal) if rows else None,
        name=name,
        pins=tuple(pins),
        currents=(),
        initial_v=initial_v,
        role="transistor",
        branch_roles=(("sg", "current"),),
        # (no parameter table: a part's table is static data, so recording W, L or the
        # card's numbers there would keep devices of other sizes or of a Monte-Carlo
        # card's variants apart — they are the laws' numbers; only K reads a table)
        parameters=(),
    )
