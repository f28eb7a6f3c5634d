r"""The junction FET (SPICE ``J``, ngspice's level 1: Shichman–Hodges with Parker and
Skellern's doping tail ``B``) as a Lagrange–Dirac part.

With ``type`` = +1 (NJF) or −1 (PJF), the internal voltages ``V_GS = type·(φ_g − φ_s′)``,
``V_GD = type·(φ_g − φ_d′)``, ``V_DS = V_GS − V_GD``, ``β`` = BETA·AREA and
``b = (1 − B)/(PB − VTO)`` (ngspice's ``jfetload``, ``jfettemp``), in the forward mode
``V_DS ≥ 0`` with ``V_GST = V_GS − VTO``:

    I_D = 0                                                         V_GST ≤ 0     (cutoff)
        = β (1 + λ V_DS) V_GST² (B + b V_GST)                        0 < V_GST < V_DS (saturation)
        = β (1 + λ V_DS) V_DS (V_DS (b V_DS − B) + V_GST (2B + 3b (V_GST − V_DS)))
                                                                    V_GST ≥ V_DS   (linear)

(``B = 1``: ``β(1 + λV_DS)V_GST²`` and ``β(1 + λV_DS)V_DS(2V_GST − V_DS)``, the classic
Shichman–Hodges law — ngspice's BETA is *not* halved). For ``V_DS < 0`` source and drain
swap roles: ``I_D(V_GS, V_GD) = −I_D(V_GD, V_GS)`` of the formula above. VTO is read in the
type-normalised frame (a PJF's VTO is negative like an NJF's). The gate–source and
gate–drain junctions are diodes, ``I = IS·AREA (e^{V/V_T} − 1) + G_min V`` with ngspice's
``−IS (1 + (3 V_T/(e V))³)`` below ``−3 V_T`` (emission coefficient 1: ngspice 39's JFET has
no ``N``); their depletion charges are ngspice's with the grading fixed at ½,
``Q = 2 PB C_J (1 − √(1 − V/PB))`` below ``FC·PB`` and its linear-capacitance continuation
above (FC limited to 0.95 as ngspice does). The parallel multiplier ``M`` scales every
current, charge and conductance, ``G_min`` included; ``AREA`` all but ``G_min``.

**Lagrange–Dirac form** (as :mod:`~diracvi.components.bjt`): three voltage-controlled
branches in flux form, ``L = w q̇`` each — the junctions ``gs`` (g→s′) and ``gd`` (g→d′)
and the channel ``ch`` (d′→s′), a PJF's pointing the other way so that every flux
velocity is a type-normalised voltage (``ẇ_gs = V_GS``: SPICE's ``pnjlim`` then limits
both junctions between Newton iterates as it does a diode's). The forces are
``F_w = −I(ẇ)``: the channel's depends on the junctions' flux velocities (non-reciprocal,
like a VCCS). The junction charges are co-energies of ``ẇ_gs``, ``ẇ_gd`` in ``L`` (each
depends on its own voltage only, so it is a Lagrangian's momentum). ``RD``, ``RS`` > 0 are
resistor branches to internal nodes ``d′``, ``s′`` with the part's own KCL rows. The power
of the forces, ``−I_D V_DS − I_GS V_GS − I_GD V_GD``, is minus what the device dissipates.
"""

from __future__ import annotations

import math

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._junction import THERMAL_VOLTAGE, depletion_coenergy, pn_current
from ._part import finite, positive
from .controlled import ControlledPart, coefficient

KINDS = {"njf": 1.0, "pjf": -1.0}


def _forward(vgs, vds, vto, beta, lambda_, b, bfac):
    """The drain current of the forward mode (``V_DS ≥ 0``), type-normalised."""
    vgst = vgs - vto
    betap = beta * (1.0 + lambda_ * vds)
    linear = betap * vds * (vds * (bfac * vds - b) + vgst * (2.0 * b + 3.0 * bfac * (vgst - vds)))
    saturation = betap * vgst * vgst * (b + bfac * vgst)
    on = jnp.where(vgst >= vds, linear, saturation)
    return jnp.where(vgst <= 0.0, 0.0 * vgst, on)


def channel_current(vgs, vgd, *, vto, beta, lambda_, b, pb, bfac=None):
    r"""The type-normalised channel current ``I_D(V_GS, V_GD)`` into ``d′`` and out of
    ``s′`` (module docstring), the source/drain swap for ``V_DS < 0`` included; ``bfac``
    the doping tail's ``(1 − B)/(PB − VTO)`` where it is not this ``pb``'s and ``vto``'s
    (away from TNOM ngspice keeps the card's)."""
    bfac = (1.0 - b) / (pb - vto) if bfac is None else bfac
    vds = vgs - vgd
    forward = vds >= 0.0
    i_f = _forward(vgs, jnp.maximum(vds, 0.0), vto, beta, lambda_, b, bfac)
    i_r = _forward(vgd, jnp.maximum(-vds, 0.0), vto, beta, lambda_, b, bfac)
    return jnp.where(forward, i_f, -i_r)


def gate_current(v, saturation_current, gmin, emission=1.0):
    """A gate junction's ``I_S (e^{V/V_T} − 1) + G_min V`` (ngspice's reverse branch);
    ``emission`` scales ``V_T`` (its ``V_T(T)/V_T(27 °C)`` away from 27 °C)."""
    return pn_current(v, saturation_current, emission, reverse="cubic") + gmin * v


def JFET(
    kind="njf",
    vto=-2.0,
    beta=1e-4,
    lambda_=0.0,
    *,
    b=1.0,
    is_=1e-14,
    rd=0.0,
    rs=0.0,
    cgs=0.0,
    cgd=0.0,
    pb=1.0,
    fc=0.5,
    area=1.0,
    m=1.0,
    gmin=1e-12,
    v0=(0.0, 0.0),
    bfac=None,
    emission=1.0,
    name: str,
) -> ControlledPart:
    r"""A JFET with pins ``d g s`` (SPICE ``J``; defaults as ngspice 39: ``VTO = −2`` V,
    ``BETA = 1e-4`` A/V², ``LAMBDA = 0``, ``B = 1``, ``IS = 1e-14`` A, ``PB = 1`` V,
    ``FC = 0.5``, ``RD = RS = CGS = CGD = 0``).

    ``kind`` is ``"njf"`` or ``"pjf"``; ``area`` the instance's area factor, ``m`` its
    parallel multiplier. ``vto``, ``beta``, ``lambda_`` and ``b`` may be traced JAX values
    (``jax.grad`` reaches them). ``v0 = (V_GS, V_GD)``: the initial gate voltages (the
    junction charges' initial values). Away from TNOM (the netlist reader's
    :func:`~diracvi.components._temperature.jfet`): ``bfac``, the doping tail's ``(1 −
    B)/(PB − VTO)`` at the card's values (``None``: from ``pb`` and ``vto``), and
    ``emission``, the gate junctions' ``V_T(T)/V_T(27 °C)``. See the module docstring for
    the equations.
    """
    where = f"JFET {name!r}"
    if kind not in KINDS:
        raise ModelError(f"{where}: kind={kind!r} must be 'njf' or 'pjf'.")
    sign = KINDS[kind]
    a = positive(where, "area", area) * positive(where, "m", m)
    law = {
        "vto": coefficient(where, "vto", vto),
        "beta": coefficient(where, "beta", beta) * a,
        "lambda_": coefficient(where, "lambda_", lambda_),
        "b": coefficient(where, "b", b),
        "pb": positive(where, "pb", pb),
    }
    if bfac is not None:
        law["bfac"] = bfac
    n_vt = positive(where, "emission", emission) * THERMAL_VOLTAGE
    i_s = finite(where, "is_", is_) * a
    g = positive(where, "gmin", gmin) * positive(where, "m", m)  # M scales GMIN, AREA not
    res = {"d": finite(where, "rd", rd) / a, "s": finite(where, "rs", rs) / a}
    caps = {"gs": finite(where, "cgs", cgs) * a, "gd": finite(where, "cgd", cgd) * a}
    fc = min(finite(where, "fc", fc), 0.95)  # ngspice limits FC to .95 (with a warning)
    if min(*res.values(), *caps.values(), i_s) < 0.0 or fc < 0.0:
        raise ModelError(f"{where}: is_, rd, rs, cgs, cgd and fc must be ≥ 0.")
    if bfac is None and isinstance(law["vto"], float) and law["vto"] == law["pb"]:
        raise ModelError(
            f"{where}: PB = VTO = {pb:g} V makes the doping tail's (1 − B)/(PB − VTO) 0/0 "
            "(ngspice's too); move PB or VTO."
        )
    v0 = np.asarray(v0, dtype=np.float64).reshape(-1)
    if v0.shape != (2,) or not np.all(np.isfinite(v0)):
        raise ModelError(f"{where}: v0={v0!r} must be two finite voltages (V_GS, V_GD).")

    # branches: name -> (+ end, − end), oriented so that every flux velocity is a
    # type-normalised voltage; "D", "S" are d′, s′ (the pins themselves without RD, RS)
    inner = {k: k.upper() if res[k] > 0.0 else k for k in "ds"}
    ends = {"gs": ("g", inner["s"]), "gd": ("g", inner["d"]), "ch": (inner["d"], inner["s"])}
    branches = {k: (e if sign > 0 else e[::-1]) for k, e in ends.items()}
    for k in "ds":
        if res[k] > 0.0:
            branches[f"r{k}"] = (k, inner[k])
    coords = []
    for k in branches:
        coords += [f"q{k}"] if k.startswith("r") else [f"q{k}", f"w{k}"]
    idx = {c: j for j, c in enumerate(coords)}
    internal = [inner[k] for k in "ds" if res[k] > 0.0]
    pins, rows = [], []
    for k, (plus, minus) in branches.items():
        for node, s in ((plus, 1), (minus, -1)):
            if node not in internal:
                pins.append((node, f"q{k}", s))
    for n in internal:
        row = np.zeros(len(coords))
        for k, (plus, minus) in branches.items():
            row[idx[f"q{k}"]] += (plus == n) - (minus == n)
        rows.append(row)
    charged = [k for k in ("gs", "gd") if caps[k] > 0.0]

    def lagrangian(q, v):
        out = sum(q[idx[f"w{k}"]] * v[idx[f"q{k}"]] for k in ("gs", "gd", "ch"))
        for k in charged:  # ngspice's gate charge: grading ½, its FC continuation
            out = out + depletion_coenergy(v[idx[f"w{k}"]], caps[k], law["pb"], 0.5, fc)
        return out + 0.0 * v[0]

    def force(q, v):
        vgs, vgd = v[idx["wgs"]], v[idx["wgd"]]
        f = jnp.zeros(len(coords), dtype=v.dtype)
        f = f.at[idx["wch"]].set(-channel_current(vgs, vgd, **law))
        f = f.at[idx["wgs"]].set(-gate_current(vgs, i_s, g, emission))
        f = f.at[idx["wgd"]].set(-gate_current(vgd, i_s, g, emission))
        for k in "ds":
            if res[k] > 0.0:
                f = f.at[idx[f"qr{k}"]].set(-res[k] * v[idx[f"qr{k}"]])
        return f

    initial_v = np.zeros(len(coords))
    initial_v[idx["wgs"]], initial_v[idx["wgd"]] = sign * v0[0], sign * v0[1]
    initial_v[idx["wch"]] = sign * (v0[0] - v0[1])
    # SPICE's pnjlim on both junctions with ngspice's JFET values: V_T and
    # V_crit = V_T ln(V_T/(√2 I_S)) (jfettemp), at the device's temperature
    vcrit = n_vt * math.log(n_vt / (math.sqrt(2.0) * i_s)) if i_s > 0 else 0.0
    row = np.asarray([n_vt, vcrit, np.inf])  # (NumPy: see _part.array_module)
    params = {"vto": law["vto"], "beta": law["beta"], "lambda": law["lambda_"], "b": law["b"]}
    return ControlledPart(
        tuple(coords),
        lagrangian,
        force=force,
        constraints=np.array(rows) if rows else None,
        constraint_names=tuple(f"KCL({n.lower()}')" for n in internal) if rows else None,
        name=name,
        pins=tuple(pins),
        currents=(),
        initial_v=initial_v,
        role="transistor",
        branch_roles=(),
        junctions=("wgs", "wgd"),
        junction_limits=np.stack([row, row]),
        parameters={k: x for k, x in params.items() if isinstance(x, float)},
    )
