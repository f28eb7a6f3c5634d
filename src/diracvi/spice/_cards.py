"""A semiconductor's ``.model`` card as its element line reads it (the ``M`` line's MOSFET
levels and VDMOS, the ``J`` line's JFET; the ``Q`` line's BJT in :mod:`._devices`).

A card parameter is either **read** (with ngspice's default, or only where given when
given-or-not changes the answer), **ignored with a note** (noise coefficients, parameters
ngspice itself reads but never uses), **fixed** (accepted at the one value diracvi
simulates, e.g. ``TNOM = 27`` °C, refused at any other), or **refused by name**: a
parameter diracvi does not implement stops the run at the element line that uses the
card, naming the card's line, rather than being silently dropped.

A name that is not a parameter of ngspice 39's model at all (not in its ``IFparm`` model
table, ``src/spicelib/devices/<model>/<model>.c``, aliases included) is ignored by ngspice
with a warning ("unrecognized parameter (xj) - ignored"): a card whose :attr:`Card.ngspice`
table is given ignores it too, with a note, rather than refusing a deck ngspice runs.
"""

from __future__ import annotations

import pickle
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import NamedTuple

from ..components._part import renamable, renamed

#: ngspice's nominal temperature, the only one diracvi simulates
TNOM = {"tnom": (27.0, "TNOM={x:g} is not supported; only 27 °C (drop it)")}
#: CIDER's numerical device models (a device simulated from its doping profile by a
#: 1-D or 2-D semiconductor solver), whose cards are words (``concmod=sg``), not numbers
CIDER = {
    k: " (CIDER's numerical device simulation, not supported)"
    for k in ("NUMD", "NUMD2", "NBJT", "NBJT2", "NUMOS")
}
#: the noise coefficients (they act in noise analyses only)
NOISE = {k: "ignored (noise only)" for k in ("kf", "af", "nlev", "gdsnoi")}


@dataclass(frozen=True)
class Card:
    """What one device model reads from its card (names lower-case). Every message is
    ``"{kind} …"``: ``ignored`` maps a name to its note's words after the name,
    ``fixed`` to ``(the value accepted, the refusal at another value)`` (a refusal of
    ``None``: the ``unknown`` one), ``unknown`` is the refusal of any other name; the
    refusals are :meth:`str.format` templates of ``key`` (upper-case) and ``x``."""

    defaults: Mapping[str, float]
    unknown: str
    optional: tuple[str, ...] = ()
    ignored: Mapping[str, str] = field(default_factory=dict)
    fixed: Mapping[str, tuple[float, str | None]] = field(default_factory=lambda: TNOM)
    alias: Mapping[str, str] = field(default_factory=dict)
    #: names read elsewhere (a MOS card's LEVEL, a VDMOS card's PCHAN): passed over
    skip: tuple[str, ...] = ()
    #: ngspice 39's model: its name for the notes and every name of its model table
    #: (aliases included); a name outside it is ignored with a note, as ngspice does.
    #: ``None``: no table, every name outside the others refused
    ngspice: tuple[str, frozenset[str]] | None = None

    def read(self, kind: str, kw: dict, fail, notes: list) -> dict:
        """``{name: value}``: :attr:`defaults` with the card's values over them, the
        :attr:`optional` ones where given; a note in ``notes`` for each ignored name;
        ``fail(why)`` raised for a name refused."""
        values = dict(self.defaults)
        for key, x in kw.items():
            key = self.alias.get(key, key)
            if key in self.skip:
                continue
            if key in values or key in self.optional:
                values[key] = x
            elif key in self.ignored:
                notes.append(f"{kind} {key.upper()} {self.ignored[key]}")
            elif key in self.fixed and x == self.fixed[key][0]:
                continue
            elif self.ngspice is not None and key not in self.ngspice[1] | set(self.fixed):
                notes.append(
                    f"{kind} {key.upper()} ignored (not a parameter of ngspice 39's "
                    f"{self.ngspice[0]}, which ignores it with a warning)"
                )
            else:
                refusal = self.fixed.get(key, (None, None))[1] or self.unknown
                raise fail(f"{kind} " + refusal.format(key=key.upper(), x=x))
        return values


class ElementCard(NamedTuple):
    """The ``.model`` an element line uses: ``fail(why)`` reports a problem of the card at
    the element line, naming the card's own line (``where``)."""

    kind: str
    params: dict
    where: str
    fail: Callable[[str], Exception]


def element_card(ctx, token: str, line, kinds: tuple[str, ...], needs: str = "this element"):
    """The :class:`ElementCard` of the ``.model`` named ``token`` that an element line
    uses, its type checked among ``kinds``."""
    declared = ctx.declared(token, line)
    kind, where = declared.kind, declared.where
    if kind not in kinds:  # before its values are read: another type's words are no numbers
        what = CIDER.get(kind, "")
        raise line.fail(
            f"model {token!r} ({where}) is a {kind}{what} model; {needs} needs {'/'.join(kinds)}"
        )
    kind, params, where = ctx.model(token, line)

    def fail(why):
        return line.fail(f"model {token!r} ({where}): {why}")

    return ElementCard(kind, params, where, fail)


class NodeIC:
    """The ``.ic`` voltages of a line's nodes, as the device builders ask for them."""

    def __init__(self, ctx):
        self.ctx = ctx

    def get(self, node, default=0.0):
        return self.ctx.ic(node)


def device_temperature(ctx, element, kw, line) -> float:
    """A device's temperature (°C) as ngspice sets it: ``TEMP=`` where the line gives it
    (its ``DTEMP=`` then ignored, with a note), else the circuit temperature plus
    ``DTEMP=`` (0 by default)."""
    if "temp" in kw:
        if "dtemp" in kw:
            ctx.note(line, f"{element}: TEMP given, so DTEMP is ignored (as ngspice does)")
        return ctx.value(kw["temp"], line, f"{element} TEMP")
    dtemp = ctx.value(kw["dtemp"], line, f"{element} DTEMP") if "dtemp" in kw else 0.0
    return ctx.temperature + dtemp


def built(parts: dict | None, build: Callable, *args, name: str, **kwargs):
    """``build(*args, name=name, **kwargs)``, a part constructor called with a netlist's
    numbers, or the part ``parts`` (one read's memory, ``None``: none) holds from an
    equal call, under the name ``name`` (:func:`~diracvi.components._part.renamed`).

    A subcircuit instantiated 10⁴ times repeats each of its transistor lines with the
    same card, size and initial voltages: the parts differ in their names only, and
    building each again cost ≈ 1 ms of Python (the level's checks and closures, their
    content keys, Equinox's construction of the part and of its wrapped functions).
    Calls are equal when their arguments' pickles are: the same types (NumPy's float64
    is not a float), numbers by their exact bits (0.0 is not −0.0), containers item by
    item in order; an argument that does not pickle (a local function) is not
    compared: the part is built."""
    key = None
    if parts is not None:
        try:
            key = (build, pickle.dumps((args, kwargs), pickle.HIGHEST_PROTOCOL))
        except (pickle.PicklingError, TypeError, AttributeError, ValueError):  # a local function
            key = None
    hit = parts.get(key) if key is not None else None
    if hit is not None:
        return renamed(hit, name)
    part = build(*args, name=name, **kwargs)
    if key is not None and renamable(part):
        parts[key] = part
    return part
