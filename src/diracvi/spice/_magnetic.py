r"""XSPICE's magnetic code models ``lcouple`` and ``core``, read as windings on one core.

ngspice draws a magnetic circuit as an electrical one: an MMF (ampere-turns) is a node
voltage and a flux (webers) a branch current. ``Aname (l+ l−) (m+ m−) LMOD`` with
``.model LMOD lcouple(num_turns=N)`` is a winding: between its MMF nodes it puts the
MMF ``V(m+) − V(m−) = N·i`` of its electrical current ``i`` (into ``l+``), and across
its electrical port the voltage ``N dΦ/dt`` of the flux ``Φ`` that leaves it at ``m+``.
``Aname (c+ c−) CMOD`` with ``.model CMOD core(H_array=[…] B_array=[…] area=A
length=l)`` is a core: the flux ``A·B(H)`` from ``c+`` to ``c−``, ``H = (V(c+) −
V(c−))/l``. A resistor between MMF nodes is a linear reluctance (``V = ℛΦ``).

The product of this "voltage" and "current", ``MMF × flux``, is an energy (A·V·s = J),
not a power, so the graph is not taken element by element (its "resistor" stores
energy). A loop of windings closed by one core (or by linear reluctances in series)
*is* one nonlinear coupled inductor: walking the
loop along the core's flux, winding k met from ``m−`` to ``m+`` adds ``+N_k i_k`` to
the MMF across the core and sees ``+N_k dΦ/dt``, met the other way ``−N_k``; so with
those signed turns ``n_k`` the loop is :func:`~diracvi.components.WoundCore` with
``L = W*(Σ n_k q̇_k)`` (:mod:`diracvi.components.magnetic`). The MMF at each loop node
(ngspice's ``v(node)``) is a sum of ``±n_k i_k`` walked from ground: reported as
such (:func:`potentials`).

Read: ``lcouple`` (``num_turns``, default 1) and ``core`` in its PWL mode
(``mode=1``, the default: ``H_array``, ``B_array``, ``area``, ``length``,
``input_domain`` = 0.01, ``fraction`` = TRUE); ports in parentheses or bare, with
``%hd``/``%h`` (lcouple's electrical port), ``%hd`` (its MMF port), ``%gd``/``%g``
(core). Refused, each naming its line: other code models, the core's hysteresis mode,
and magnetic circuits other than single loops of windings with one core or with
linear reluctances (parallel paths, two cores, a core in series with a reluctance).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from ..components.magnetic import PiecewiseLinearCore, Reluctance, WoundCore
from ..errors import ModelError

_TOKEN = re.compile(r"%[A-Za-z]+|[()]|\[|\]|~|[^\s()\[\]~%]+")
_PARAM = re.compile(r"([A-Za-z_]\w*)\s*=\s*(\[[^\]]*\]|\{[^}]*\}|'[^']*'|[^\s=()\[\]]+)")

#: the code models read here: their ports ``(name, default type, allowed types)``
PORTS = {
    "lcouple": (("l", "hd", ("h", "hd")), ("mmf_out", "hd", ("hd",))),
    "core": (("mc", "gd", ("g", "gd")),),
}
#: core parameters of its hysteresis mode, unused in PWL mode (as in ngspice)
HYSTERESIS_ONLY = ("in_low", "in_high", "hyst", "out_lower_limit", "out_upper_limit")
CORE_PARAMS = ("h_array", "b_array", "area", "length", "input_domain", "fraction", "mode")
GROUND = "\0ground"


@dataclass
class Element:
    """One ``A`` line of a magnetic model, its nodes in circuit-wide names."""

    kind: str  # "lcouple" or "core"
    name: str  # the part name (``a:x1:a1``), the label of a winding's current
    display: str  # ngspice's name (``a.x1.a1``)
    line: object
    chain: str
    mmf: tuple  # (m+, m−) or the core's (c+, c−)
    electric: tuple = ()  # a winding's (l+, l−)
    turns: float = 1.0
    law: object = None  # a core's PiecewiseLinearCore


def a_line(ctx, name, pos, kw, line):
    """``Aname port… model`` of ``lcouple`` or ``core``: recorded, built after the
    whole netlist is read (:func:`assemble`), since a winding's loop spans lines."""
    tokens = _TOKEN.findall(line.text)
    if len(tokens) < 3:
        raise line.fail("expected 'Aname port… model' (an XSPICE code model instance)")
    # XSPICE's parameters include vectors: read from the declaration (_lcouple, _core)
    model = ctx.declared(tokens[-1], line, "lcouple(num_turns=…)' or 'core(…)")
    kind = model.kind.lower()
    if kind not in PORTS:
        raise line.fail(
            f"element {pos[0]!r}: the XSPICE code model {kind!r} (model {model.name!r}, "
            f"{model.where}) is not supported; diracvi reads XSPICE's magnetic models "
            "lcouple and core (PWL mode)"
        )
    ports = _ports(tokens[1:-1], PORTS[kind], line, kind)
    chain = ".".join(ctx.path)
    nodes = [tuple(ctx.node(n) for n in port) for port in ports]
    element = Element(kind, name, ctx.display(pos[0]), line, chain, nodes[-1])
    if kind == "lcouple":
        element.electric = nodes[0]
        element.turns = _lcouple(model)
    else:
        element.law = _core(model)
    ctx.reader.magnetics.append(element)
    ctx.reader.display[name] = element.display
    return None, {}


def _ports(tokens, table, line, kind):
    """The ports' node pairs (a single-ended port's second node is ground)."""
    words = [t for t in tokens if t not in "()"]
    if any(t in ("[", "]", "~") for t in words):
        raise line.fail(f"{kind}: vector ports ('[ ]') and inverted ports ('~') are not {kind}'s")
    out, k = [], 0
    for port, default, allowed in table:
        kind_of = default
        if k < len(words) and words[k].startswith("%"):
            kind_of = words[k][1:].lower()
            k += 1
            if kind_of not in allowed:
                raise line.fail(
                    f"{kind} port {port!r} takes the types {['%' + a for a in allowed]}, "
                    f"not %{kind_of}"
                )
        count = 2 if kind_of.endswith("d") else 1
        nodes = words[k : k + count]
        if len(nodes) < count or any(n.startswith("%") for n in nodes):
            raise line.fail(f"{kind} port {port!r} (%{kind_of}) needs {count} node(s)")
        k += count
        out.append(tuple(nodes) if count == 2 else (nodes[0], "0"))
    if k != len(words):
        form = " ".join("(n+ n-)" for _ in table)
        raise line.fail(f"{kind} has {len(table)} port(s): 'Aname {form} model', got {words}")
    return out


def _values(model) -> dict:
    """The ``.model`` line's parameters: ``name -> token`` (vectors kept whole)."""
    body = re.sub(r"^\s*\.model\s+\S+\s+\w+", "", model.line.text, flags=re.I)
    return {k.lower(): v for k, v in _PARAM.findall(body)}


def _lcouple(model) -> float:
    params = _values(model)
    unknown = sorted(set(params) - {"num_turns"})
    if unknown:
        raise model.line.fail(
            f"lcouple model {model.name!r}: unknown parameters {unknown} (it has num_turns)"
        )
    return model.scope.value(params.get("num_turns", "1"), model.line, "num_turns")


def _core(model) -> PiecewiseLinearCore:
    params = _values(model)
    where = f"core model {model.name!r} ({model.where})"
    unknown = sorted(set(params) - set(CORE_PARAMS) - set(HYSTERESIS_ONLY))
    if unknown:
        raise model.line.fail(
            f"{where}: unknown parameters {unknown} (core has "
            f"{', '.join(CORE_PARAMS + HYSTERESIS_ONLY)})"
        )

    def value(key, default=None):
        token = params.get(key)
        if token is None:
            if default is None:
                raise model.line.fail(f"{where}: '{key}' is required (PWL mode)")
            return default
        return model.scope.value(token, model.line, f".model {model.name} {key}")

    mode = value("mode", 1.0)
    if mode != 1.0:
        raise model.line.fail(
            f"{where}: mode={mode:g} (hysteresis) is not supported; diracvi builds the core's "
            "PWL mode (mode=1, the default): give the B(H) curve as H_array/B_array"
        )
    arrays = {}
    for key in ("h_array", "b_array"):
        token = params.get(key)
        if token is None or not token.startswith("["):
            raise model.line.fail(f"{where}: '{key} = [v1 v2 …]' is required (PWL mode)")
        items = token[1:-1].replace(",", " ").split()
        arrays[key] = [model.scope.value(t, model.line, f"{key} entry") for t in items]
    fraction = params.get("fraction", "true").lower()
    if fraction not in ("true", "false", "1", "0"):
        raise model.line.fail(f"{where}: fraction={fraction!r} must be TRUE or FALSE")
    try:
        return PiecewiseLinearCore(
            arrays["h_array"],
            arrays["b_array"],
            area=value("area"),
            length=value("length"),
            input_domain=value("input_domain", 0.01),
            fraction=fraction in ("true", "1"),
        )
    except ModelError as exc:
        raise model.line.fail(f"{where}: {str(exc).split(': ', 1)[-1]}") from None


# --------------------------------------------------------------------- the loops
def assemble(reader) -> None:
    """Join the recorded windings, cores and the resistors between their MMF nodes
    into one :func:`~diracvi.components.WoundCore` per loop, added to the circuit;
    every problem goes to ``reader.problems``."""
    elements = reader.magnetics
    if not elements:
        return
    circuit = reader.circuit
    ground = circuit._is_ground
    magnetic = {n for e in elements for n in e.mmf if not ground(n)}
    for e in elements:
        touch = [n for n in e.electric if n in magnetic]
        if touch:
            _fail(reader, e, f"its electrical port joins the MMF node {touch[0]!r}; keep "
                  "the magnetic circuit (MMF ports, cores, reluctances) apart")  # fmt: skip
            return
    branches = [(e.mmf[0], e.mmf[1], e) for e in elements]
    # resistors between MMF nodes are reluctances; any other part there is refused
    grown = True
    while grown:
        grown = False
        for part, nodes in list(circuit._parts):
            ends = [nodes[p] for p in part.pin_names]
            if not any(n in magnetic for n in ends):
                continue
            where = circuit.origin.get(part.name, part.name)
            r = _resistance(part) if part.role == "resistor" else None
            if r is None:
                first = next(e for e in elements if set(e.mmf) & set(ends))
                shared = [n for n in ends if n in magnetic]
                _fail(reader, first, f"{where} joins its MMF node(s) {shared}; only lcouple "
                      "MMF ports, cores and resistors (linear reluctances) may join a "
                      "magnetic circuit")  # fmt: skip
                return
            circuit.remove(part.name)
            branches.append((ends[0], ends[1], (float(r), where)))
            new = {n for n in ends if not ground(n)} - magnetic
            magnetic |= new
            grown = grown or bool(new)
    for loop in _loops(branches, ground):
        try:
            _build(reader, loop, ground)
        except _Refused as why:
            _fail(reader, why.element, why.text)


def _resistance(part):
    """A linear resistor's ``R`` from its force ``F = −R q̇`` (``None`` if not linear)."""
    zero = np.zeros(1)
    one, two = (float(-part.force(zero, np.array([x]), 0.0)[0]) for x in (1.0, 2.0))
    return one if one > 0.0 and abs(two - 2.0 * one) <= 1e-12 * abs(one) else None


class _Refused(Exception):
    def __init__(self, element, text):
        super().__init__(text)
        self.element, self.text = element, text


def _fail(reader, element, why: str) -> None:
    reader.problems.add(element.line.fail(f"element {element.display!r}: {why}"), element.chain)


def _label(branch) -> str:
    item = branch[2]
    return item.display if isinstance(item, Element) else item[1]


def _loops(branches, ground):
    """The connected groups of branches, ground not joining them (every loop may close
    through ground)."""
    parent = list(range(len(branches)))

    def find(k):
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    seen: dict[str, int] = {}
    for k, (a, b, _) in enumerate(branches):
        for n in (a, b):
            if ground(n):
                continue
            if n in seen:
                parent[find(k)] = find(seen[n])
            else:
                seen[n] = k
    groups: dict[int, list] = {}
    for k, br in enumerate(branches):
        groups.setdefault(find(k), []).append(br)
    return list(groups.values())


def _build(reader, loop, ground) -> None:
    """One loop → a WoundCore part and the MMF of its nodes (or :class:`_Refused`)."""
    windings = [b for b in loop if isinstance(b[2], Element) and b[2].kind == "lcouple"]
    cores = [b for b in loop if isinstance(b[2], Element) and b[2].kind == "core"]
    paths = [b for b in loop if not isinstance(b[2], Element)]
    blame = (windings or cores)[0][2] if windings or cores else None
    if blame is None:
        return  # resistors only, reached from no winding: not a magnetic loop
    nodes = sorted({"0" if ground(n) else n for a, b, _ in loop for n in (a, b)})
    if not windings:
        raise _Refused(blame, f"no lcouple winding is on the magnetic path at {nodes}")
    degree: dict[str, int] = {}
    for a, b, _ in loop:
        for n in (a, b):
            n = GROUND if ground(n) else n
            degree[n] = degree.get(n, 0) + 1
    odd = sorted(n for n, d in degree.items() if d != 2 and n != GROUND)
    at_ground = degree.get(GROUND, 0)
    ends = [n for n in odd if degree[n] == 1]
    if ends:
        raise _Refused(
            blame,
            f"the magnetic path is open at node {ends[0]!r} (one branch reaches it): "
            "nothing carries its flux; close the loop with a core (or a resistor as the "
            "reluctance)",
        )
    if odd or at_ground not in (0, 2):
        where = odd[0] if odd else "ground"
        count = degree[odd[0]] if odd else at_ground
        raise _Refused(
            blame,
            f"the magnetic circuit at nodes {nodes} is not a single loop (node {where!r} "
            f"joins {count} of its branches); diracvi builds windings on one magnetic "
            "path: a loop of lcouple MMF ports closed by one core or by linear reluctances",
        )
    if len(cores) > 1 or (cores and paths):
        what = (
            f"two cores ({cores[0][2].display}, {cores[1][2].display})"
            if len(cores) > 1
            else f"a core ({cores[0][2].display}) in series with a reluctance ({_label(paths[0])})"
        )
        raise _Refused(
            blame,
            f"the loop at nodes {nodes} holds {what}; diracvi builds one core, or linear "
            "reluctances alone, per loop",
        )
    if not cores and not paths:
        raise _Refused(
            blame,
            f"nothing closes the loop of windings at nodes {nodes} (no core, no reluctance): "
            "its flux is undetermined; add a core (or a resistor as the reluctance)",
        )

    def canon(n):
        return GROUND if ground(n) else n

    order = _walk(loop, cores[0] if cores else windings[0], canon)
    # signed turns: a winding met from m− to m+ along the flux raises the MMF by N i
    signs = {}
    for a, _, (_, minus, item) in order:
        if isinstance(item, Element) and item.kind == "lcouple":
            signs[item.name] = 1.0 if a == canon(minus) else -1.0
    signed = [signs[w[2].name] * w[2].turns for w in windings]
    labels = [w[2].name for w in windings]
    total = sum(p[2][0] for p in paths)
    if cores:
        law, owner = cores[0][2].law, cores[0][2].name
    else:
        law, owner = Reluctance(total), windings[0][2].name + ":core"
    part = WoundCore(law, signed, name=owner, labels=labels)
    pins = {}
    for k, w in enumerate(windings):
        pins[f"p{k + 1}"], pins[f"n{k + 1}"] = w[2].electric
    reader.circuit.add(part, **pins)
    reader.circuit.origin[owner] = ", ".join(
        f"{w[2].line.where} ({w[2].display})" for w in windings
    )
    if at_ground == 0:
        reader.notes.append(
            f"{blame.line.where}: the magnetic loop at nodes {nodes} does not reach ground: "
            "its MMF node voltages are undetermined (ngspice: 'singular matrix'), so they "
            "are not reported"
        )
        return
    mmf = dict(zip(labels, signed, strict=True))  # F = Σ mmf[label]·i(label)
    start = next(k for k, (a, _, _) in enumerate(order) if a == GROUND)
    level: dict[str, float] = {}  # the MMF at a node, as coefficients of the currents
    for _, to, (_, _, item) in order[start:] + order[:start]:
        if to == GROUND:
            break
        if isinstance(item, Element) and item.kind == "lcouple":
            rise = {item.name: mmf[item.name]}
        elif isinstance(item, Element):  # the core drops the whole MMF
            rise = {k: -x for k, x in mmf.items()}
        else:  # a reluctance drops its share ℛ_b/ℛ of it
            rise = {k: -x * item[0] / total for k, x in mmf.items()}
        level = {k: level.get(k, 0.0) + rise.get(k, 0.0) for k in {*level, *rise}}
        reader.potentials[to] = tuple(sorted(level.items()))


def _walk(loop, first, canon):
    """The loop's branches in order, as ``(from, to, branch)`` (ground as
    :data:`GROUND`), starting with ``first`` from its ``+`` end (a core: along its flux)."""
    ends = [(canon(a), canon(b)) for a, b, _ in loop]
    k = next(k for k, br in enumerate(loop) if br is first)
    order, used, at = [], set(), ends[k][0]
    while True:
        x, y = ends[k]
        nxt = y if x == at else x
        order.append((at, nxt, loop[k]))
        used.add(k)
        at = nxt
        if len(order) == len(loop):
            return order
        k = next(j for j, (x, y) in enumerate(ends) if j not in used and at in (x, y))


def mmf_values(currents: dict, table: dict) -> dict:
    """The MMF at each node of ``table`` (see :func:`potentials`) from the currents by
    label (an operating point's ``currents``)."""
    return {node: sum(c * currents[k] for k, c in terms) for node, terms in table.items()}


def potentials(out: dict, table: dict, display: dict) -> dict:
    """``out`` with ``v(node)`` added for each MMF node of ``table`` (node ->
    ``((current label, coefficient), …)``), from the currents ``out["i(<name>)"]``."""
    for node, terms in table.items():
        out[f"v({node})"] = sum(c * out[f"i({display.get(k, k)})"] for k, c in terms)
    return out
