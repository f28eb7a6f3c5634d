r"""Subcircuits: ``.subckt NAME pins… [params: a=1 b=2]`` … ``.ends`` definitions and the
``X`` lines that instantiate them, flattened as ngspice flattens them.

An instance ``XA n1 n2 SUB [params:] a=…`` copies SUB's body into the circuit with
names scoped by the instance chain, as ngspice reports them: a node ``m`` inside
``XA``'s instance ``X1`` is ``xa.x1.m``, and an element ``V1`` there is ``v.xa.x1.v1``
(its letter, the chain, its name). Pins are the nodes of the ``X`` line; ``0``, ``gnd``
and the ``.global`` nodes are the same everywhere. Parameters: the instance's values
(evaluated where the instance is), else the definition's defaults (evaluated with the
global parameters and the definition's earlier ones); the body sees these over the
enclosing scope's. An instance may also set a parameter that a ``.param`` line of the body
assigns: its value wins over the body's (:func:`body_params`). Definitions and
``.model``\ s inside a definition are local to it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ._lines import Line, NetlistError, Problems, card, split

#: instance chains deeper than this are taken as a subcircuit that instantiates itself
MAX_DEPTH = 30


@dataclass
class Subckt:
    """A ``.subckt`` definition: its pins, parameter defaults (tokens) and body lines."""

    name: str
    pins: tuple[str, ...]
    defaults: dict
    body: list[Line]
    line: Line
    used: list = field(default_factory=list)


def collect(lines: list[Line], problems: Problems) -> tuple[list[Line], dict[str, Subckt]]:
    """Split ``lines`` into the lines outside any ``.subckt`` and the definitions made at
    this level (nested definitions stay in their parent's body)."""
    rest: list[Line] = []
    defs: dict[str, Subckt] = {}
    k = 0
    while k < len(lines):
        line = lines[k]
        word = card(line)
        k += 1
        if word == ".ends":
            problems.add(line.fail("'.ends' without a '.subckt' before it (remove it)"))
            continue
        if word != ".subckt":
            rest.append(line)
            continue
        depth, end = 1, None
        for j in range(k, len(lines)):
            w = card(lines[j])
            depth += (w == ".subckt") - (w == ".ends")
            if depth == 0:
                end = j
                break
        if end is None:
            problems.add(line.fail("'.subckt' without its '.ends' (close the definition)"))
            return rest, defs
        body, k = lines[k:end], end + 1
        try:
            sub = _header(line, body)
        except NetlistError as exc:  # recorded, the definition skipped
            problems.add(exc)
            continue
        if sub.name in defs:
            first = defs[sub.name].line.where
            problems.add(line.fail(f"subcircuit {sub.name!r} is defined twice (first {first})"))
            continue
        defs[sub.name] = sub
    return rest, defs


def body_params(body: list[Line]) -> set[str]:
    """The names a ``.param`` line of ``body`` itself assigns (not those of a definition
    nested in it). ngspice lets an instance's ``name=value`` override such a parameter as
    it overrides a ``params:`` default: a library's ``.subckt RPOT 1 2 3`` with ``.param
    value=1k`` and ``.param ratio=1`` in its body ("default parameters, which are required
    by some simulators", ngspice's ``examples/probe/F5models.lib``) instantiated as ``XP a
    b 0 RPOT value=5k ratio=0.15`` is 750 Ω and 4250 Ω in ngspice 39, not 1 kΩ and 0."""
    names: set[str] = set()
    depth = 0
    for line in body:
        word = card(line)
        depth += (word == ".subckt") - (word == ".ends")
        if word != ".param" or depth:
            continue
        pos, kw = split(line)
        names.update(k.lower() for k in kw)
        if pos[1:]:  # ".param name = expr with blanks": the one name before its '='
            rest = line.text.split(None, 1)[1] if len(line.text.split()) > 1 else ""
            m = re.match(r"\s*([A-Za-z_][\w.]*)\s*=", rest)
            if m:
                names.add(m.group(1).lower())
    return names


def _header(line: Line, body: list[Line]) -> Subckt:
    pos, kw = split(line)
    words = [w for w in pos[1:] if w.lower() != "params:"]
    if not words:
        raise line.fail("expected '.subckt NAME pin… [params: name=value …]'")
    pins = tuple(w.lower() for w in words[1:])
    if len(set(pins)) != len(pins):
        raise line.fail(f"subcircuit {words[0]!r} names a pin twice {list(pins)}")
    return Subckt(words[0].lower(), pins, kw, body, line)


def instance_parts(pos, kw, line):
    """``Xname n… SUBNAME [params:] a=…`` → ``(nodes, subckt name, overrides)``."""
    words = [w for w in pos[1:] if w.lower() != "params:"]
    if not words:
        raise line.fail("expected 'Xname node… SUBNAME [params: name=value …]'")
    return words[:-1], words[-1].lower(), kw
