"""NMOS/PMOS ``.model`` cards at ``LEVEL=2`` (ngspice's ``mos2``, Grove–Frohman).

Names, aliases and defaults are ngspice's (``mos2.c``, ``mos2set.c``, ``mos2temp.c``):
VTO (VT0), KP, GAMMA, PHI, LAMBDA, NSUB, TOX (default 0.1 µm: level 2 always has an
oxide), U0 (UO, default 600 cm²/V·s), NSS, TPG, DELTA, UCRIT (10⁴ V/cm), UEXP, VMAX, XJ,
NEFF (1), NFS, and the junction, overlap and resistance parameters every level reads
(:mod:`._mos_card`), MJSW defaulting to 0.33 here. KP, PHI, GAMMA and VTO are derived
from the process as at level 1 (:func:`~diracvi.components._mos1.process_parameters`)
when not given. UTRA, which SPICE2 documents, is not a parameter of ngspice's mos2: it is
ignored with a note, as ngspice ignores it (with a warning).
"""

from __future__ import annotations

from ._mos_card import level_card, read_level

CARD = level_card(
    2, "Grove–Frohman",
    {"lambda": 0.0, "delta": 0.0, "ucrit": 1e4, "uexp": 0.0, "vmax": 0.0, "xj": 0.0,
     "neff": 1.0, "nfs": 0.0, "u0": 600.0, "tox": 1e-7, "mjsw": 0.33},
    ("kp", "nsub", "nss", "tpg", "tnom"),
)  # fmt: skip


def read_mos2_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The values of a level-2 card (aliases already applied), checked: ``{name: value}``
    with the defaults of :data:`CARD` and the others only where given; ``"level"`` 2."""
    return read_level(
        CARD, 2.0, kind, kw, fail, notes, positive=("phi", "tox", "u0", "ucrit", "neff")
    )


def law(v: dict, process: dict) -> dict:
    """Level 2's arguments of :func:`diracvi.components.MOSFET2` from the card's values
    and :func:`~diracvi.components._mos1.process_parameters`' ``process`` (computed with
    the card's TOX or its 0.1 µm default)."""
    return dict(
        vto=process["vto"], kp=process["kp"], lambda_=v["lambda"], gamma=process["gamma"],
        phi=process["phi"], tox=v["tox"], u0=v["u0"], nsub=v.get("nsub", 0.0), xj=v["xj"],
        delta=v["delta"], ucrit=v["ucrit"], uexp=v["uexp"], vmax=v["vmax"], neff=v["neff"],
        nfs=v["nfs"],
    )  # fmt: skip
