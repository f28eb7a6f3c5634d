r"""Join parts at named nodes: KCL one-forms for electrical nodes, ports for flanges.

For an electrical node ``n`` the Kirchhoff current law is the interaction one-form

    α^n = Σ_{pins at n} sign · dq_branch          (sign +1 where the current enters a part)

over the branch charges of all parts (paper §5.2: ``v^R − v^L − v^C = 0`` for the RLC
circuit). Stacked, one row per node except ground, they form one
:class:`~diracvi.Interaction`; their multipliers are the node potentials (the discrete
λ is the impulse ``−h φ_n``). Mechanical flanges sharing a node are joined by
:func:`~diracvi.connect`. A current-controlled source (``part.senses``) adds one more
row, ``dc − dq_element = 0``, tying its pin-less coordinate to the controlling branch
(:mod:`~diracvi.components.controlled`).
"""

from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.interaction import Interaction, connect
from ..model.interconnect import interconnect
from ..model.sparse_rows import SparseRows
from ..runtime.compile import run_once_jit
from ._part import Part, fields, traced
from ._topology import GROUND, Graph
from .electrical import CoupledInductors, Ground, MutualInductance, template_momentum

GROUND_NAMES = ("0", "gnd")


@dataclass(frozen=True)
class Assembly:
    """A built network: the interconnected system, its initial state and name maps.

    Attributes:
        system: the :class:`~diracvi.InterconnectedSystem` (or the single part).
        q0, p0: initial coordinates and momenta (``p0 = ∂L/∂v(q0, v0)`` per part;
            computed at its first use — a netlist's transient without UIC starts from
            its operating point's momenta and never asks).
        nodes: the electrical nodes with a KCL row, in row order.
        kcl_rows: node -> name of its interaction row (a multiplier name).
        currents: element label -> coordinate name whose velocity is ``i(label)``.
        mechanical: mechanical node -> one flange coordinate at that node.
    """

    system: object
    q0: np.ndarray
    _momenta: object = field(repr=False, compare=False)  # () -> p0, called once by p0
    nodes: tuple[str, ...]
    kcl_rows: dict = field(default_factory=dict)
    currents: dict = field(default_factory=dict)
    mechanical: dict = field(default_factory=dict)

    @functools.cached_property
    def p0(self) -> np.ndarray:
        """``p0 = ∂L/∂v(q0, v0)``, the parts' momenta side by side (:func:`_momenta`:
        NumPy, or JAX's where a part's parameter or the state is traced)."""
        return self._momenta()


class Circuit:
    """A network of parts joined at named nodes (electrical and mechanical).

    ``circuit.add(part, p="n1", n="0")`` joins each pin/flange of ``part`` to a node.
    Nodes ``"0"`` and ``"gnd"`` (any case) are ground, as is any node given a
    :class:`~diracvi.components.Ground`. :meth:`build` checks the topology (floating
    nodes, loops of voltage sources, cut-sets of current sources) and returns an
    :class:`Assembly`.
    """

    def __init__(self, name: str = "circuit"):
        self.name = str(name)
        self._parts: list[tuple[Part, dict]] = []
        self._names: set[str] = set()
        self._grounds: set[str] = set()
        self._couplings: list[MutualInductance] = []
        self._initial: dict[str, tuple[float, float]] = {}
        self.origin: dict[str, str] = {}  # part name -> where it came from (netlist line)

    def add(self, part, **nodes):
        """Join ``part``'s pins/flanges to nodes (keyword = pin, value = node name)."""
        # a part first: isinstance of another class on a Module reads its __class__
        # through equinox's __getattribute__ (a netlist adds 10⁴ parts)
        if not isinstance(part, Part):
            return self._add_other(part, nodes)
        f = fields(part)
        name = f["name"]
        if name in self._names:  # (a set: a scan of the parts is O(N²) overall)
            raise ModelError(f"circuit {self.name!r}: a part named {name!r} exists already.")
        wanted, every = _joined(f["pins"], f["flanges"])
        if nodes.keys() != every:
            missing = [w for w in wanted if w not in nodes]
            extra = [w for w in nodes if w not in wanted]
            raise ModelError(
                f"part {name!r}: join every pin/flange {wanted} to a node "
                f"(missing {missing}, unknown {extra})."
            )
        self._parts.append((part, {k: v if type(v) is str else str(v) for k, v in nodes.items()}))
        self._names.add(name)
        return part

    def remove(self, name: str) -> tuple[Part, dict]:
        """Take part ``name`` out again: ``(part, {pin: node})``. (A netlist reader uses
        it when a line turns out to belong to another domain: a resistor between the
        MMF nodes of XSPICE's magnetic models is a reluctance, not a resistor.)"""
        for k, (part, nodes) in enumerate(self._parts):
            if part.name == name:
                del self._parts[k]
                self._names.discard(name)
                return part, nodes
        raise ModelError(f"circuit {self.name!r} has no part {name!r} to remove.")

    def _add_other(self, part, nodes: dict):
        """:meth:`add` for a :class:`Ground` or a :class:`MutualInductance`."""
        if isinstance(part, Ground):
            if set(nodes) != {"p"}:
                raise ModelError("Ground(): join its single pin, circuit.add(Ground(), p='n0').")
            self._grounds.add(str(nodes["p"]))
            return part
        if isinstance(part, MutualInductance):
            if nodes:
                raise ModelError(f"MutualInductance {part.name!r} has no pins; add it alone.")
            self._couplings.append(part)
            return part
        raise ModelError(
            f"circuit.add({part!r}): not a part; build one with diracvi.components "
            "(Resistor(1.0, name='R1'), Mass(2.0, name='m'), …)."
        )

    @property
    def parts(self) -> tuple[Part, ...]:
        """The parts added so far, in order."""
        return tuple(p for p, _ in self._parts)

    def initial(self, node: str, position: float = 0.0, velocity: float = 0.0) -> None:
        """Initial position and velocity of a mechanical node (default 0, 0)."""
        self._initial[str(node)] = (float(position), float(velocity))

    def _is_ground(self, node: str) -> bool:
        return node.lower() in GROUND_NAMES or node in self._grounds

    def _where(self, name: str) -> str:
        return self.origin.get(name, f"part {name!r}")

    # ----------------------------------------------------------------- build
    def _coupled(self) -> list[tuple[Part, dict]]:
        parts = list(self._parts)
        used: set[str] = set()
        for k in self._couplings:
            found = {}
            for label in (k.first, k.second):
                hit = [(i, p, n) for i, (p, n) in enumerate(parts) if p.name == label]
                if not hit:
                    raise ModelError(
                        f"{self._where(k.name)}: coupled inductor {label!r} is not in the "
                        "circuit; name two inductors added before."
                    )
                if label in used:
                    raise ModelError(
                        f"{self._where(k.name)}: inductor {label!r} is coupled twice; only "
                        "pairwise coupling (one K per inductor) is supported."
                    )
                found[label] = hit[0]
            (_, a, na), (_, b, nb) = found[k.first], found[k.second]
            la, lb = _inductance(a), _inductance(b)
            if la is None or lb is None:
                raise ModelError(
                    f"{self._where(k.name)}: K couples linear inductors only; "
                    f"{k.first!r}/{k.second!r} is not one."
                )
            used.update((k.first, k.second))
            part = CoupledInductors(
                (la, lb),
                k.coupling,
                name=k.name,
                labels=(k.first, k.second),
                i0=(a.initial_v[0], b.initial_v[0]),
            )
            nodes = {"p1": na["p"], "n1": na["n"], "p2": nb["p"], "n2": nb["n"]}
            parts = [x for x in parts if x[0].name not in (k.first, k.second)]
            parts.append((part, nodes))
            self.origin.setdefault(k.name, self._where(k.name))
        return parts

    def build(self) -> Assembly:
        """Check the topology and assemble the interconnected system."""
        parts = self._coupled()
        if not parts:
            raise ModelError(f"circuit {self.name!r} has no parts; add some before build().")
        # every per-part read from the parts' fields, in one pass (see _part.fields)
        table = [fields(p) for p, _ in parts]
        names = [f["name"] for f in table]
        offsets = np.cumsum([0] + [len(f["_coords"]) for f in table])
        total = int(offsets[-1])

        # electrical: the nodes numbered (vertex 0: ground), each pin an incidence entry,
        # each branch (part, coordinate) an edge between its + and − pins' nodes
        vertex: dict[str, int] = {GROUND: 0}
        labels = [GROUND]  # vertex -> node name
        first: dict[str, None] = {}  # the nodes with a pin, in the order first joined
        pin_vertex, pin_col, pin_sign = [], [], []
        ea, eb, kinds, owners, written = [], [], [], [], []
        for (_, nodes), f, start in zip(parts, table, offsets[:-1].tolist(), strict=True):
            pins = f["pins"]
            if not pins:
                continue
            at = _positions(f["_coords"])
            ends: dict[str, dict[int, str]] = {}
            for pin, coord, sign in pins:
                node = nodes[pin]
                v = vertex.get(node)
                if v is None:
                    v = vertex[node] = 0 if self._is_ground(node) else len(labels)
                    if v:
                        labels.append(node)
                first[node] = None
                pin_vertex.append(v)
                pin_col.append(start + at[coord])
                pin_sign.append(sign)
                ends.setdefault(coord, {})[sign] = node
            # a branch end inside the part (a transistor's internal node b′, joined by the
            # part's own KCL constraint) counts as one part-internal node for the checks
            name, inner = f["name"], None
            roles = dict(f.get("branch_roles", ()))
            for coord, e in ends.items():
                pair = []
                for sign in (1, -1):
                    node = e.get(sign)
                    if node is None:
                        if inner is None:
                            inner = len(labels)
                            labels.append(f"{name}\0internal")
                        pair.append(labels[inner])
                    else:
                        pair.append(node)
                ea.append(vertex.get(pair[0], inner))
                eb.append(vertex.get(pair[1], inner))
                kinds.append(roles.get(coord, f["role"]))
                owners.append(name)
                written.append(pair)
        pairs = zip(parts, table, strict=True)
        mech_nodes = {nodes[fl] for (_, nodes), f in pairs for fl, _, _ in f["flanges"]}
        clash = mech_nodes & set(first)
        if clash:
            raise ModelError(
                f"nodes {sorted(clash)} join both electrical pins and mechanical flanges; "
                "use an EMF or VoiceCoil between the two domains and distinct node names."
            )
        node_list = [n for n in first if vertex[n]]
        if first:
            graph = Graph(labels, ea, eb, kinds, owners, written)
            self._check_topology(graph, len(node_list) < len(first), node_list, vertex)
        # the node–branch incidence matrix, sparse: 2 entries per branch, O(N) in memory
        # (dense it would be nodes × coordinates: 4.8 GB for a ladder of 10⁴ stages);
        # a node's row is its place in node_list (first joined), ground has none
        row_of = np.full(len(labels), -1, dtype=np.int64)
        row_of[[vertex[n] for n in node_list]] = np.arange(len(node_list))
        rows = row_of[np.asarray(pin_vertex, dtype=np.int64)]
        kept = rows >= 0
        forms = SparseRows(
            rows[kept],
            np.asarray(pin_col, dtype=np.int64)[kept],
            np.asarray(pin_sign, dtype=np.float64)[kept],
            (len(node_list), total),
        )
        kcl_rows = {n: f"KCL({n})" for n in node_list}

        # mechanical: flanges at a node -> connect(first, other)
        at_node: dict[str, list[tuple[str, str, int]]] = {}
        for (_, nodes), f, start in zip(parts, table, offsets[:-1].tolist(), strict=True):
            for flange, coord, kind in f["flanges"]:
                col = start + _positions(f["_coords"])[coord]
                at_node.setdefault(nodes[flange], []).append((f"{f['name']}.{coord}", kind, col))
        ports = []
        for node, members in at_node.items():
            kinds = {k for _, k, _ in members}
            if len(kinds) > 1:
                raise ModelError(
                    f"mechanical node {node!r} joins translational and rotational flanges "
                    f"({[c for c, _, _ in members]}); a joint needs one kind."
                )
            ports += [connect(members[0][0], c, name=f"{node}:{c}") for c, _, _ in members[1:]]

        q0, v0 = _initial_state(table)
        xp = np if isinstance(q0, np.ndarray) else jnp
        for node, members in at_node.items():
            x, v = self._initial.get(node, (0.0, 0.0))
            for _, _, col in members:
                if xp is np:
                    q0[col], v0[col] = x, v
                else:
                    q0, v0 = q0.at[col].set(x), v0.at[col].set(v)
        unknown = set(self._initial) - set(at_node)
        if unknown:
            raise ModelError(
                f"initial(...) names {sorted(unknown)}, which are not mechanical nodes of "
                f"circuit {self.name!r} (nodes: {sorted(at_node)})."
            )
        interactions = []
        if node_list:
            interactions.append(Interaction(forms, names=tuple(kcl_rows[n] for n in node_list)))
        interactions += self._sense_rows(table, offsets)
        interactions += ports
        if len(parts) == 1 and not interactions:
            system = parts[0][0]
            prefix = ""
        else:
            if len(parts) == 1:
                raise ModelError(
                    f"circuit {self.name!r} has a single part {names[0]!r}; nothing to join."
                )
            system = interconnect([p for p, _ in parts], interactions, name=self.name)
            prefix = None
        momenta = functools.partial(_momenta, system, parts, q0, v0, offsets)
        currents = {}
        for f in table:
            name = f["name"]
            for label, coord in f["currents"]:
                currents[label or name] = f"{name}.{coord}" if prefix is None else coord
        mechanical = {node: members[0][0] for node, members in at_node.items()}
        return Assembly(system, q0, momenta, tuple(node_list), kcl_rows, currents, mechanical)

    def _sense_rows(self, table, offsets) -> list:
        """One row ``dc − dq_element = 0`` per current-controlled source (``part.senses``):
        the pin-less coordinate ``c`` of the source follows the controlling element's
        branch charge. The source's ``c``-line is ``0 = ν`` (nothing in its ``L`` or ``F``
        depends on ``c``), so the row's multiplier vanishes and the controlling branch
        feels no reaction (see :mod:`~diracvi.components.controlled`)."""
        if not any(f.get("senses") for f in table):
            return []
        branch = {}  # i(label) -> the column of its coordinate
        for f, start in zip(table, offsets[:-1].tolist(), strict=True):
            for label, coord in f["currents"]:
                branch[label or f["name"]] = start + _positions(f["_coords"])[coord]
        lower = {k.lower(): v for k, v in branch.items()}
        rows, names = [], []
        for f, start in zip(table, offsets[:-1].tolist(), strict=True):
            for coord, element in f.get("senses", ()):
                target = branch.get(element, lower.get(element.lower()))
                if target is None:
                    raise ModelError(
                        f"{self._where(f['name'])}: the controlling element {element!r} is "
                        f"not in circuit {self.name!r}; name an element whose current is "
                        f"reported, one of {sorted(branch)} (SPICE: a voltage source)."
                    )
                r = len(names)
                rows.append((r, start + _positions(f["_coords"])[coord], 1.0))
                rows.append((r, target, -1.0))
                names.append(f"sense({f['name']})")
        r, c, v = np.array(rows, dtype=np.float64).T
        shape = (len(names), int(offsets[-1]))
        return [Interaction(SparseRows(r, c, v, shape), names=tuple(names))]

    def _check_topology(self, graph: Graph, grounded: bool, node_list, vertex) -> None:
        """No ground, floating nodes, cut-sets of current sources, loops of voltage
        sources (:class:`~._topology.Graph`); a node with a single connection is allowed
        (as in SPICE): KCL holds that branch's current at 0 — a voltage source's node
        follows the source, a capacitor's keeps its charge; a lone current source is a
        cut-set."""
        if not grounded:
            raise ModelError(
                f"circuit {self.name!r} has no ground node: name one node '0' or 'gnd' "
                "(SPICE's reference, potential 0)."
            )
        nodes = np.array([vertex[n] for n in node_list], dtype=np.int64)
        graph.check(nodes, self._where, self.name)


#: from this many parts the initial momenta are one compiled call on the packed
#: interconnection (one trace per kind of part) instead of one eager call per part
_BATCH_MOMENTA = 8


@run_once_jit
def _packed_momentum(system, q, v):
    """``p = ∂L/∂v(q, v, 0)`` of the packed interconnection: one program, kept in the
    store (a later process loads it untraced)."""
    return system.momentum(q, v, 0.0)


@run_once_jit
def _part_momenta(parts, qs, vs):
    """``p_i = ∂L_i/∂v(q_i, v_i)`` (and a charge port's ``Q_i``) of each of ``parts`` at
    its own ``(q_i, v_i)``: one program, kept in the store. Evaluated eagerly, each
    operation of each part's Lagrangian was an XLA program of its own, compiled in every
    process (a deck with two BJTs: 40 of them, 2 s of its read)."""
    return tuple(part.momentum(q, v) for part, q, v in zip(parts, qs, vs, strict=True))


def _closed_momenta(parts, q0, v0, offsets):
    """The momenta of a circuit whose parts are linear R, L, C but for fewer than
    :data:`_BATCH_MOMENTA` others (a source, a diode): the template parts' in closed
    form (:func:`~.electrical.template_momentum`), the others' by one compiled call
    (:func:`_part_momenta`); ``None`` otherwise, or where a part's parameter is traced."""
    p0, rest = np.zeros(len(v0)), []
    for (part, _), a, b in zip(parts, offsets[:-1].tolist(), offsets[1:].tolist(), strict=True):
        known = template_momentum(fields(part), v0[a]) if b - a == 1 else None
        if known is None:
            rest.append((part, a, b))
            if len(rest) >= _BATCH_MOMENTA:
                return None
        else:
            p0[a] = known
    if rest:
        found = _part_momenta(
            tuple(part for part, _, _ in rest),
            tuple(q0[a:b] for _, a, b in rest),
            tuple(v0[a:b] for _, a, b in rest),
        )
        if any(traced(p) for p in found):
            return None
        for (_, a, b), p in zip(rest, found, strict=True):
            p0[a:b] = np.asarray(p)
    return p0


def _momenta(system, parts, q0, v0, offsets):
    """``p0 = ∂L/∂v(q0, v0)``: the parts' momenta, side by side (``L = Σ L_i``); NumPy,
    or JAX's where a part's parameter or the state is traced (a netlist read inside a
    traced fit). A circuit of linear R, L, C only has them in closed form."""
    if isinstance(v0, np.ndarray) and isinstance(q0, np.ndarray):
        p0 = _closed_momenta(parts, q0, v0, offsets)
        if p0 is not None:
            return p0
    # the method is read from the class: read from a Module, equinox binds it as a PyTree
    # and checks every leaf of the system — 0.5 s per call at 10⁴ parts
    packed = getattr(type(system), "_packed", None)
    if len(parts) >= _BATCH_MOMENTA and packed is not None:
        p0 = _packed_momentum(packed(system), q0, v0)
    else:
        p0 = jnp.concatenate(
            [
                jnp.atleast_1d(jnp.asarray(p.momentum(q0[a:b], v0[a:b])))
                for (p, _), a, b in zip(parts, offsets[:-1], offsets[1:], strict=True)
            ]
        )
    return p0 if traced(p0) else np.asarray(p0)


@functools.cache
def _joined(pins, flanges) -> tuple[tuple[str, ...], frozenset]:
    """A part's pins and flanges in order (``pin_names``, ``flange_names``), and as a
    set: once per kind of part (its ``pins`` and ``flanges`` tuples are the key)."""
    wanted = (*dict.fromkeys(p for p, _, _ in pins), *(f for f, _, _ in flanges))
    return wanted, frozenset(wanted)


@functools.cache
def _positions(coords) -> dict:
    """coordinate -> its position in a part's ``coords`` (once per tuple of names)."""
    return {c: i for i, c in enumerate(coords)}


def _initial_state(table):
    """``(q0, v0)``: the parts' own initial coordinates and velocities, side by side
    (NumPy; JAX's where one is traced, a differentiated capacitance, say)."""
    q = list(itertools.chain.from_iterable(f["initial_q"] for f in table))
    v = list(itertools.chain.from_iterable(f["initial_v"] for f in table))
    # a part stores floats (or the tracers it was given): one type test per number
    if all(type(x) is float for x in q) and all(type(x) is float for x in v):
        return np.array(q, dtype=np.float64), np.array(v, dtype=np.float64)
    if not any(traced(x) for x in (*q, *v)):
        return np.asarray(q, dtype=np.float64), np.asarray(v, dtype=np.float64)
    return jnp.asarray(q, dtype=float), jnp.asarray(v, dtype=float)


def _inductance(part: Part):
    return dict(part.parameters).get("inductance") if part.role == "inductor" else None
