r"""The saved vectors: what ``.save`` selects, else what ngspice saves by default.

ngspice saves, without ``.save``, every node voltage ``v(node)`` and every branch
current of its equations: voltage sources and inductors, ``i(vname)``, ``i(lname)``.
Element currents of other parts are saved when asked: ``.save @r1[i]`` (written
``i(@r1[i])``, as ngspice names it) or, a diracvi extension, ``.save i(r1)``. ``.save
all`` is the default set; a bare name is a node. Names are ngspice's: lower-case, and
scoped by the instance chain inside subcircuits (``v(xa.n2)``, ``i(v.xa.v1)``).
"""

from __future__ import annotations

import re

from ..components._part import fields

#: part roles whose current is a branch unknown of ngspice's equations (saved by default)
BRANCH_ROLES = ("voltage", "inductor")


def select(netlist, saves, problems, note=None) -> tuple:
    """``((ngspice name, waveform key), …)`` for ``netlist``; ``saves`` are the
    ``(token, line)`` of its ``.save`` lines; unknown names are added to ``problems``.

    A device's internal quantity (``@m1[id]``, ``@q1[ic]``, ``@d1[cd]``) is not a waveform
    of diracvi's: it is noted through ``note(line, text)`` and left out, and the run goes
    on, as ngspice goes on past a vector it cannot save; if nothing else was asked for,
    the default set is saved."""
    assembly = netlist.assembly
    display = netlist.display
    table = [fields(p) for p, _ in netlist.circuit._parts]  # (read once: see fields)
    elements = {display.get(f["name"], f["name"]).lower() for f in table}
    roles = {f["name"]: f["role"] for f in table}
    # an XSPICE winding's current is no vector of ngspice's (its ports are the A device's)
    windings = {k for f in table if f["role"] == "wound core" for k, _ in f["currents"]}
    currents = {}  # ngspice name (lower) -> waveform key
    branch = []
    for label in assembly.currents:
        shown = display.get(label, label)
        currents[shown.lower()] = f"i({shown})"
        if label in windings:
            continue
        if roles.get(label) in BRANCH_ROLES or label not in roles:  # K: coupled inductors
            branch.append((f"i({shown.lower()})", f"i({shown})"))
    every = (*assembly.nodes, *netlist.potentials)  # with the MMF nodes of magnetic loops
    nodes = [(f"v({n})", f"v({n})") for n in every]
    default = nodes + branch
    if not saves:
        return tuple(default)
    chosen, skipped = [], []
    for token, line in saves:
        t = token.lower().replace(" ", "")
        if t == "all":
            chosen += default
            continue
        m = re.fullmatch(r"([vi])\((.*)\)|@([^\[]+)\[(\w+)\]|([^()@\[\]]+)", t)
        if m is None:
            problems.add(
                line.fail(f"'.save {token}': not a vector name (v(node), i(Vname), @R1[i])")
            )
            continue
        kind, inner, device, what, bare = m.groups()
        if device is not None:
            if what == "i" and device in currents:
                chosen.append((f"i(@{device}[i])", currents[device]))
            elif device in elements and note is not None:
                skipped.append(token)
                note(
                    line,
                    f"'.save {token}' not saved: diracvi saves @name[i] of elements that "
                    f"carry a current of their own ({', '.join(sorted(currents)[:6])}"
                    f"{', …' if len(currents) > 6 else ''}), node voltages and i(Vname)",
                )
            else:
                problems.add(
                    line.fail(
                        f"'.save {token}': diracvi saves a device's current only "
                        f"(@name[i]) of an element of the circuit; elements: {sorted(currents)}"
                    )
                )
            continue
        if kind == "i":
            if inner not in currents:
                problems.add(
                    line.fail(
                        f"'.save {token}': no element {inner!r} (elements: {sorted(currents)})"
                    )
                )
                continue
            chosen.append((f"i({inner})", currents[inner]))
            continue
        node = bare if bare is not None else inner
        if "," in node:
            problems.add(
                line.fail(f"'.save {token}': differential voltages are not saved; save both nodes")
            )
        elif node in ("0", "gnd"):
            problems.add(line.fail(f"'.save {token}': ground is 0 V; remove it"))
        elif node not in every:
            problems.add(line.fail(f"'.save {token}': no node {node!r} (nodes: {list(every)})"))
        else:
            chosen.append((f"v({node})", f"v({node})"))
    if skipped and not chosen:
        note(saves[0][1], "nothing else is saved by .save, so the default vectors are")
        chosen = default
    return tuple(dict.fromkeys(chosen))
