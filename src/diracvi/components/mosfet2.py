r"""The level-2 MOSFET (Grove–Frohman, SPICE ``M`` at ``LEVEL=2``, ngspice's ``mos2``) as a
Lagrange–Dirac part: level 1's structure (:mod:`~diracvi.components._mos_part`: junctions,
overlap and Meyer capacitances, RD/RS, the source/drain swap) with level 2's drain current
(:mod:`~diracvi.components._grove_frohman`: the 2/3-power bulk charge, short- and
narrow-channel threshold, mobility degradation, channel-length modulation from NSUB,
weak inversion with NFS, Baum's velocity saturation with VMAX).

Level 2 always has an oxide: ``TOX`` defaults to 0.1 µm (``mos2temp``), so the gate has
Meyer's capacitances with ``C'_ox = ε_ox/TOX`` and ``KP`` defaults to ``U0 C'_ox``.
"""

from __future__ import annotations

import math

from ..errors import ModelError
from ._grove_frohman import Level2, level2
from ._mos1 import CHARGE, EPS_OX, EPS_SI
from ._mos_part import KINDS, build
from ._part import finite, positive
from .controlled import ControlledPart, coefficient


def _nonzero(x) -> bool:
    """ngspice's ``x != 0`` branch on a card value; a traced value takes the branch."""
    return not isinstance(x, float) or x != 0.0


def MOSFET2(
    kind="nmos",
    vto=0.0,
    kp=None,
    lambda_=0.0,
    w=100e-6,
    l=100e-6,  # noqa: E741  (SPICE's name)
    gamma=0.0,
    phi=0.6,
    *,
    tox=1e-7,
    u0=600.0,
    nsub=0.0,
    xj=0.0,
    delta=0.0,
    ucrit=1e4,
    uexp=0.0,
    vmax=0.0,
    neff=1.0,
    nfs=0.0,
    ld=0.0,
    is_=1e-14,
    m=1.0,
    cgso=0.0,
    cgdo=0.0,
    cgbo=0.0,
    rd=0.0,
    rs=0.0,
    cbd=0.0,
    cbs=0.0,
    cbdsw=0.0,
    cbssw=0.0,
    pb=0.8,
    mj=0.5,
    mjsw=0.33,
    fc=0.5,
    gmin=1e-12,
    v0=(0.0, 0.0, 0.0),
    name: str,
) -> ControlledPart:
    r"""A level-2 MOSFET with pins ``d g s b`` (defaults as ngspice's ``mos2set`` and
    ``mos2temp``: ``VTO = 0``, ``KP = U0 ε_ox/TOX``, ``λ = γ = 0``, ``Φ = 0.6`` V, ``TOX =
    0.1 µm``, ``U0 = 600`` cm²/V·s, ``UCRIT = 10⁴`` V/cm, ``UEXP = VMAX = NFS = DELTA = XJ =
    0``, ``NEFF = 1``, ``MJSW = 0.33``; the rest as :func:`~diracvi.components.MOSFET`).

    ``nsub`` (cm⁻³, 0: not given) sets the depletion width ``X_D = √(2ε_Si/(q NSUB))`` that
    the short-channel threshold (with ``xj``, m), the computed channel-length modulation
    (when ``lambda_`` is not > 0) and the punch-through limit read; it does not derive VTO,
    GAMMA or PHI here (the netlist reader does, as ngspice). ``vmax`` (m/s) turns on
    velocity saturation, ``nfs`` (cm⁻²) weak inversion. ``vto``, ``kp``, ``lambda_``,
    ``gamma``, ``uexp``, ``vmax``, ``nfs`` and ``delta`` may be traced JAX values.
    """
    where = f"MOSFET2 {name!r}"
    if kind not in KINDS:
        raise ModelError(f"{where}: kind={kind!r} must be 'nmos' or 'pmos'.")
    traced = {
        k: coefficient(where, k, x)
        for k, x in (("vto", vto), ("lambda_", lambda_), ("gamma", gamma), ("uexp", uexp),
                     ("vmax", vmax), ("nfs", nfs), ("delta", delta))
    }  # fmt: skip
    phi = positive(where, "phi", phi)
    tox = positive(where, "tox", tox)
    u0 = positive(where, "u0", u0)
    ucrit = positive(where, "ucrit", ucrit)
    neff = positive(where, "neff", neff)
    nsub = finite(where, "nsub", nsub)
    xj = finite(where, "xj", xj)
    if nsub < 0.0 or xj < 0.0:
        raise ModelError(f"{where}: nsub={nsub:g} and xj={xj:g} must be ≥ 0 (0: not given).")
    width = positive(where, "w", w)
    leff = positive(where, "l", l) - 2.0 * finite(where, "ld", ld)
    if leff <= 0.0:
        raise ModelError(f"{where}: the effective length L − 2·LD = {leff:g} m must be > 0.")
    mult = positive(where, "m", m)
    cox = EPS_OX / tox
    kp = u0 * 1e-4 * cox if kp is None else coefficient(where, "kp", kp)
    sign = KINDS[kind]
    law = Level2(
        vbi=sign * traced["vto"] - traced["gamma"] * math.sqrt(phi),
        beta=kp * mult * width / leff,
        gamma=traced["gamma"],
        phi=phi,
        # ngspice 39 divides by the oxide capacitance times M; per device, as since 2025
        factor=traced["delta"] * math.pi * EPS_SI / (4.0 * cox * width),
        xd=math.sqrt(2.0 * EPS_SI / (CHARGE * nsub * 1e6)) if nsub > 0.0 else 0.0,
        xj=xj,
        leff=leff,
        lambda_=traced["lambda_"],
        fast_states=CHARGE * traced["nfs"] * 1e4 / cox,
        ucrit=ucrit * 100.0 * EPS_SI / cox,
        uexp=traced["uexp"],
        u0=u0 * 1e-4,
        vmax=traced["vmax"],
        neff=neff,
        pb=positive(where, "pb", pb),
        has_nfs=_nonzero(traced["nfs"]),
        has_vmax=not isinstance(traced["vmax"], float) or traced["vmax"] > 0.0,
        has_nsub=nsub > 0.0,
    )
    params = {"kp": kp, "vto": traced["vto"], "lambda": traced["lambda_"], "phi": phi,
              "gamma": traced["gamma"], "tox": tox, "u0": u0, "nsub": nsub, "xj": xj,
              "delta": traced["delta"], "ucrit": ucrit, "uexp": traced["uexp"],
              "vmax": traced["vmax"], "neff": neff, "nfs": traced["nfs"]}  # fmt: skip
    return build(
        where, kind, level2(law), phi, width=width, leff=leff, mult=mult, is_=is_,
        cgso=cgso, cgdo=cgdo, cgbo=cgbo, cox=cox, rd=rd, rs=rs, cbd=cbd, cbs=cbs,
        cbdsw=cbdsw, cbssw=cbssw, pb=pb, mj=mj, mjsw=mjsw, fc=fc,
        gmin=gmin / mult,  # mos2load's junctions add GMIN unscaled by M (mos1load scales it)
        v0=v0, params=params, name=name,
    )  # fmt: skip
