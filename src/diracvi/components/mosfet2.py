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
from . import _grove_frohman
from ._junction import THERMAL_VOLTAGE
from ._mos1 import CHARGE, EPS_OX, EPS_SI
from ._mos_part import KINDS, SHARED, build, device, law
from ._part import finite, positive
from .controlled import ControlledPart, coefficient


def _nonzero(x) -> bool:
    """ngspice's ``x != 0`` branch on a card value; a traced value takes the branch."""
    return not isinstance(x, float) or x != 0.0


#: level 2's shared keywords: no ``cox`` (its oxide is ``TOX``'s), ``MJSW`` 0.33 (``mos2set``)
SHARED2 = {k: x for k, x in SHARED.items() if k != "cox"} | {"mjsw": 0.33}


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
    name: str,
    **shared,
) -> ControlledPart:
    r"""A level-2 MOSFET with pins ``d g s b`` (defaults as ngspice's ``mos2set`` and
    ``mos2temp``: ``VTO = 0``, ``KP = U0 ε_ox/TOX``, ``λ = γ = 0``, ``Φ = 0.6`` V, ``TOX =
    0.1 µm``, ``U0 = 600`` cm²/V·s, ``UCRIT = 10⁴`` V/cm, ``UEXP = VMAX = NFS = DELTA = XJ =
    0``, ``NEFF = 1``; ``shared`` as :func:`~diracvi.components.MOSFET`'s, but for ``cox``
    (``TOX``'s here) and ``mjsw`` (0.33: :data:`SHARED2`)).

    ``nsub`` (cm⁻³, 0: not given) sets the depletion width ``X_D = √(2ε_Si/(q NSUB))`` that
    the short-channel threshold (with ``xj``, m), the computed channel-length modulation
    (when ``lambda_`` is not > 0) and the punch-through limit read; it does not derive VTO,
    GAMMA or PHI here (the netlist reader does, as ngspice). ``vmax`` (m/s) turns on
    velocity saturation, ``nfs`` (cm⁻²) weak inversion. ``vto``, ``kp``, ``lambda_``,
    ``gamma``, ``uexp``, ``vmax``, ``nfs`` and ``delta`` may be traced JAX values.
    """
    dev = device("MOSFET2", kind, w, l, name, shared, SHARED2)
    where, width, leff, mult = dev.where, dev.width, dev.leff, dev.mult
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
    cox = EPS_OX / tox
    kp = u0 * 1e-4 * cox if kp is None else coefficient(where, "kp", kp)
    sign = KINDS[kind]
    # the law as data (:class:`~._grove_frohman.Level2`'s numbers a vector, its flags
    # static): devices of other sizes share one program
    lambda_ = traced["lambda_"]
    flags = {
        "has_nfs": _nonzero(traced["nfs"]),
        "has_vmax": not isinstance(traced["vmax"], float) or traced["vmax"] > 0.0,
        "has_nsub": nsub > 0.0,
        "has_xj": xj > 0.0,
        "lambda_set": lambda_ > 0.0 if isinstance(lambda_, float) else None,
    }
    forward = law(
        _grove_frohman.law,
        flags,
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
        pb=positive(where, "pb", dev.shared["pb"]),
        # the bulk junctions' V_T(T)/V_T(27 °C) is the law's too (mos2load: vt at T)
        vt=THERMAL_VOLTAGE * dev.shared["emission"],
    )
    params = {"kp": kp, "vto": traced["vto"], "lambda": traced["lambda_"], "phi": phi,
              "gamma": traced["gamma"], "tox": tox, "u0": u0, "nsub": nsub, "xj": xj,
              "delta": traced["delta"], "ucrit": ucrit, "uexp": traced["uexp"],
              "vmax": traced["vmax"], "neff": neff, "nfs": traced["nfs"]}  # fmt: skip
    # mos2load's junctions add GMIN unscaled by M (mos1load scales it)
    return build(dev, forward, phi, params, cox=cox, gmin=dev.shared["gmin"] / mult)
