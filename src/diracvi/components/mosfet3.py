r"""The level-3 MOSFET (the semi-empirical short-channel model, SPICE ``M`` at ``LEVEL=3``,
ngspice's ``mos3``) as a Lagrange–Dirac part: level 1's structure
(:mod:`~diracvi.components._mos_part`: junctions, overlap and Meyer capacitances, RD/RS,
the source/drain swap) with level 3's drain current
(:mod:`~diracvi.components._semi_empirical`: THETA's mobility modulation, ETA's static
feedback, VMAX's velocity saturation, KAPPA's channel shortening, DELTA's narrow width,
XJ/LD's short channel, NFS's weak inversion).

Level 3 always has an oxide: ``TOX`` defaults to 0.1 µm (``mos3set``), so the gate has
Meyer's capacitances with ``C'_ox = ε_ox/TOX`` and ``KP`` defaults to ``U0 C'_ox``. Its
channel is ``L_eff = L − 2·LD + XL`` long and ``W_eff = W − 2·WD + XW`` wide, and the
gate's overlaps and oxide scale with ``W_eff`` (``mos3load``).
"""

from __future__ import annotations

import math

from ..errors import ModelError
from . import _semi_empirical
from ._junction import THERMAL_VOLTAGE
from ._mos1 import CHARGE, EPS_OX, EPS_SI
from ._mos_part import KINDS, build, device, law
from ._part import finite, positive
from .controlled import ControlledPart, coefficient
from .mosfet2 import SHARED2, _nonzero

#: ETA's static feedback is ``σ = ETA·8.15e-22/(C'_ox L³)`` (F/m: ngspice's constant)
ETA_SCALE = 8.15e-22


def MOSFET3(
    kind="nmos",
    vto=0.0,
    kp=None,
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
    eta=0.0,
    theta=0.0,
    kappa=0.2,
    vmax=0.0,
    nfs=0.0,
    xl=0.0,
    wd=0.0,
    xw=0.0,
    delvto=0.0,
    name: str,
    **shared,
) -> ControlledPart:
    r"""A level-3 MOSFET with pins ``d g s b`` (defaults as ngspice's ``mos3set`` and
    ``mos3temp``: ``VTO = 0``, ``KP = U0 ε_ox/TOX``, ``γ = 0``, ``Φ = 0.6`` V, ``TOX =
    0.1 µm``, ``U0 = 600`` cm²/V·s, ``KAPPA = 0.2``, ``ETA = THETA = VMAX = NFS = DELTA =
    XJ = XL = WD = XW = DELVTO = 0``; ``shared`` as :func:`~diracvi.components.MOSFET`'s,
    but for ``cox`` (``TOX``'s here) and ``mjsw`` (0.33)).

    ``nsub`` (cm⁻³, 0: not given) sets ``α = 2ε_Si/(q NSUB)``, which the short-channel
    factor (with ``xj``, m) and the channel shortening (with ``kappa``) read; without it
    neither acts. It does not derive VTO, GAMMA or PHI here (the netlist reader does, as
    ngspice). ``vmax`` (m/s) turns on velocity saturation, ``nfs`` (cm⁻²) weak inversion,
    ``eta`` the drain's lowering of the threshold, ``theta`` (1/V) the gate's mobility
    modulation. ``vto``, ``kp``, ``gamma``, ``eta``, ``theta``, ``kappa``, ``vmax``,
    ``nfs``, ``delta`` and ``delvto`` may be traced JAX values.
    """
    where = f"MOSFET3 {name!r}"
    xl, wd, xw = (finite(where, k, x) for k, x in (("xl", xl), ("wd", wd), ("xw", xw)))
    width = positive(where, "w", w) - 2.0 * wd + xw
    if width <= 0.0:
        raise ModelError(
            f"{where}: the effective width W − 2·WD + XW = {width:g} m must be > 0 "
            f"(w={w:g}, wd={wd:g}, xw={xw:g})."
        )
    length = positive(where, "l", l) + xl  # device() takes 2·LD off it: L_eff
    ld = finite(where, "ld", shared.get("ld", 0.0))
    if length - 2.0 * ld <= 0.0:
        raise ModelError(
            f"{where}: the effective length L − 2·LD + XL = {length - 2.0 * ld:g} m must be "
            f"> 0 (l={l:g}, ld={ld:g}, xl={xl:g})."
        )
    dev = device("MOSFET3", kind, width, length, name, shared, SHARED2)
    traced = {
        k: coefficient(where, k, x)
        for k, x in (("vto", vto), ("gamma", gamma), ("eta", eta), ("theta", theta),
                     ("kappa", kappa), ("vmax", vmax), ("nfs", nfs), ("delta", delta),
                     ("delvto", delvto))
    }  # fmt: skip
    phi = positive(where, "phi", phi)
    tox = positive(where, "tox", tox)
    u0 = positive(where, "u0", u0)
    nsub = finite(where, "nsub", nsub)
    xj = finite(where, "xj", xj)
    if nsub < 0.0 or xj < 0.0:
        raise ModelError(f"{where}: nsub={nsub:g} and xj={xj:g} must be ≥ 0 (0: not given).")
    cox = EPS_OX / tox
    kp = u0 * 1e-4 * cox if kp is None else coefficient(where, "kp", kp)
    sign = KINDS[kind]
    leff, width = dev.leff, dev.width
    # the law as data (:class:`~._semi_empirical.Level3`'s numbers a vector, its flags
    # static): devices of other sizes share one program
    alpha = 2.0 * EPS_SI / (CHARGE * nsub * 1e6) if nsub > 0.0 else 0.0
    flags = {
        "has_nfs": _nonzero(traced["nfs"]),
        "has_vmax": not isinstance(traced["vmax"], float) or traced["vmax"] > 0.0,
        "has_alpha": alpha != 0.0,
        "short": xj != 0.0 and alpha != 0.0,
    }
    forward = law(
        _semi_empirical.law,
        flags,
        vbi=sign * (traced["vto"] + traced["delvto"]) - traced["gamma"] * math.sqrt(phi),
        beta=kp * dev.mult * width / leff,
        gamma=traced["gamma"],
        phi=phi,
        narrow=traced["delta"] * 0.5 * math.pi * EPS_SI / (cox * width),
        sigma=traced["eta"] * ETA_SCALE / (cox * leff**3),
        alpha=alpha,
        xj=xj,
        ld=0.5 * (length - leff),  # LD, which device() consumed
        leff=leff,
        fast_states=CHARGE * traced["nfs"] * 1e4 / cox,
        theta=traced["theta"],
        kappa=traced["kappa"],
        u0=u0 * 1e-4,
        vmax=traced["vmax"],
        # the bulk junctions' V_T(T)/V_T(27 °C) is the law's too (mos3load: vt at T)
        vt=THERMAL_VOLTAGE * dev.shared["emission"],
    )
    params = {"kp": kp, "vto": traced["vto"], "phi": phi, "gamma": traced["gamma"],
              "tox": tox, "u0": u0, "nsub": nsub, "xj": xj, "delta": traced["delta"],
              "eta": traced["eta"], "theta": traced["theta"], "kappa": traced["kappa"],
              "vmax": traced["vmax"], "nfs": traced["nfs"], "xl": xl, "wd": wd, "xw": xw,
              "delvto": traced["delvto"]}  # fmt: skip
    # mos3load's junctions add GMIN unscaled by M (mos1load scales it), and below −3 V_T
    # follow the cubic reverse branch (mos1load and mos2load hold −I_S there)
    return build(
        dev, forward, phi, params, cox=cox, gmin=dev.shared["gmin"] / dev.mult,
        reverse="cubic",
    )  # fmt: skip
