"""NMOS/PMOS ``.model`` cards at ``LEVEL=6`` (ngspice's ``mos6``, Sakurai–Newton).

Names, aliases and defaults are ngspice 39's (``mos6.c``, ``mos6set.c``, ``mos6temp.c``):
KV, NV, KC, NC, VTO (VT0), GAMMA, GAMMA1, SIGMA, PHI, LAMBDA0 (LAMBDA when LAMBDA0 is
not given), LAMBDA1, and level 1's junction, overlap, resistance and process parameters
(:mod:`._mos`). Without KC, a card with ``TOX`` derives ``KC = ½ U0 C'_ox`` (``U0``
defaulting to 600 cm²/V·s) as ``mos6temp`` does; PHI, GAMMA and VTO come from ``NSUB``
as at level 1. NVTH and PS are read by ngspice 39 but never used by its load: accepted
with a note.
"""

from __future__ import annotations

_DEFAULTS = {
    "kv": 2.0, "nv": 0.5, "nc": 1.0, "gamma1": 0.0, "sigma": 0.0, "lambda1": 0.0,
    "is": 1e-14, "ld": 0.0, "cgso": 0.0, "cgdo": 0.0, "cgbo": 0.0, "rsh": 0.0, "cj": 0.0,
    "cjsw": 0.0, "js": 0.0, "pb": 0.8, "mj": 0.5, "mjsw": 0.5, "fc": 0.5,
}  # fmt: skip
# given or not changes the answer (derived, or a fallback of another parameter)
_OPTIONAL = ("vto", "kc", "gamma", "phi", "lambda", "lambda0", "rd", "rs", "cbd", "cbs")
_PROCESS = ("tox", "u0", "nsub", "nss", "tpg")
_UNUSED = ("nvth", "ps")  # read by ngspice 39's mos6, never used in its load
_NOISE = ("kf", "af", "nlev", "gdsnoi")


def read_mos6_model(kind: str, kw: dict, fail, notes: list) -> dict:
    """The values of a level-6 card (aliases already applied), checked: ``{name: value}``
    with the defaults of ``_DEFAULTS`` and the others only where given; ``"level"`` 6."""
    values = dict(_DEFAULTS, level=6.0)
    for key, x in kw.items():
        if key == "level":
            continue
        if key in values or key in _OPTIONAL or key in _PROCESS:
            values[key] = x
        elif key in _UNUSED:
            notes.append(f"{kind} {key.upper()} ignored (ngspice 39's level 6 does not use it)")
        elif key in _NOISE:
            notes.append(f"{kind} {key.upper()} ignored (noise only)")
        elif key == "tnom":
            if x != 27.0:
                raise fail(f"{kind} TNOM={x:g} is not supported; only 27 °C (drop it)")
        else:
            raise fail(
                f"{kind} parameter {key.upper()!r} is not a level-6 (Sakurai–Newton) "
                "parameter of ngspice"
            )
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
