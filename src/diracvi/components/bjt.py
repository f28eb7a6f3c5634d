r"""The Gummel–Poon bipolar transistor (SPICE ``Q``, ngspice's level 1) as a Lagrange–Dirac part.

With ``type`` = +1 (NPN) or −1 (PNP) and the internal junction voltages
``V_BE = type·(φ_b′ − φ_e′)``, ``V_BC = type·(φ_b′ − φ_c′)`` (ngspice's ``bjtload``):

    I_be = I_S (e^{V_BE/(N_F V_T)} − 1),        I_bc = I_S (e^{V_BC/(N_R V_T)} − 1)
    I_ben = I_SE (e^{V_BE/(N_E V_T)} − 1) + G_min V_BE,   I_bcn likewise (I_SC, N_C)
    q_1 = 1 / (1 − V_BC/V_AF − V_BE/V_AR)                      (Early effect)
    q_b = q_1 (1 + √(1 + 4 (I_be/I_KF + I_bc/I_KR)))/2        (high injection)
    I_C = (I_be − I_bc)/q_b − I_bc/B_R − I_bcn,   I_B = I_be/B_F + I_ben + I_bc/B_R + I_bcn

(each exponential with ngspice's reverse branch below ``−3 N V_T``). ``V_AF``, ``V_AR``,
``I_KF``, ``I_KR`` = 0 or ``None`` mean infinity, as in ngspice.

**Lagrange–Dirac form.** Three voltage-controlled branches in flux form (``L = w q̇``
each, as :mod:`~diracvi.components.diode`): ``be`` (b′→e′) carrying ``I_be/B_F + I_ben``,
``bc`` (b′→c′) carrying ``I_bc/B_R + I_bcn``, and the transport branch ``ce`` (c′→e′)
carrying ``(I_be − I_bc)/q_b`` (a PNP's three point the other way, so that every flux
velocity is a type-normalised voltage and SPICE's ``pnjlim`` limits ``ẇ_be``, ``ẇ_bc``
between Newton iterates as it limits a diode's), a force ``F_w = −I(ẇ_be, ẇ_bc)`` that
depends on *other* branches' flux velocities (non-reciprocal, like a VCCS). A substrate
branch (to c′ for NPN, b′ for PNP, as ngspice's default vertical/lateral layout) carries ngspice's
``G_min`` leak. ``RB``, ``RC``, ``RE`` > 0 are resistor branches (``F = −R q̇``) to
internal nodes ``b′ c′ e′`` whose KCL rows are the part's own constraints ``A q̇ = 0``.
Junction capacitances ``CJE``, ``CJC`` (ngspice's depletion charge with ``FC``), the
substrate capacitance ``CJS`` (``VJS``, ``MJS``; ngspice's form, the depletion charge
with ``FC = 0``) and the diffusion charges ``TF·I_be``, ``TR·I_bc`` enter the Lagrangian
as co-energies of the flux velocity, ``C*(ẇ)`` with ``∂C*/∂ẇ = Q(ẇ)``: the ``w``-line then
reads ``q̇ = i + dQ/dt``, and the energy ``⟨p, v⟩ − L`` contains the stored ``∫V dQ``.

Gummel–Poon's full base–emitter diffusion charge (ngspice's)

    Q_F = TF · I_be (1 + XTF e^{V_BC/(1.44 VTF)} (I_be/(I_be + ITF))²) / q_b

depends on both junction voltages, and ``∂Q_F/∂V_BC ≠ ∂Q_BC/∂V_BE``: it is no co-energy's
gradient, so no Lagrangian gives it. When ``q_b`` varies (``VAF``, ``VAR``, ``IKF``, ``IKR``)
or ``XTF ≠ 0`` it enters through a charge port (:class:`~._charge_port.ChargePortPart`):
the ``w_be`` momentum is ``∂L/∂ẇ_be + type·Q_F``, and its current ``dQ_F/dt`` is integrated
as SPICE integrates a charge (the module ``_charge_port`` derives the discrete pair and
``docs/circuits.md`` the power balance). Otherwise ``Q_F = TF·I_be`` stays in ``L``.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._charge_port import ChargePortPart
from ._junction import THERMAL_VOLTAGE, depletion_coenergy, diffusion_coenergy, pn_current
from ._part import array_module, finite, positive
from .controlled import ControlledPart, coefficient

KINDS = {"npn": 1.0, "pnp": -1.0}


def _inverse(where, arg, value):
    """``1/value`` with 0, ``None`` and ``inf`` meaning an infinite value (ngspice)."""
    if value is None or (isinstance(value, float) and math.isinf(value)):
        return 0.0
    x = coefficient(where, arg, value)
    if isinstance(x, float) and x < 0.0:
        raise ModelError(f"{where}: {arg}={value!r} must be ≥ 0 (0 or None: infinite).")
    return 0.0 if isinstance(x, float) and x == 0.0 else 1.0 / x


def gummel_poon(vbe, vbc, p):
    """``(I_C, I_B, I_be/B_F + I_ben, I_bc/B_R + I_bcn, transport)`` for type-normalised
    junction voltages and the parameter dict ``p`` (area already applied)."""
    ibe = pn_current(vbe, p["is"], p["nf"])
    ibc = pn_current(vbc, p["is"], p["nr"])
    iben = pn_current(vbe, p["ise"], p["ne"]) + p["gmin"] * vbe
    ibcn = pn_current(vbc, p["isc"], p["nc"]) + p["gmin"] * vbc
    qb = base_charge(vbe, vbc, ibe, ibc, p)
    transport = (ibe - ibc) / qb
    base_emitter = ibe / p["bf"] + iben
    base_collector = ibc / p["br"] + ibcn
    return (
        transport - base_collector,
        base_emitter + base_collector,
        base_emitter,
        base_collector,
        transport,
    )


def base_charge(vbe, vbc, ibe, ibc, p):
    r"""Gummel–Poon's normalised base charge ``q_b = q_1 (1 + √(1 + 4 q_2))/2``."""
    q1 = 1.0 / (1.0 - vbc * p["ova"] - vbe * p["ovb"])
    if p["oik"] == 0.0 and p["oikr"] == 0.0:
        return q1
    q2 = p["oik"] * ibe + p["oikr"] * ibc
    return q1 * (1.0 + jnp.sqrt(jnp.maximum(1.0 + 4.0 * q2, 0.0))) / 2.0


def base_resistance(vbe, vbc, p, rb, rbm, irb):
    r"""ngspice's bias-dependent base resistance ``r_bb`` (``bjtload.c``, area applied):

        IRB = 0:  r_bb = RBM + (RB − RBM)/q_b
        IRB > 0:  r_bb = RBM + 3 (RB − RBM) (tan z − z)/(z tan² z),
                  z = (√(1 + 14.59025 x) − 1)/(2.4317 √x),   x = max(I_B/IRB, 10⁻⁹)

    with ``q_b`` Gummel–Poon's base charge and ``I_B`` the static base current at the
    internal junction voltages (``x`` ≥ 10⁻⁹ keeps ``z`` > 0; ``(tan z − z)/(z tan² z)`` →
    1/3 as ``z`` → 0, so ``r_bb`` → ``RB`` at small currents)."""
    if irb == 0.0:
        ibe = pn_current(vbe, p["is"], p["nf"])
        ibc = pn_current(vbc, p["is"], p["nr"])
        return rbm + (rb - rbm) / base_charge(vbe, vbc, ibe, ibc, p)
    i_b = gummel_poon(vbe, vbc, p)[1]
    x = jnp.maximum(i_b / irb, 1e-9)
    z = (jnp.sqrt(1.0 + 14.59025 * x) - 1.0) / (2.4317 * jnp.sqrt(x))
    t = jnp.tan(z)
    return rbm + 3.0 * (rb - rbm) * (t - z) / (z * t * t)


def forward_diffusion_charge(vbe, vbc, p):
    r"""ngspice's base–emitter diffusion charge ``Q_F(V_BE, V_BC)`` (type-normalised),
    ``TF·I_be (1 + arg_tf)/q_b`` with ``arg_tf = XTF e^{V_BC/(1.44 VTF)} (I_be/(I_be + ITF))²``.

    ngspice switches to the plain ``TF·I_be`` for ``V_BE ≤ 0``; there ``|I_be| ≤ I_S`` and
    the two differ by at most ``TF·I_S·|1 − (1 + arg_tf)/q_b|`` (~10⁻²⁴ C for common
    values), far below any charge the circuit moves. One formula everywhere keeps
    ``∂Q_F/∂V_BC`` structurally present: a ``jnp.where`` would hide it from the
    Jacobian's sparsity pattern (:mod:`diracvi.solvers.sparsity`) at sample points with
    ``V_BE ≤ 0``."""
    ibe = pn_current(vbe, p["is"], p["nf"])
    ibc = pn_current(vbc, p["is"], p["nr"])
    argtf = p["xtf"] * jnp.exp(vbc * p["ovtf"]) if p["ovtf"] != 0.0 else p["xtf"] + 0.0 * vbc
    if p["itf"] != 0.0:
        share = ibe / (ibe + p["itf"])
        argtf = argtf * share * share
    return p["tf"] * ibe * (1.0 + argtf) / base_charge(vbe, vbc, ibe, ibc, p)


def BJT(
    kind="npn",
    *,
    is_=1e-16,
    bf=100.0,
    br=1.0,
    nf=1.0,
    nr=1.0,
    vaf=None,
    var=None,
    ikf=None,
    ikr=None,
    ise=0.0,
    ne=1.5,
    isc=0.0,
    nc=2.0,
    rb=0.0,
    rc=0.0,
    re=0.0,
    cje=0.0,
    vje=0.75,
    mje=0.33,
    cjc=0.0,
    vjc=0.75,
    mjc=0.33,
    tf=0.0,
    tr=0.0,
    xtf=0.0,
    vtf=None,
    itf=0.0,
    cjs=0.0,
    vjs=0.75,
    mjs=0.0,
    fc=0.5,
    area=1.0,
    gmin=1e-12,
    v0=(0.0, 0.0),
    name: str,
    xcjc=1.0,
    rbm=None,
    irb=0.0,
    iss=0.0,
    ns=1.0,
) -> ControlledPart:
    r"""A Gummel–Poon BJT with pins ``c b e s`` (substrate ``s``: ground it when unused).

    Defaults as ngspice's manual (``IS = 1e-16`` A, ``BF = 100``, ``BR = 1``, ``NE = 1.5``,
    ``NC = 2``, ``VJE = VJC = VJS = 0.75`` V, ``MJE = MJC = 0.33``, ``MJS = 0``, ``FC = 0.5``,
    ``VTF = ∞``). ``is_``, ``bf``, ``br`` and ``tf`` may be traced JAX values.
    ``v0 = (V_BE, V_BC[, V_sub])``: the initial junction voltages (they set the initial
    junction charges when ``CJE``/``CJC``/``CJS``/``TF``/``TR`` ≠ 0); ``V_sub = φ_s − φ_c′``
    (NPN) or ``φ_s − φ_b′`` (PNP), 0 V when not given.

    ``xcjc``: the fraction of ``CJC`` between the internal base ``b′`` and ``c′``; the rest,
    ``(1 − XCJC)·CJC``, sits between the external base ``b`` and ``c′`` (ngspice's ``qbx``
    at ``V_BX = type·(φ_b − φ_c′)``, no diffusion charge), a branch ``bx`` carrying only that
    charge; with ``RB = 0`` the two bases are one node and the split changes nothing.
    ``rbm``, ``irb``: the bias-dependent base resistance (:func:`base_resistance`;
    ``rbm`` ``None``: ``RB``, a constant resistance). ``iss``, ``ns``: the substrate
    junction's current ``ISS·AREA (e^{V_sub/(NS V_T)} − 1)`` (ngspice's reverse branch below
    ``−3 NS V_T``) beside its ``G_min``, the junction limited as ngspice does when ``ISS`` is
    given.
    """
    where = f"BJT {name!r}"
    if kind not in KINDS:
        raise ModelError(f"{where}: kind={kind!r} must be 'npn' or 'pnp'.")
    sign = KINDS[kind]
    a = positive(where, "area", area)
    p = {
        "is": coefficient(where, "is_", is_) * a,
        "bf": coefficient(where, "bf", bf),
        "br": coefficient(where, "br", br),
        "nf": positive(where, "nf", nf),
        "nr": positive(where, "nr", nr),
        "ise": finite(where, "ise", ise) * a,
        "ne": positive(where, "ne", ne),
        "isc": finite(where, "isc", isc) * a,
        "nc": positive(where, "nc", nc),
        "ova": _inverse(where, "vaf", vaf),
        "ovb": _inverse(where, "var", var),
        "oik": _inverse(where, "ikf", ikf) / a,
        "oikr": _inverse(where, "ikr", ikr) / a,
        "gmin": positive(where, "gmin", gmin),
        "tf": coefficient(where, "tf", tf),
        "xtf": finite(where, "xtf", xtf),
        "ovtf": _inverse(where, "vtf", vtf) / 1.44,  # ngspice's 1/(1.44 VTF)
        "itf": finite(where, "itf", itf) * a,
    }
    if not all(isinstance(p[k], float) for k in ("ova", "ovb", "oik", "oikr", "ovtf")):
        raise ModelError(f"{where}: vaf, var, ikf, ikr, vtf must be plain numbers (not traced).")
    res = {k: finite(where, k, x) / a for k, x in (("rb", rb), ("rc", rc), ("re", re))}
    xcjc = finite(where, "xcjc", xcjc)
    if not 0.0 <= xcjc <= 1.0:
        raise ModelError(f"{where}: xcjc={xcjc!r} must lie in [0, 1] (a fraction of CJC).")
    base_r = {
        "rbm": res["rb"] if rbm is None else finite(where, "rbm", rbm) / a,
        "irb": finite(where, "irb", irb) * a,
    }
    if base_r["rbm"] < 0.0 or base_r["irb"] < 0.0:
        raise ModelError(f"{where}: rbm={rbm!r} and irb={irb!r} must be ≥ 0.")
    varying_rb = res["rb"] > 0.0 and base_r["rbm"] != res["rb"]
    substrate = (finite(where, "iss", iss) * a, positive(where, "ns", ns))
    if substrate[0] < 0.0:
        raise ModelError(f"{where}: iss={iss!r} must be ≥ 0.")
    junction = {
        "be": (
            finite(where, "cje", cje) * a,
            positive(where, "vje", vje),
            finite(where, "mje", mje),
        ),
        "bc": (
            finite(where, "cjc", cjc) * a,
            positive(where, "vjc", vjc),
            finite(where, "mjc", mjc),
        ),
    }
    junction["sub"] = (
        finite(where, "cjs", cjs) * a,
        positive(where, "vjs", vjs),
        finite(where, "mjs", mjs),
    )
    # XCJC < 1 with RB > 0: (1 − XCJC)·CJC moves to the external base (branch bx)
    split = res["rb"] > 0.0 and xcjc < 1.0 and junction["bc"][0] > 0.0
    if split:
        cjc_total, vjc_, mjc_ = junction["bc"]
        junction["bc"] = (cjc_total * xcjc, vjc_, mjc_)
        junction["bx"] = (cjc_total * (1.0 - xcjc), vjc_, mjc_)
    # the B-E diffusion charge is a co-energy's gradient only when q_b ≡ 1 and XTF = 0
    ported = _nonzero(p["tf"]) and (
        p["xtf"] != 0.0 or any(p[k] != 0.0 for k in ("ova", "ovb", "oik", "oikr"))
    )
    transit = {
        "be": 0.0 if ported else p["tf"],
        "bc": finite(where, "tr", tr),
        "sub": 0.0,
        "bx": 0.0,
    }
    fc = finite(where, "fc", fc)
    if min(res.values()) < 0.0 or min(c for c, _, _ in junction.values()) < 0.0:
        raise ModelError(f"{where}: rb, rc, re, cje, cjc, cjs must be ≥ 0.")
    if not 0.0 <= fc < 1.0 or not all(0.0 <= m < 1.0 for _, _, m in junction.values()):
        raise ModelError(f"{where}: fc, mje, mjc, mjs must lie in [0, 1).")
    if p["xtf"] < 0.0 or p["itf"] < 0.0:
        raise ModelError(f"{where}: xtf={xtf!r} and itf={itf!r} must be ≥ 0.")
    v0 = np.asarray(v0, dtype=np.float64).reshape(-1)
    if v0.shape not in ((2,), (3,)) or not np.all(np.isfinite(v0)):
        raise ModelError(
            f"{where}: v0={v0!r} must be two or three finite voltages (V_BE, V_BC[, V_sub])."
        )

    # branches: name -> (+ end, − end); internal nodes b′ c′ e′ are "B", "C", "E"
    # oriented so that every flux velocity is a type-normalised voltage (a PNP's branches
    # point the other way): ẇ_be = V_BE, ẇ_bc = V_BC, ẇ_ce = V_CE as ngspice's bjtload
    # uses them, and junction limiting sees forward bias as a positive velocity
    if kind == "npn":
        branches = {"be": ("B", "E"), "bc": ("B", "C"), "ce": ("C", "E")}
    else:
        branches = {"be": ("E", "B"), "bc": ("C", "B"), "ce": ("E", "C")}
    branches["sub"] = ("s", "C" if kind == "npn" else "B")
    if split:  # ẇ_bx = V_BX = type·(φ_b − φ_c′)
        branches["bx"] = ("b", "C") if kind == "npn" else ("C", "b")
    for k, (node, inner) in {"rb": ("b", "B"), "rc": ("c", "C"), "re": ("e", "E")}.items():
        if res[k] > 0.0:
            branches[k] = (node, inner)
    coords = []
    for k in branches:
        coords += [f"q{k}"] if k.startswith("r") else [f"q{k}", f"w{k}"]
    idx = {c: j for j, c in enumerate(coords)}
    outer = {"B": "b", "C": "c", "E": "e"}
    internal = [n for n in "BCE" if f"r{outer[n].lower()}" in branches]

    pins, rows = [], []
    for k, (plus, minus) in branches.items():
        for node, s in ((plus, 1), (minus, -1)):
            if node in internal:
                continue
            pins.append((outer.get(node, node), f"q{k}", s))
    for n in internal:
        row = np.zeros(len(coords))
        for k, (plus, minus) in branches.items():
            row[idx[f"q{k}"]] += (plus == n) - (minus == n)
        rows.append(row)

    charges = {
        k: (junction[k], transit[k], p["is"], p["nf" if k == "be" else "nr"])
        for k in ("be", "bc", "sub", "bx")
        if k in junction and (junction[k][0] > 0.0 or _nonzero(transit[k]))
    }

    def stored(vn, k):  # co-energy C*(V) of junction k (type-normalised V)
        (cj, vj, m), t, i_s, n = charges[k]
        grading = 0.0 if k == "sub" else fc  # ngspice's substrate charge: FC = 0
        out = depletion_coenergy(vn, cj, vj, m, grading) if cj > 0.0 else 0.0 * vn
        if _nonzero(t):
            out = out + diffusion_coenergy(vn, t, i_s, n)
        return out

    def lagrangian(q, v):
        out = sum(q[idx[f"w{k}"]] * v[idx[f"q{k}"]] for k in branches if f"w{k}" in idx)
        for k in charges:  # (the substrate's φ_s − φ_c′ (NPN) or φ_s − φ_b′ (PNP) as ngspice)
            out = out + stored(v[idx[f"w{k}"]], k)
        return out + 0.0 * v[0]

    def force(q, v):
        vbe, vbc = v[idx["wbe"]], v[idx["wbc"]]
        _, _, i_be, i_bc, i_ce = gummel_poon(vbe, vbc, p)
        f = jnp.zeros(len(coords), dtype=v.dtype)
        f = f.at[idx["wbe"]].set(-i_be)
        f = f.at[idx["wbc"]].set(-i_bc)
        f = f.at[idx["wce"]].set(-i_ce)
        vsub = v[idx["wsub"]]
        i_sub = p["gmin"] * vsub
        if substrate[0] > 0.0:
            i_sub = i_sub + pn_current(vsub, *substrate)
        f = f.at[idx["wsub"]].set(-i_sub)
        for k in ("rb", "rc", "re"):
            if k in branches:
                r = res[k]
                if k == "rb" and varying_rb:
                    r = base_resistance(vbe, vbc, p, res["rb"], **base_r)
                f = f.at[idx[f"q{k}"]].set(-r * v[idx[f"q{k}"]])
        return f

    initial_v = np.zeros(len(coords))
    initial_v[idx["wbe"]], initial_v[idx["wbc"]] = sign * v0[0], sign * v0[1]
    initial_v[idx["wce"]] = sign * (v0[0] - v0[1])
    if len(v0) == 3:
        initial_v[idx["wsub"]] = v0[2]
    if split:
        initial_v[idx["wbx"]] = sign * v0[1]  # V_BX = V_BC while no current flows in RB
    # SPICE's pnjlim on both junctions, with ngspice's BJT values: V_T (not N·V_T) and
    # V_crit = V_T ln(V_T/(√2 I_S))
    xp = array_module(p["is"])
    vcrit = THERMAL_VOLTAGE * xp.log(THERMAL_VOLTAGE / (math.sqrt(2.0) * p["is"]))
    row = xp.stack([xp.asarray(x, float) for x in (THERMAL_VOLTAGE, vcrit, np.inf)])
    limited, limit_rows = ("wbe", "wbc"), [row, row]
    if substrate[0] > 0.0:  # ngspice limits V_sub with V_T and ISS's own V_crit
        vcrit_sub = THERMAL_VOLTAGE * np.log(THERMAL_VOLTAGE / (math.sqrt(2.0) * substrate[0]))
        limited += ("wsub",)
        limit_rows.append(
            xp.stack([xp.asarray(x, float) for x in (THERMAL_VOLTAGE, vcrit_sub, np.inf)])
        )
    constraints = np.array(rows) if rows else None
    params = {"is": p["is"], "bf": p["bf"], "br": p["br"]}
    extra = {}
    if ported:

        def charge(q, v):  # the charge port: Q_F on the w_be line
            q_f = forward_diffusion_charge(v[idx["wbe"]], v[idx["wbc"]], p)
            return jnp.zeros(len(coords), dtype=v.dtype).at[idx["wbe"]].set(q_f)

        extra["charge"] = charge
    return (ChargePortPart if ported else ControlledPart)(
        tuple(coords),
        lagrangian,
        force=force,
        constraints=constraints,
        constraint_names=tuple(f"KCL({outer[n]}')" for n in internal) if rows else None,
        name=name,
        pins=tuple(pins),
        currents=(),
        initial_v=initial_v,
        role="transistor",
        branch_roles=(),
        junctions=limited,
        junction_limits=xp.stack(limit_rows),
        parameters={k: x for k, x in params.items() if isinstance(x, float)},
        **extra,
    )


def _nonzero(x) -> bool:
    """``x ≠ 0`` for a number; a traced value counts as nonzero (it is being varied)."""
    return not isinstance(x, float) or x != 0.0
