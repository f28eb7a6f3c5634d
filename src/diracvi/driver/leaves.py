"""The leaves of one kind in a model (a switch's :class:`~diracvi.components.switch.Relay`,
a line's :class:`~diracvi.components.tline.Incident`), found once per model object.

A driver asks for them on every call (``simulate`` checks for lines, the event loop sets
the relays' states), and walking a large netlist's PyTree leaf by leaf costs about a
tenth of a second. A model is immutable, so what was found is remembered per object
(weakly, the last :data:`KEEP` models).
"""

from __future__ import annotations

import weakref
from collections import OrderedDict

import jax

from ..model.stacked import ALIKE

#: how many models' findings are remembered
KEEP = 64


class LeavesOf:
    """``finder(system)``: the leaves of ``system`` for which ``is_kind`` holds, in PyTree
    order. An interconnection (not packed) is read member by member — a linear R, L or C
    copied from its template (:data:`~diracvi.model.stacked.ALIKE`) holds none and is not
    walked — then, with ``interactions``, its interaction rows; anything else whole."""

    def __init__(self, is_kind, *, interactions: bool):
        self.is_kind = is_kind
        self.interactions = interactions
        self._found: OrderedDict = OrderedDict()

    def leaves(self, tree) -> list:
        """Every leaf of ``tree`` of the kind."""
        return [x for x in jax.tree.leaves(tree, is_leaf=self.is_kind) if self.is_kind(x)]

    def own(self, sub) -> list:
        """A member's leaves of the kind (none in a template copy)."""
        own = getattr(sub, "__dict__", None)
        if own is not None and ALIKE in own:
            return []
        return self.leaves(sub)

    def __call__(self, system) -> list:
        hit = self._found.get(id(system))
        if hit is not None and hit[0]() is system:
            return hit[1]
        subsystems = getattr(system, "subsystems", None)
        if subsystems is not None and getattr(system, "_packing", None) is None:
            found = [x for sub in subsystems for x in self.own(sub)]
            if self.interactions:
                found += self.leaves(getattr(system, "interactions", ()))
        else:
            found = self.leaves(system)
        try:
            self._found[id(system)] = (weakref.ref(system), found)
        except TypeError:  # (not weakly referenceable: not remembered)
            return found
        while len(self._found) > KEEP:
            self._found.popitem(last=False)
        return found


__all__ = ["KEEP", "LeavesOf"]
