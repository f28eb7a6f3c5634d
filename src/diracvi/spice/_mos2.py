"""NMOS/PMOS ``.model`` cards at ``LEVEL=2`` (ngspice's ``mos2``, Grove–Frohman).

Names, aliases and defaults are ngspice's (``mos2.c``, ``mos2set.c``, ``mos2temp.c``):
VTO (VT0), KP, GAMMA, PHI, LAMBDA, NSUB, TOX (default 0.1 µm: level 2 always has an
oxide), U0 (UO, default 600 cm²/V·s), NSS, TPG, DELTA, UCRIT (10⁴ V/cm), UEXP, VMAX, XJ,
NEFF (1), NFS, and level 1's junction, overlap and resistance parameters (:mod:`._mos`),
MJSW defaulting to 0.33 here. KP, PHI, GAMMA and VTO are derived from the process as at
level 1 (:func:`~diracvi.components._mos1.process_parameters`) when not given. UTRA,
which SPICE2 documents, is not a parameter of ngspice's mos2 (it would ignore it): it is
refused like any other unknown name.
"""

from __future__ import annotations

_DEFAULTS = {
    "lambda": 0.0, "delta": 0.0, "ucrit": 1e4, "uexp": 0.0, "vmax": 0.0, "xj": 0.0,
    "neff": 1.0, "nfs": 0.0, "u0": 600.0, "tox": 1e-7,
    "is": 1e-14, "ld": 0.0, "cgso": 0.0, "cgdo": 0.0, "cgbo": 0.0, "rsh": 0.0, "cj": 0.0,
    "cjsw": 0.0, "js": 0.0, "pb": 0.8, "mj": 0.5, "mjsw": 0.33, "fc": 0.5,
}  # fmt: skip
# given or not changes the answer (derived from the process, or RD over RSH·NRD …)
_OPTIONAL = ("vto", "kp", "gamma", "phi", "rd", "rs", "cbd", "cbs", "nsub", "nss", "tpg")
_NOISE = ("kf", "af", "nlev", "gdsnoi")


def read_mos2_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The values of a level-2 card (aliases already applied), checked: ``{name: value}``
    with the defaults of ``_DEFAULTS`` and the others only where given; ``"level"`` 2."""
    values = dict(_DEFAULTS, level=2.0)
    for key, x in kw.items():
        if key == "level":
            continue
        if key in values or key in _OPTIONAL:
            values[key] = x
        elif key in _NOISE:
            notes.append(f"{kind} {key.upper()} ignored (noise only)")
        elif key in ("l", "w"):
            notes.append(f"{kind} {key.upper()} on the .model card ignored (ngspice's level "
                         "2 reads L and W from the M line)")  # fmt: skip
        elif key == "tnom":
            if x != 27.0:
                raise fail(f"{kind} TNOM={x:g} is not supported; only 27 °C (drop it)")
        else:
            raise fail(
                f"{kind} parameter {key.upper()!r} is not a level-2 (Grove–Frohman) "
                "parameter of ngspice"
            )
    for key in ("phi", "tox", "u0", "ucrit", "neff"):
        if values.get(key, 1.0) <= 0.0:
            raise fail(f"{kind} {key.upper()}={values[key]:g} must be > 0")
    return values


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
