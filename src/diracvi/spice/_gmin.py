r"""Nodes without a DC path to ground get ngspice's GMIN shunt.

A node joined to the rest of the circuit only through capacitors has no DC voltage: the
static equations are singular there. ngspice says so ("singular matrix: check node 8"),
then solves its operating point by gmin stepping and keeps a conductance ``GMIN``
(``.options gmin``, default 1e-12 S) from such a node to ground in the transient too:
its capacitors slowly leak through it (on ``liec_cw_multiplier``, ``v(8) − v(6)`` drifts
by −9.5e-4 V over 50 ms with GMIN = 1e-12 S, and by −9.4e-2 V with GMIN = 1e-10 S — the
drift scales with GMIN). diracvi does the same, explicitly: a resistor ``1/GMIN`` from
each such node to ground, with a note naming it.
"""

from __future__ import annotations

from .. import components as cp

#: ngspice's default GMIN (S)
GMIN = 1e-12


def islands(circuit) -> list[str]:
    """The nodes joined to ground only through capacitors, in the order first named.

    A node with no path to ground at all, a cut-set of current sources and a circuit
    without ground stay the topology errors :meth:`~diracvi.components.Circuit.build`
    reports (they are mistakes, not a missing DC path)."""
    if not any(circuit._is_ground(n) for _, nodes in circuit._parts for n in nodes.values()):
        return []
    every, order = _components(circuit, ())
    direct, _ = _components(circuit, ("capacitor",))
    ground = "\0ground"
    return [n for n in order if every(n) == every(ground) and direct(n) != direct(ground)]


def _components(circuit, open_roles):
    """``(find, nodes)``: the root of each node's connected component, branches of
    ``open_roles`` left out, and the non-ground nodes in the order first named."""
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
            if roles.get(coord, part.role) in open_roles:
                continue
            for other in ends[1:]:
                parent[find(other)] = find(ends[0])
    find(ground)
    return find, order


def add_shunts(circuit, gmin: float, note) -> None:
    """Join each node of :func:`islands` to ground by ``1/gmin`` Ω (``note(text)``)."""
    for node in islands(circuit):
        name = f"gmin:{node}"
        circuit.add(cp.Resistor(1.0 / gmin, name=name), p=node, n="0")
        circuit.origin[name] = f"GMIN at node {node!r}"
        note(
            f"node {node!r} has no DC path to ground (only capacitors join it to the rest): "
            f"a conductance GMIN = {gmin:g} S to ground is added there, as ngspice "
            "does ('singular matrix: check node'), so its DC voltage is defined"
        )
