"""NMOS/PMOS ``.model`` cards at ``LEVEL=6`` (ngspice's ``mos6``, Sakurai–Newton).

Names, aliases and defaults are ngspice 39's (``mos6.c``, ``mos6set.c``, ``mos6temp.c``):
KV, NV, KC, NC, VTO (VT0), GAMMA, GAMMA1, SIGMA, PHI, LAMBDA0 (LAMBDA when LAMBDA0 is
not given), LAMBDA1, and the junction, overlap, resistance and process parameters every
level reads (:mod:`._mos_card`). Without KC, a card with ``TOX`` derives ``KC = ½ U0 C'_ox`` (``U0``
defaulting to 600 cm²/V·s) as ``mos6temp`` does; PHI, GAMMA and VTO come from ``NSUB``
as at level 1. NVTH and PS are read by ngspice 39 but never used by its load: accepted
with a note; so is a name ngspice 39's level 6 does not have (KP, XJ, …), which it
ignores with a warning.
"""

from __future__ import annotations

from ._mos_card import PROCESS, level_card

CARD = level_card(
    6,
    "Sakurai–Newton",
    {"kv": 2.0, "nv": 0.5, "nc": 1.0, "gamma1": 0.0, "sigma": 0.0, "lambda1": 0.0},
    ("kc", "lambda", "lambda0", *PROCESS, "tnom"),
    # read by ngspice 39's mos6, never used in its load
    ignored={k: "ignored (ngspice 39's level 6 does not use it)" for k in ("nvth", "ps")},
)


def read_mos6_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The values of a level-6 card (aliases already applied), checked: ``{name: value}``
    with the defaults of :data:`CARD` and the others only where given; ``"level"`` 6."""
    values = CARD.read(kind, kw, fail, notes) | {"level": 6.0}
    if values.get("phi", 0.6) <= 0.0:
        raise fail(f"{kind} PHI={values['phi']:g} must be > 0 (ngspice: 'Phi is not positive')")
    return values


def law(v: dict, process: dict) -> dict:
    """Level 6's law arguments of :func:`diracvi.components.MOSFET6` from the card's values
    and :func:`~diracvi.components._mos1.process_parameters`' ``process``."""
    if "kc" in v:
        kc = v["kc"]
    elif process["cox"] > 0.0:  # mos6temp: KC = ½ U0 C'ox (U0 in cm²/V·s)
        kc = 0.5 * v.get("u0", 600.0) * process["cox"] * 1e-4
    else:
        kc = 5e-5
    lambda0 = v.get("lambda0", v.get("lambda", 0.0))
    return dict(
        kc=kc, nc=v["nc"], kv=v["kv"], nv=v["nv"], gamma=process["gamma"],
        gamma1=v["gamma1"], sigma=v["sigma"], phi=process["phi"], lambda0=lambda0,
        lambda1=v["lambda1"],
    )  # fmt: skip
