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

import numpy as np

from .. import components as cp
from ..components._part import fields
from ..components._topology import GROUND, components

#: ngspice's default GMIN (S)
GMIN = 1e-12


def islands(circuit) -> list[str]:
    """The nodes joined to ground through capacitors (a MOSFET's gate branch counts as
    one: no DC current flows into a gate) and no DC path (current sources are none), in
    the order first named.

    A node with no path to ground at all, a cut-set of current sources and a circuit
    without ground stay the topology errors :meth:`~diracvi.components.Circuit.build`
    reports (they are mistakes, not a missing DC path)."""
    # the nodes numbered (0: ground), each branch's ends joined to its first end
    vertex = {GROUND: 0}
    order: list[str] = []  # vertex − 1 -> node
    a, b, kind = [], [], []  # kind: 0 a DC path, 1 a capacitor, 2 a current source
    for part, nodes in circuit._parts:
        f = fields(part)
        roles = dict(f.get("branch_roles", ()))
        branches: dict[str, list[int]] = {}
        for pin, coord, _ in f["pins"]:
            node = nodes.get(pin)
            if node is None:
                continue
            v = vertex.get(node)
            if v is None:
                v = vertex[node] = 0 if circuit._is_ground(node) else len(order) + 1
                if v:
                    order.append(node)
            branches.setdefault(coord, []).append(v)
        for coord, ends in branches.items():
            for other in ends[1:]:
                a.append(ends[0])
                b.append(other)
                role = roles.get(coord, f["role"])
                # a transistor's gate branch (role "current" for the cut-set check)
                # carries only its capacitances' current: no DC path, as a capacitor
                gate = role == "current" and f["role"] == "transistor"
                kind.append(1 if role == "capacitor" or gate else 2 if role == "current" else 0)
    if len(vertex) == len(order) + 1:  # no ground node among them
        return []
    a, b, kind = (np.asarray(x, dtype=np.int64) for x in (a, b, kind))
    # joined through capacitors and DC paths (a current source's branch is neither: a
    # node it alone joins to ground is the cut-set error build reports), and through DC
    # paths alone
    every = components(len(order) + 1, a[kind < 2], b[kind < 2])
    direct = components(len(order) + 1, a[kind == 0], b[kind == 0])
    alone = (every[1:] == every[0]) & (direct[1:] != direct[0])
    return [order[k] for k in np.flatnonzero(alone)]


def add_shunts(circuit, gmin: float, note) -> None:
    """Join each node of :func:`islands` to ground by ``1/gmin`` Ω (``note(text)``)."""
    for node in islands(circuit):
        # a subcircuit's node is 'x8.2'; a part's name may not hold a dot (it separates
        # subsystem and coordinate names): ':' as the subcircuit elements' names have it
        name = f"gmin:{node}".replace(".", ":")
        circuit.add(cp.Resistor(1.0 / gmin, name=name), p=node, n="0")
        circuit.origin[name] = f"GMIN at node {node!r}"
        note(
            f"node {node!r} has no DC path to ground (only capacitors join it to the rest): "
            f"a conductance GMIN = {gmin:g} S to ground is added there, as ngspice "
            "does ('singular matrix: check node'), so its DC voltage is defined"
        )
