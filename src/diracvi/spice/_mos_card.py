"""What every MOSFET level's ``.model`` card shares (ngspice's ``mos1``, ``mos2`` and
``mos6`` alike), and a level's card made of it and its law's own parameters.

The shared parameters: the bulk junctions (``IS`` or ``JS`` times the line's ``AD``/``AS``,
``CBD``/``CBS`` or ``CJ`` times ``AD``/``AS``, ``CJSW`` times ``PD``/``PS``, ``PB``, ``MJ``,
``MJSW``, ``FC``), the overlaps ``CGSO``, ``CGDO``, ``CGBO`` and ``LD``, the resistances
``RD``/``RS`` or ``RSH`` times ``NRD``/``NRS``, the process (``TOX``, ``U0``, ``NSUB``,
``NSS``, ``TPG``: :func:`~diracvi.components._mos1.process_parameters`), the noise
coefficients (a note), ``TNOM`` (levels 1, 2 and 3 read any TNOM: their temperature
update; level 6 only 27 °C).
A name ngspice 39's level does not have is ignored with a note, as ngspice ignores it (with
a warning); a name it has and diracvi does not read is refused naming the level.
"""

from __future__ import annotations

from ._cards import NOISE, TNOM, Card

#: the junction, overlap and resistance parameters, with ngspice's defaults
JUNCTIONS = {
    "is": 1e-14, "ld": 0.0, "cgso": 0.0, "cgdo": 0.0, "cgbo": 0.0, "rsh": 0.0, "cj": 0.0,
    "cjsw": 0.0, "js": 0.0, "pb": 0.8, "mj": 0.5, "mjsw": 0.5, "fc": 0.5,
}  # fmt: skip
#: read only where given: given or not changes the answer (derived from the process, or
#: RD over RSH·NRD …)
OPTIONAL = ("vto", "gamma", "phi", "rd", "rs", "cbd", "cbs")
PROCESS = ("tox", "u0", "nsub", "nss", "tpg")

#: every name of ngspice 39's model tables (``mosN.c``'s ``MOSNmPTable``, aliases
#: included) for the levels diracvi has: a name outside its level's is ignored by ngspice
#: with a warning, and by diracvi with a note (:class:`~._cards.Card`)
_SHARED = frozenset(
    "vto vt0 gamma phi rd rs cbd cbs is pb cgso cgdo cgbo rsh cj mj cjsw mjsw js tox "
    "ld u0 uo fc nmos pmos nsub tpg nss tnom".split()
)
NGSPICE39 = {
    1: _SHARED | {"kp", "lambda", "kf", "af"},
    2: _SHARED | set("kp lambda delta uexp ucrit vmax xj neff nfs kf af".split()),
    3: _SHARED | set("kp xl wd xw delvto delvt0 vmax xj nfs xd alpha eta delta input_delta "
                     "theta kappa kf af".split()),
    6: _SHARED | set("kv nv kc nc nvth ps gamma1 sigma lambda lambda0 lambda1".split()),
}  # fmt: skip


def level_card(
    level: int, law: str, defaults: dict, optional: tuple, ignored=None, fixed=None
) -> Card:
    """Level ``level``'s card (``law``: its name, for the refusal): ``defaults`` and
    ``optional`` of its law over the shared ones, ``ignored`` beside the noise
    coefficients (``None``: L and W on the card, which the level reads from the M line),
    ``fixed`` beside TNOM (:class:`~._cards.Card`)."""
    if ignored is None:
        why = f"on the .model card ignored (ngspice's level {level} reads L and W from the M line)"
        ignored = {"l": why, "w": why}
    return Card(
        defaults=JUNCTIONS | defaults,
        optional=OPTIONAL + optional,
        ignored=NOISE | ignored,
        fixed=TNOM | (fixed or {}),
        skip=("level",),
        unknown=f"parameter {{key!r}} of ngspice's level-{level} ({law}) MOSFET is not "
        "supported by diracvi",
        ngspice=(f"level-{level} MOSFET", NGSPICE39[level]),
    )


def read_level(card: Card, level: float, kind: str, kw: dict, fail, notes: list, positive) -> dict:
    """The values of a level card (aliases already applied), checked: ``{name: value}``
    with ``card``'s defaults and the others only where given, ``"level"`` set, and each
    of ``positive`` > 0 where given or defaulted."""
    values = card.read(kind, kw, fail, notes) | {"level": level}
    for key in positive:
        if values.get(key, 1.0) <= 0.0:
            raise fail(f"{kind} {key.upper()}={values[key]:g} must be > 0")
    return values
