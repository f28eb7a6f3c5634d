"""NMOS/PMOS ``.model`` cards at ``LEVEL=3`` (ngspice's ``mos3``, the semi-empirical
short-channel model).

Names, aliases and defaults are ngspice 39's (``mos3.c``, ``mos3set.c``, ``mos3temp.c``):
VTO (VT0), KP, GAMMA, PHI, NSUB, TOX (default 0.1 µm: level 3 always has an oxide), U0
(UO, default 600 cm²/V·s), NSS, TPG, DELTA, ETA, THETA, KAPPA (0.2), VMAX, XJ, NFS, the
geometry adjustments XL, WD, XW, DELVTO (DELVT0), and the junction, overlap and
resistance parameters every level reads (:mod:`._mos_card`), MJSW defaulting to 0.33
here. KP, PHI, GAMMA and VTO are derived from the process as at level 1
(:func:`~diracvi.components._mos1.process_parameters`) when not given. XD, ALPHA and
INPUT_DELTA, which ngspice computes from NSUB and only reports, are refused (ngspice 39
refuses a card that sets them); LAMBDA, UCRIT, UEXP, NEFF (level 2's), which ngspice's
level 3 does not have, are ignored with a note, as ngspice ignores them.
"""

from __future__ import annotations

import math

from ._mos_card import level_card, read_level

CARD = level_card(
    3, "semi-empirical",
    {"delta": 0.0, "eta": 0.0, "theta": 0.0, "kappa": 0.2, "vmax": 0.0, "xj": 0.0,
     "nfs": 0.0, "u0": 600.0, "tox": 1e-7, "mjsw": 0.33, "xl": 0.0, "wd": 0.0, "xw": 0.0,
     "delvto": 0.0},
    ("kp", "nsub", "nss", "tpg", "tnom"),
    # in ngspice 39's table, but its mos3mpar has no case for them: ngspice refuses the
    # card ("could not find a valid modelname")
    fixed={k: (math.nan, "{key}={x:g}: ngspice 39 computes it (from NSUB) and refuses a "
               "card that sets it; drop it") for k in ("xd", "alpha", "input_delta")},
)  # fmt: skip


def read_mos3_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The values of a level-3 card (aliases already applied), checked: ``{name: value}``
    with the defaults of :data:`CARD` and the others only where given; ``"level"`` 3."""
    kw = {"delvto" if k == "delvt0" else k: x for k, x in kw.items()}
    return read_level(CARD, 3.0, kind, kw, fail, notes, positive=("phi", "tox", "u0"))


def law(v: dict, process: dict) -> dict:
    """Level 3's arguments of :func:`diracvi.components.MOSFET3` from the card's values
    and :func:`~diracvi.components._mos1.process_parameters`' ``process`` (computed with
    the card's TOX or its 0.1 µm default)."""
    return dict(
        vto=process["vto"], kp=process["kp"], gamma=process["gamma"], phi=process["phi"],
        tox=v["tox"], u0=v["u0"], nsub=v.get("nsub", 0.0), xj=v["xj"], delta=v["delta"],
        eta=v["eta"], theta=v["theta"], kappa=v["kappa"], vmax=v["vmax"], nfs=v["nfs"],
        xl=v["xl"], wd=v["wd"], xw=v["xw"], delvto=v["delvto"],
    )  # fmt: skip
