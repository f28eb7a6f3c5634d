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
from ._scope import GROUNDS

#: part roles whose current is a branch unknown of ngspice's equations (saved by default)
BRANCH_ROLES = ("voltage", "inductor")


def select(netlist, saves, problems, note=None, derived=()) -> tuple:
    """``((ngspice name, waveform key), …)`` for ``netlist``; ``saves`` are the
    ``(token, line)`` of its ``.save`` lines; unknown names are added to ``problems``.

    A device's internal quantity (``@m1[id]``, ``@q1[ic]``, ``@d1[cd]``) is not a waveform
    of diracvi's: it is noted through ``note(line, text)`` and left out, and the run goes
    on, as ngspice goes on past a vector it cannot save; if nothing else was asked for,
    the default set is saved. ``derived``: names of vectors that are saved as they are
    (the ``.probe`` differences ``v(vd_…)``, see :func:`probes`)."""
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
        if t in derived:
            chosen.append((t, t))
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


# ------------------------------------------------------------------ .probe

#: ngspice's pin names of a device (inpc_probe.c, get_terminal_number/_name): the
#: name a pin may be given by -> its number, and the number -> the name in a vector name
_PINS = {
    "d": {"a": 1, "c": 2, "k": 2},
    "j": {"d": 1, "g": 2, "s": 3},
    "z": {"d": 1, "g": 2, "s": 3},
    "m": {"d": 1, "g": 2, "s": 3, "b": 4},
    "q": {"c": 1, "b": 2, "e": 3, "s": 4},
}
_PIN_NAMES = {
    "d": {1: "a", 2: "c"},
    "j": {1: "d", 2: "g", 3: "s"},
    "z": {1: "d", 2: "g", 3: "s"},
    "m": {1: "d", 2: "g", 3: "s", 4: "b_tj", 5: "tc", 6: "n6", 7: "n7"},
    "q": {1: "c", 2: "b", 3: "e", 4: "s", 5: "t"},
}
#: elements whose two nodes ``vd(NAME)`` reads (ngspice: an instance of 2 terminals)
TWO_TERMINALS = "rclvidb"


def probe_tokens(text: str) -> list[str]:
    """The parameters of a ``.probe`` line as ngspice takes them (inpc_probe.c): the
    text after the card, ``alli`` removed, cut after each ``)``, blanks removed
    (``vd(MQ6: 2:1)`` is ``vd(mq6:2:1)``), lower-case."""
    body = text.split(None, 1)[1] if len(text.split(None, 1)) > 1 else ""
    body = re.sub(r"(?<![\w(])alli(?![\w)])", " ", body, flags=re.I)
    pieces = body.split(")")
    return [re.sub(r"\s+", "", p).lower() + ")" for p in pieces[:-1] if p.strip()]


def _pin(instances, device: str, pin: str):
    """``(circuit node or None for ground, ngspice's pin name)`` of ``device``'s pin
    ``pin`` (a number or ngspice's letter), or a string saying why there is none."""
    if device not in instances:
        return f"no instance {device!r} at the top level"
    nodes = instances[device]
    letter = device[0]
    if pin == "0":
        return None, "0"
    number = int(pin) if pin.isdigit() else _PINS.get(letter, {}).get(pin[:1])
    if letter not in _PINS or number is None or number < 1:
        return f"pin {pin!r} is not a pin of {device!r}"
    if number > len(nodes):
        return f"{device!r} has {len(nodes)} pins, not {number}"
    node = nodes[number - 1]
    return (None if node in GROUNDS else node), _PIN_NAMES[letter].get(number, f"n{number}")


def _difference(token: str, instances, nodes):
    """``(name, (plus node, minus node))`` of a ``vd(…)`` probe (``None``: ground), or a
    string saying why ngspice skips it."""
    inner = token[3:-1]
    if ":" not in inner:
        if "," in inner:  # vd(node1, node2)
            a, b = inner.split(",", 1)
            ends = []
            for n in (a, b):
                if n not in GROUNDS and n not in nodes:
                    return f"no node {n!r}"
                ends.append(None if n in GROUNDS else n)
            return f"v(vd_{a}:{b})", tuple(ends)
        if inner not in instances:  # vd(R1)
            return f"no instance {inner!r} at the top level"
        if inner[0] not in TWO_TERMINALS or len(instances[inner]) != 2:
            return f"{inner!r} is not a two-terminal element"
        a, b = instances[inner]
        return f"v(vd_{inner})", (None if a in GROUNDS else a, None if b in GROUNDS else b)
    device, rest = inner.split(":", 1)
    if "," in rest:  # vd(M1:1, M2:3)
        pin1, other = rest.split(",", 1)
        if ":" not in other:
            return "the second device's pin is missing (vd(m1:d, m2:s))"
        device2, pin2 = other.split(":", 1)
    else:  # vd(M1:1:3)
        if ":" not in rest:
            return "two pins are needed (vd(m1:d:s))"
        pin1, pin2 = rest.split(":", 1)
        device2 = device
    one, two = _pin(instances, device, pin1), _pin(instances, device2, pin2)
    for end in (one, two):
        if isinstance(end, str):
            return end
    if one[1] == two[1] and device == device2:
        return "the two pins are the same"
    if one[1] == "0" and two[1] == "0":
        return "one of the pins must not be 0"
    if device == device2:
        name = f"v(vd_{device}:{one[1]}:{two[1]})"
    else:
        name = f"v(vd_{device}:{one[1]}_{device2}:{two[1]})"
    return name, (one[0], two[0])


def probes(netlist, tokens, instances, note) -> tuple[list, dict]:
    """ngspice's ``.probe`` vectors: ``(saves, differences)``.

    ``tokens``: ``(parameter, line)`` of the ``.probe`` lines (:func:`probe_tokens`);
    ``instances``: top-level element name -> its nodes in line order. ``vd(a:b)``,
    ``vd(R1)``, ``vd(M1:d:s)``, ``vd(M1:d, M2:d)`` are ``φ₊ − φ₋`` under ngspice's name
    ``v(vd_…)`` (ngspice adds an E source of gain 1 writing the difference to a node
    ``vd_…``); ``differences`` maps that name to its ``(node₊, node₋)`` (``None``:
    ground). ``v(node)`` and ``i(R1)`` (a two-terminal element's current, ngspice's 0 V
    source at its second node) are ``.save`` tokens in ``saves``. A pin current
    ``i(M1:s)`` and a power ``p(M1)`` are not diracvi's vectors and a malformed
    parameter is skipped by ngspice: each is noted, naming its line."""
    nodes = set(netlist.assembly.nodes)
    display = netlist.display
    currents = {display.get(k, k).lower() for k in netlist.assembly.currents}
    saves, differences = [], {}
    for token, line in tokens:
        if token.startswith("vd("):
            found = _difference(token, instances, nodes)
            if isinstance(found, str):
                note(line, f"'.probe {token}' skipped, as ngspice skips it: {found}")
            else:
                differences[found[0]] = found[1]
                saves.append((found[0], line))
        elif token.startswith("v(") and ":" not in token:
            if token[2:-1] in nodes:
                saves.append((token, line))
            else:
                note(line, f"'.probe {token}' skipped, as ngspice skips it: no such node")
        elif token.startswith("i(") and ":" not in token and "," not in token:
            if token[2:-1] in currents:
                saves.append((token, line))
            else:
                note(
                    line,
                    f"'.probe {token}' not reported: diracvi has the currents of "
                    f"{', '.join(sorted(currents)[:6])}{', …' if len(currents) > 6 else ''}",
                )
        elif token.startswith(("i(", "p(", "v(")):
            note(
                line,
                f"'.probe {token}' not reported: diracvi gives no pin current, pin voltage or "
                "power of a device (ngspice's 0 V sources at its pins); vd(dev:pin:0) gives "
                "a pin's voltage, i(R1) a two-terminal element's current",
            )
        else:
            note(
                line, f"'.probe {token}' skipped, as ngspice skips it: not v(…), vd(…), i(…), p(…)"
            )
    return saves, differences


def differences(out: dict, table: dict) -> dict:
    """``out`` with each ``vd`` probe of ``table`` (name -> ``(node₊, node₋)``, ``None``
    for ground) added as ``v(node₊) − v(node₋)``, where ``out`` holds its nodes."""
    for name, ends in table.items():
        terms = [out.get(f"v({n})") if n is not None else 0.0 for n in ends]
        if any(t is None for t in terms):
            continue
        out[name] = terms[0] - terms[1]
    return out
