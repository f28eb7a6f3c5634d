r"""Model binning: an ``M`` line naming ``nch`` where the deck defines ``nch.1``, ``nch.2``…,
each card with its ``LMIN``, ``LMAX``, ``WMIN``, ``WMAX``, uses the card whose ranges hold
the line's ``L`` and ``W`` (ngspice 39's ``INPgetModBin``, ``src/spicelib/parser/inpgmod.c``).

ngspice's rules, which this module follows:

- it bins only when no model is named exactly ``nch``; a bin's name is ``nch.`` and one or
  more digits (``model_name_match``);
- ``L`` and ``W`` are read from the line itself (no defaults: a line without both finds no
  model), ``W`` not divided by ``NF`` (ngspice's default ``wnflag = 0``), both times
  ``.options scale`` when given;
- a card holds ``x`` in ``[min, max]`` when ``min < x < max`` or ``x`` is within 1e-9 (in
  metres, ``is_equal``) of either edge; the bins are tried in the deck's order, so at an
  edge two bins share, the one defined first is used;
- only BSIM3, BSIM4 and HiSIM cards are binned (levels 8, 49, 14, 54, 68, 73): a bin of
  another level is passed over, and a line whose bins are all of other levels finds no
  model ("could not find a valid modelname") — ngspice refuses it, and so does diracvi,
  saying why.

A line none of whose bins holds its ``L`` and ``W`` is refused naming every bin's ranges.
"""

from __future__ import annotations

import re

#: the MOSFET levels ngspice 39 bins (INPgetModBin's list of model types)
BINNABLE = {8: "BSIM3", 49: "BSIM3", 14: "BSIM4", 54: "BSIM4", 68: "HiSIM2", 73: "HiSIM_HV"}
#: ngspice's is_equal: an edge within 1e-9 (absolute, metres) holds the value
EDGE = 1e-9
RANGES = ("lmin", "lmax", "wmin", "wmax")


def in_range(x: float, low: float, high: float) -> bool:
    """ngspice's ``in_range``: ``low < x < high``, or ``x`` within :data:`EDGE` of an edge."""
    return abs(x - low) < EDGE or abs(x - high) < EDGE or low < x < high


def binned(ctx, element: str, token: str, kw: dict, line) -> str:
    """The model the ``M`` line of ``element`` naming ``token`` uses: ``token`` itself
    when a model of that name is visible or no bin of it is (the caller reports a
    missing model), else the bin the line's ``L`` and ``W`` select (module docstring),
    refused by ``line.fail`` when none does."""
    name = token.lower()
    if name in ctx.models:
        return token
    pattern = re.compile(re.escape(name) + r"\.\d+")
    bins = [m for key, m in ctx.models.items() if pattern.fullmatch(key)]
    if not bins:
        return token
    listed = ", ".join(repr(m.name) for m in bins)
    binnable, other = [], []
    for m in bins:
        level = _number(m, "level", 1.0)
        (binnable if m.kind in ("NMOS", "PMOS") and level in BINNABLE else other).append((m, level))
    if not binnable:
        levels = sorted({f"{m.kind} level {level:g}" for m, level in other})
        raise line.fail(
            f"model {token!r} is not defined; its bins {listed} are {', '.join(levels)} "
            "cards, and ngspice 39 bins only BSIM3, BSIM4 and HiSIM cards (levels 8, 49, "
            "14, 54, 68, 73): it refuses this line too ('could not find a valid "
            "modelname'); name one of the cards on the line"
        )
    if "l" not in kw or "w" not in kw:
        raise line.fail(
            f"model {token!r} is binned ({listed}): the bin is chosen by the line's L= and "
            "W=, which ngspice reads from the line itself (no defaults); give both"
        )
    scale = ctx.reader.options.get("scale", 1.0)
    scale = scale if isinstance(scale, float | int) else 1.0
    length = ctx.value(kw["l"], line, f"{element} L") * scale
    width = ctx.value(kw["w"], line, f"{element} W") * scale
    ranges = []
    for m, _ in binnable:
        if not all(k in m.tokens for k in RANGES):
            continue  # ngspice's parse_line: a card without all four is passed over
        lmin, lmax, wmin, wmax = (_number(m, k, 0.0) for k in RANGES)
        if in_range(length, lmin, lmax) and in_range(width, wmin, wmax):
            m.used = True
            return m.name
        ranges.append(f"{m.name}: L {lmin:g}–{lmax:g}, W {wmin:g}–{wmax:g}")
    raise line.fail(
        f"L={length:g}, W={width:g} lie in no bin of model {token!r} ("
        + ("; ".join(ranges) or "no bin gives all of LMIN, LMAX, WMIN, WMAX")
        + "); choose L and W inside one, or add a bin"
    )


def _number(model, key: str, default: float) -> float:
    """A card's ``key`` as a number (its token evaluated in the card's scope)."""
    token = model.tokens.get(key)
    if token is None:
        return default
    return model.scope.value(token, model.line, f".model {model.name} {key}")
