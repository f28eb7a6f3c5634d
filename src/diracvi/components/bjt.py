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
carrying ``(I_be − I_bc)/q_b``, a force ``F_w = −I(ẇ_be, ẇ_bc)`` that depends on *other*
branches' flux velocities (non-reciprocal, like a VCCS). A substrate branch (to c′ for
NPN, b′ for PNP, as ngspice's default vertical/lateral layout) carries ngspice's
``G_min`` leak. ``RB``, ``RC``, ``RE`` > 0 are resistor branches (``F = −R q̇``) to
internal nodes ``b′ c′ e′`` whose KCL rows are the part's own constraints ``A q̇ = 0``.
Junction capacitances ``CJE``, ``CJC`` (ngspice's depletion charge with ``FC``) and the
diffusion charges ``TF·I_be``, ``TR·I_bc`` enter the Lagrangian as co-energies of the
flux velocity, ``C*(ẇ)`` with ``∂C*/∂ẇ = Q(ẇ)``: the ``w``-line then reads
``q̇ = i + dQ/dt``, and the energy ``⟨p, v⟩ − L`` contains the stored ``∫V dQ``.
Gummel–Poon's diffusion charge ``TF·I_be/q_b`` is not the momentum of any Lagrangian
unless ``q_b`` is constant (its mixed derivatives are not symmetric), so ``TF``/``TR`` need
``V_AF = V_AR = I_KF = I_KR = ∞``.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._junction import depletion_coenergy, diffusion_coenergy, pn_current
from ._part import finite, positive
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
    q1 = 1.0 / (1.0 - vbc * p["ova"] - vbe * p["ovb"])
    if p["oik"] == 0.0 and p["oikr"] == 0.0:
        qb = q1
    else:
        q2 = p["oik"] * ibe + p["oikr"] * ibc
        qb = q1 * (1.0 + jnp.sqrt(jnp.maximum(1.0 + 4.0 * q2, 0.0))) / 2.0
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
    fc=0.5,
    area=1.0,
    gmin=1e-12,
    v0=(0.0, 0.0),
    name: str,
) -> ControlledPart:
    r"""A Gummel–Poon BJT with pins ``c b e s`` (substrate ``s``: ground it when unused).

    Defaults as ngspice's manual (``IS = 1e-16`` A, ``BF = 100``, ``BR = 1``, ``NE = 1.5``,
    ``NC = 2``, ``VJE = VJC = 0.75`` V, ``MJE = MJC = 0.33``, ``FC = 0.5``). ``is_``, ``bf``
    and ``br`` may be traced JAX values. ``v0 = (V_BE, V_BC)``: the initial junction
    voltages (they set the initial junction charges when ``CJE``/``CJC``/``TF``/``TR`` ≠ 0).
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
    }
    if not all(isinstance(p[k], float) for k in ("ova", "ovb", "oik", "oikr")):
        raise ModelError(f"{where}: vaf, var, ikf, ikr must be plain numbers (not traced).")
    res = {k: finite(where, k, x) / a for k, x in (("rb", rb), ("rc", rc), ("re", re))}
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
    transit = {"be": finite(where, "tf", tf), "bc": finite(where, "tr", tr)}
    fc = finite(where, "fc", fc)
    if min(res.values()) < 0.0 or min(c for c, _, _ in junction.values()) < 0.0:
        raise ModelError(f"{where}: rb, rc, re, cje, cjc must be ≥ 0.")
    if not 0.0 <= fc < 1.0 or not all(0.0 <= m < 1.0 for _, _, m in junction.values()):
        raise ModelError(f"{where}: fc, mje, mjc must lie in [0, 1).")
    if any(t != 0.0 for t in transit.values()) and any(
        p[k] != 0.0 for k in ("ova", "ovb", "oik", "oikr")
    ):
        raise ModelError(
            f"{where}: tf/tr need vaf = var = ikf = ikr = ∞: Gummel–Poon's diffusion charge "
            "TF·I_be/q_b is not the momentum of a Lagrangian when q_b varies."
        )
    v0 = np.asarray(v0, dtype=np.float64).reshape(-1)
    if v0.shape != (2,) or not np.all(np.isfinite(v0)):
        raise ModelError(f"{where}: v0={v0!r} must be two finite voltages (V_BE, V_BC).")

    # branches: name -> (+ end, − end); internal nodes b′ c′ e′ are "B", "C", "E"
    branches = {"be": ("B", "E"), "bc": ("B", "C"), "ce": ("C", "E")}
    branches["sub"] = ("s", "C" if kind == "npn" else "B")
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
        for k in ("be", "bc")
        if junction[k][0] > 0.0 or transit[k] != 0.0
    }

    def stored(vn, k):  # co-energy C*(V) of junction k (type-normalised V)
        (cj, vj, m), t, i_s, n = charges[k]
        out = depletion_coenergy(vn, cj, vj, m, fc) if cj > 0.0 else 0.0 * vn
        if t != 0.0:
            out = out + diffusion_coenergy(vn, t, i_s, n)
        return out

    def lagrangian(q, v):
        out = sum(q[idx[f"w{k}"]] * v[idx[f"q{k}"]] for k in branches if f"w{k}" in idx)
        for k in charges:
            out = out + stored(sign * v[idx[f"w{k}"]], k)
        return out + 0.0 * v[0]

    def force(q, v):
        vbe, vbc = sign * v[idx["wbe"]], sign * v[idx["wbc"]]
        _, _, i_be, i_bc, i_ce = gummel_poon(vbe, vbc, p)
        f = jnp.zeros(len(coords), dtype=v.dtype)
        f = f.at[idx["wbe"]].set(-sign * i_be)
        f = f.at[idx["wbc"]].set(-sign * i_bc)
        f = f.at[idx["wce"]].set(-sign * i_ce)
        f = f.at[idx["wsub"]].set(-p["gmin"] * v[idx["wsub"]])
        for k in ("rb", "rc", "re"):
            if k in branches:
                f = f.at[idx[f"q{k}"]].set(-res[k] * v[idx[f"q{k}"]])
        return f

    initial_v = np.zeros(len(coords))
    initial_v[idx["wbe"]], initial_v[idx["wbc"]] = v0
    initial_v[idx["wce"]] = v0[0] - v0[1]
    constraints = np.array(rows) if rows else None
    params = {"is": p["is"], "bf": p["bf"], "br": p["br"]}
    return ControlledPart(
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
        parameters={k: x for k, x in params.items() if isinstance(x, float)},
    )
