r"""ngspice's level-1 MOSFET formulas beside the drain current: the process parameters and
Meyer's gate capacitances.

**Process parameters** (``mos1temp.c`` at the nominal 27 °C; ``TOX`` in m, ``U0`` in
cm²/V·s, ``NSUB`` in cm⁻³, ``NSS`` in cm⁻²; ``type`` = ±1 for NMOS/PMOS). With
``C'_ox = ε_ox/TOX`` (``ε_ox = 3.9 ε₀``), each of KP, PHI, GAMMA, VTO that the card does
not give is derived — KP whenever ``TOX`` is given, the others only with ``NSUB`` too:

    KP    = U0 · 10⁻⁴ · C'_ox                                   (U0 defaults to 600)
    PHI   = max(0.1, 2 V_T ln(NSUB·10⁶ / n_i)),  n_i = 1.45·10¹⁶ m⁻³
    GAMMA = √(2 ε_Si q NSUB·10⁶) / C'_ox                        (ε_Si = 11.7 ε₀)
    VTO   = V_FB + type (GAMMA √PHI + PHI)
    V_FB  = Φ_ms − NSS·10⁴ q / C'_ox,   Φ_ms = W_gate − (3.25 + E_g/2 + type PHI/2)
    W_gate = 3.2 (TPG = 0, aluminium);  3.25 + E_g/2 − type TPG E_g/2 (polysilicon)

``E_g = 1.16 − 7.02·10⁻⁴ T²/(T + 1108)`` eV and ``V_T`` at the model's TNOM (300.15 K by
default), TPG defaulting to 1; the temperature update from there is
:func:`diracvi.components._temperature.mos1`.

**Meyer's capacitances** (``DEVqmeyer``): with ``V_GST = V_GS − V_on`` and
``V_dsat = max(V_DSAT, 0.025 V)`` (ngspice's guard), in the NMOS-oriented forward mode
(the roles of source and drain swap for ``V_DS < 0``), ``C_ox = C'_ox W L_eff``:

    V_GST ≤ −Φ            C_GB = C_ox,               C_GS = C_GD = 0        (accumulation)
    −Φ < V_GST ≤ −Φ/2     C_GB = −C_ox V_GST/Φ,      C_GS = C_GD = 0        (depletion)
    −Φ/2 < V_GST ≤ 0      C_GB = −C_ox V_GST/Φ,      C_GS = C_ox (4 V_GST/(3Φ) + 2/3), C_GD = 0,
                          both scaled as in the linear region when V_DS < V_dsat
    V_GST > 0, V_DS ≥ V_dsat   C_GS = 2 C_ox/3,  C_GD = C_GB = 0                (saturation)
    V_GST > 0, V_DS < V_dsat   C_GS = ⅔ C_ox (1 − (V_dsat − V_DS)²/(2V_dsat − V_DS)²),
                               C_GD = ⅔ C_ox (1 − V_dsat²/(2V_dsat − V_DS)²)    (linear)

(ngspice's routine returns half of each; its transient adds the halves at the two ends
of a step: the trapezoidal mean of ``C(V)``.)
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from ..errors import ModelError
from ._junction import THERMAL_VOLTAGE

EPS0 = 8.854214871e-12  # F/m, ngspice's value
EPS_OX = 3.9 * EPS0
EPS_SI = 11.70 * EPS0
CHARGE = 1.6021766208e-19
NI = 1.45e16  # intrinsic carrier density of silicon, m⁻³
T_NOM = 300.15


def intrinsic_density(tnom: float) -> float:
    """The intrinsic density at the model's ``tnom`` (kelvin) as ``mos3temp`` takes it
    (levels 1 and 2 take :data:`NI`, the 300 K value):
    ``n_i(T) = NI (T/300)^1.5 exp(E_g(T)(1/300 − 1/T)/(2k/q))``."""
    gap = 1.16 - 7.02e-4 * tnom * tnom / (tnom + 1108.0)
    k_over_q = THERMAL_VOLTAGE / T_NOM
    return NI * (tnom / 300.0) ** 1.5 * math.exp(0.5 * gap * (1.0 / 300.0 - 1.0 / tnom) / k_over_q)


#: :func:`intrinsic_density` at ngspice's nominal 27 °C
NI_NOM = intrinsic_density(T_NOM)
MAGIC_VDS = 0.025


def process_parameters(
    sign: float, given: dict, where: str, tnom: float = T_NOM, ni: float = NI
) -> dict:
    """KP, PHI, GAMMA, VTO derived from ``TOX``, ``U0``, ``NSUB``, ``NSS``, ``TPG``
    (module docstring) where ``given`` lacks them; returns ``{"kp", "phi", "gamma",
    "vto", "cox"}`` with ``cox = C'_ox`` in F/m² (0 without ``TOX``). ``given`` maps
    ngspice's lower-case names to the card's values; ``V_T`` and ``E_g`` are taken at the
    model's ``tnom`` (kelvin), as ``mos1temp.c`` does; ``ni`` is the intrinsic density
    PHI's derivation and the ``NSUB`` check read (:data:`NI`, or level 3's
    :data:`NI_NOM`)."""
    vtnom = THERMAL_VOLTAGE * tnom / T_NOM
    gap = 1.16 - 7.02e-4 * tnom * tnom / (tnom + 1108.0)
    out = {k: given.get(k) for k in ("kp", "phi", "gamma", "vto")}
    defaults = {"kp": 2e-5, "phi": 0.6, "gamma": 0.0, "vto": 0.0}
    tox = given.get("tox", 0.0) or 0.0
    if tox < 0.0:
        raise ModelError(f"{where}: TOX={tox:g} m must be > 0.")
    cox = EPS_OX / tox if tox > 0.0 else 0.0
    if cox > 0.0:
        if out["kp"] is None:
            out["kp"] = given.get("u0", 600.0) * cox * 1e-4  # cm²/V·s → m²/V·s
        nsub = given.get("nsub")
        if nsub is not None:
            if nsub * 1e6 <= ni:
                raise ModelError(
                    f"{where}: NSUB={nsub:g} cm⁻³ is not above the intrinsic density "
                    f"{ni * 1e-6:g} cm⁻³ (ngspice: 'Nsub < Ni')."
                )
            if out["phi"] is None:
                out["phi"] = max(0.1, 2.0 * vtnom * math.log(nsub * 1e6 / ni))
            phi = out["phi"]
            fermis = sign * 0.5 * phi
            tpg = given.get("tpg", 1.0)
            wkfng = 3.2 if tpg == 0 else 3.25 + 0.5 * gap - sign * tpg * 0.5 * gap
            wkfngs = wkfng - (3.25 + 0.5 * gap + fermis)
            if out["gamma"] is None:
                out["gamma"] = math.sqrt(2.0 * EPS_SI * CHARGE * nsub * 1e6) / cox
            if out["vto"] is None:
                vfb = wkfngs - given.get("nss", 0.0) * 1e4 * CHARGE / cox
                out["vto"] = vfb + sign * (out["gamma"] * math.sqrt(phi) + phi)
    values = {k: defaults[k] if x is None else x for k, x in out.items()}
    return values | {"cox": cox}


#: half-width of the C¹ rounding of Meyer's region corners (in the normalized arguments
#: below: V_GST/Φ, V_DS/V_dsat); the capacitances move by at most a quarter of it there
CORNER = 1e-3


def _smooth_max0(x, d=CORNER):
    """``max(x, 0)`` with its corner rounded over ``|x| < d`` (C¹, quadratic)."""
    mid = (x + d) ** 2 / (4.0 * d)
    return jnp.where(x >= d, x, jnp.where(x <= -d, 0.0 * x, mid))


def _smooth_clip01(x, d=CORNER):
    """``clip(x, 0, 1)`` with both corners rounded as :func:`_smooth_max0`."""
    return _smooth_max0(x, d) - _smooth_max0(x - 1.0, d)


def meyer_half(vgs, vgd, von, vdsat, phi, cox):
    r"""ngspice's ``DEVqmeyer``: half of Meyer's ``(C_GS, C_GD, C_GB)`` for NMOS-oriented
    forward-mode voltages (module docstring); ``cox`` is ``C'_ox W L_eff``.

    The regions are written as clipped ramps, ``C_GB = (C_ox/2) clip(−V_GST/Φ, 0, 1)``,
    ``C_GS + C_GD = (C_ox/3) clip(1 + 2V_GST/Φ, 0, 1)`` before the linear-region shaping,
    with every corner where a capacitance starts or stops changing rounded (C¹) over
    :data:`CORNER`: a capacitance with a corner in the voltage makes a Newton iterate at
    the corner alternate between its two slopes (the step converges only linearly). The
    branches JAX evaluates but does not select are kept finite (derivatives too)."""
    vgst = vgs - von
    vdsat = MAGIC_VDS + _smooth_max0(vdsat - MAGIC_VDS, CORNER * MAGIC_VDS)
    vds = vgs - vgd
    u = jnp.minimum(vds / vdsat, 1.5)  # past 1 only the rounding of shape_d reads it
    shape_s = jnp.where(u < 1.0, 1.0 - (1.0 - u) ** 2 / (2.0 - u) ** 2, 1.0)
    shape_d = _smooth_max0(1.0 - 1.0 / (2.0 - u) ** 2)
    cgb = 0.5 * cox * _smooth_clip01(-vgst / phi)
    base = cox / 3.0 * _smooth_clip01(1.0 + 2.0 * vgst / phi)
    return base * shape_s, base * shape_d, cgb


def mode_weight(vds, band=1e-6):
    """The weight of the forward mode (``V_DS > 0``) in Meyer's capacitances: 1 above
    ``band`` volts, 0 below ``−band``, a C¹ smoothstep between. At ``V_DS = 0`` both modes
    give the same capacitances, so the blend only removes the corner that choosing a mode
    by the sign of ``V_DS`` puts along ``V_GS = V_GD`` (where an off or idle transistor
    sits), on which Newton converges only linearly."""
    t = jnp.clip((vds + band) / (2.0 * band), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)
