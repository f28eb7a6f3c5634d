r"""Nodes without a DC path to ground get ngspice's GMIN shunt.

A node joined to the rest of the circuit only through capacitors (or current sources)
has no DC voltage: the static equations are singular there. ngspice says so ("singular
matrix: check node 8"), then solves its operating point by gmin stepping and keeps a
conductance ``GMIN`` (``.options gmin``, default 1e-12 S) from such a node to ground in
the transient too: its capacitors slowly leak through it (on ``liec_cw_multiplier``,
``v(8) − v(6)`` drifts by −9.5e-4 V over 50 ms with GMIN = 1e-12 S, and by −9.4e-2 V
with GMIN = 1e-10 S — the drift scales with GMIN). diracvi does the same, explicitly:
a resistor ``1/GMIN`` from each such node to ground, with a note naming it.
"""

from __future__ import annotations

from .. import components as cp

#: ngspice's default GMIN (S)
GMIN = 1e-12

#: branch roles that carry no DC current between their nodes
_OPEN_AT_DC = ("capacitor", "current")


def islands(circuit) -> list[str]:
    """The nodes with no DC path to ground, in the order they were first named."""
    parent: dict[str, str] = {}

    def find(x):
        parent.setdefault(x, x)
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    ground = "\0ground"
    order: list[str] = []
    for part, nodes in circuit._parts:
        roles = dict(getattr(part, "branch_roles", ()))
        branches: dict[str, list[str]] = {}
        for pin, coord, _ in part.pins:
            node = nodes.get(pin)
            if node is None:
                continue
            node = ground if circuit._is_ground(node) else node
            if node != ground and node not in parent:
                order.append(node)
            find(node)
            branches.setdefault(coord, []).append(node)
        for coord, ends in branches.items():
            if roles.get(coord, part.role) in _OPEN_AT_DC:
                continue
            for other in ends[1:]:
                parent[find(other)] = find(ends[0])
    find(ground)
    return [n for n in order if find(n) != find(ground)]


def add_shunts(circuit, gmin: float, note) -> None:
    """Join each node of :func:`islands` to ground by ``1/gmin`` Ω (``note(text)``)."""
    for node in islands(circuit):
        name = f"gmin:{node}"
        circuit.add(cp.Resistor(1.0 / gmin, name=name), p=node, n="0")
        circuit.origin[name] = f"GMIN at node {node!r}"
        note(
            f"node {node!r} has no DC path to ground (only capacitors or current sources "
            f"join it): a conductance GMIN = {gmin:g} S to ground is added there, as ngspice "
            "does ('singular matrix: check node'), so its DC voltage is defined"
        )
