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

from dataclasses import dataclass, field

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.interaction import Interaction, connect
from ..model.interconnect import interconnect
from ..model.sparse_rows import SparseRows
from ._part import Part, traced
from .electrical import CoupledInductors, Ground, MutualInductance

GROUND_NAMES = ("0", "gnd")


@dataclass(frozen=True)
class Assembly:
    """A built network: the interconnected system, its initial state and name maps.

    Attributes:
        system: the :class:`~diracvi.InterconnectedSystem` (or the single part).
        q0, p0: initial coordinates and momenta (``p0 = ∂L/∂v(q0, v0)`` per part).
        nodes: the electrical nodes with a KCL row, in row order.
        kcl_rows: node -> name of its interaction row (a multiplier name).
        currents: element label -> coordinate name whose velocity is ``i(label)``.
        mechanical: mechanical node -> one flange coordinate at that node.
    """

    system: object
    q0: np.ndarray
    p0: np.ndarray
    nodes: tuple[str, ...]
    kcl_rows: dict = field(default_factory=dict)
    currents: dict = field(default_factory=dict)
    mechanical: dict = field(default_factory=dict)


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
        if part.name in self._names:  # (a set: a scan of the parts is O(N²) overall)
            raise ModelError(f"circuit {self.name!r}: a part named {part.name!r} exists already.")
        wanted = (*part.pin_names, *part.flange_names)
        missing = [w for w in wanted if w not in nodes]
        extra = [w for w in nodes if w not in wanted]
        if missing or extra:
            raise ModelError(
                f"part {part.name!r}: join every pin/flange {wanted} to a node "
                f"(missing {missing}, unknown {extra})."
            )
        self._parts.append((part, {k: str(v) for k, v in nodes.items()}))
        self._names.add(part.name)
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
        names = [p.name for p, _ in parts]
        offsets = np.cumsum([0] + [p.n for p, _ in parts])
        coords = [f"{p.name}.{c}" for p, _ in parts for c in p.coords]
        index = {c: i for i, c in enumerate(coords)}

        # electrical: branches (part, coordinate) -> the nodes of their + and − pins
        incidence: dict[str, list[tuple[int, int]]] = {}
        branches = []  # (part name, kind, node+, node−)
        for part, nodes in parts:
            ends: dict[str, dict[int, str]] = {}
            for pin, coord, sign in part.pins:
                node = nodes[pin]
                incidence.setdefault(node, []).append((index[f"{part.name}.{coord}"], sign))
                ends.setdefault(coord, {})[sign] = node
            # a branch end inside the part (a transistor's internal node b′, joined by the
            # part's own KCL constraint) counts as one part-internal node for the checks
            inner = f"{part.name}\0internal"
            for coord, e in ends.items():
                branches.append((part.name, _kind(part, coord), e.get(1, inner), e.get(-1, inner)))
        mech_nodes = {n for part, nodes in parts for f in part.flange_names for n in [nodes[f]]}
        clash = mech_nodes & set(incidence)
        if clash:
            raise ModelError(
                f"nodes {sorted(clash)} join both electrical pins and mechanical flanges; "
                "use an EMF or VoiceCoil between the two domains and distinct node names."
            )
        node_list = [n for n in incidence if not self._is_ground(n)]
        if incidence:
            self._check_topology(incidence, branches, node_list)
        # the node–branch incidence matrix, sparse: 2 entries per branch, O(N) in memory
        # (dense it would be nodes × coordinates: 4.8 GB for a ladder of 10⁴ stages)
        entries = [(r, col, sign) for r, n in enumerate(node_list) for col, sign in incidence[n]]
        rows, cols, signs = np.array(entries, dtype=np.float64).reshape(-1, 3).T
        forms = SparseRows(rows, cols, signs, (len(node_list), len(coords)))
        kcl_rows = {n: f"KCL({n})" for n in node_list}

        # mechanical: flanges at a node -> connect(first, other)
        at_node: dict[str, list[tuple[str, str]]] = {}
        for part, nodes in parts:
            for flange, coord, kind in part.flanges:
                at_node.setdefault(nodes[flange], []).append((f"{part.name}.{coord}", kind))
        ports = []
        for node, members in at_node.items():
            kinds = {k for _, k in members}
            if len(kinds) > 1:
                raise ModelError(
                    f"mechanical node {node!r} joins translational and rotational flanges "
                    f"({[c for c, _ in members]}); a joint needs one kind."
                )
            ports += [connect(members[0][0], c, name=f"{node}:{c}") for c, _ in members[1:]]

        # a traced initial state (a differentiated capacitance, say) stays a JAX array
        xp = jnp if any(traced(x) for p, _ in parts for x in p.initial_q + p.initial_v) else np
        q0 = xp.concatenate([xp.asarray(p.initial_q, dtype=float) for p, _ in parts])
        v0 = xp.concatenate([xp.asarray(p.initial_v, dtype=float) for p, _ in parts])
        for node, members in at_node.items():
            x, v = self._initial.get(node, (0.0, 0.0))
            for c, _ in members:
                if xp is np:
                    q0[index[c]], v0[index[c]] = x, v
                else:
                    q0, v0 = q0.at[index[c]].set(x), v0.at[index[c]].set(v)
        unknown = set(self._initial) - set(at_node)
        if unknown:
            raise ModelError(
                f"initial(...) names {sorted(unknown)}, which are not mechanical nodes of "
                f"circuit {self.name!r} (nodes: {sorted(at_node)})."
            )
        interactions = []
        if node_list:
            interactions.append(Interaction(forms, names=tuple(kcl_rows[n] for n in node_list)))
        interactions += self._sense_rows(parts, index)
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
        p0 = _momenta(system, parts, q0, v0, offsets)
        currents = {}
        for part, _ in parts:
            for label, coord in part.currents:
                key = label or part.name
                currents[key] = f"{part.name}.{coord}" if prefix is None else coord
        mechanical = {node: members[0][0] for node, members in at_node.items()}
        return Assembly(system, q0, p0, tuple(node_list), kcl_rows, currents, mechanical)

    def _sense_rows(self, parts, index) -> list:
        """One row ``dc − dq_element = 0`` per current-controlled source (``part.senses``):
        the pin-less coordinate ``c`` of the source follows the controlling element's
        branch charge. The source's ``c``-line is ``0 = ν`` (nothing in its ``L`` or ``F``
        depends on ``c``), so the row's multiplier vanishes and the controlling branch
        feels no reaction (see :mod:`~diracvi.components.controlled`)."""
        branch = {}  # i(label) -> the full name of its coordinate
        for part, _ in parts:
            for label, coord in part.currents:
                branch[label or part.name] = f"{part.name}.{coord}"
        lower = {k.lower(): v for k, v in branch.items()}
        rows, names = [], []
        for part, _ in parts:
            for coord, element in getattr(part, "senses", ()):
                target = branch.get(element, lower.get(element.lower()))
                if target is None:
                    raise ModelError(
                        f"{self._where(part.name)}: the controlling element {element!r} is "
                        f"not in circuit {self.name!r}; name an element whose current is "
                        f"reported, one of {sorted(branch)} (SPICE: a voltage source)."
                    )
                r = len(names)
                rows.append((r, index[f"{part.name}.{coord}"], 1.0))
                rows.append((r, index[target], -1.0))
                names.append(f"sense({part.name})")
        if not rows:
            return []
        r, c, v = np.array(rows, dtype=np.float64).T
        return [Interaction(SparseRows(r, c, v, (len(names), len(index))), names=tuple(names))]

    def _check_topology(self, incidence, branches, node_list) -> None:
        grounds = [n for n in incidence if self._is_ground(n)]
        if not grounds:
            raise ModelError(
                f"circuit {self.name!r} has no ground node: name one node '0' or 'gnd' "
                "(SPICE's reference, potential 0)."
            )
        # a node with a single connection is allowed (as in SPICE): KCL holds that
        # branch's current at 0 — a voltage source's node follows the source, a
        # capacitor's keeps its charge; a lone current source is a cut-set (below)
        gnd = "\0ground"

        def canon(node):
            return gnd if self._is_ground(node) else node

        def components(kinds_out):
            uf = _UnionFind()
            for _name, kind, a, b in branches:
                uf.find(canon(a)), uf.find(canon(b))
                if kind not in kinds_out:
                    uf.union(canon(a), canon(b))
            return uf

        uf = components(())
        away = sorted(n for n in node_list if uf.find(n) != uf.find(gnd))
        if away:
            raise ModelError(
                f"nodes {away} are floating: no path of elements joins them to ground "
                "(node '0'); connect them to the rest of the circuit."
            )
        uf = components(("current",))
        cut = sorted(n for n in node_list if uf.find(n) != uf.find(gnd))
        if cut:
            srcs = sorted(
                self._where(b[0])
                for b in branches
                if b[1] == "current" and (canon(b[2]) in cut) != (canon(b[3]) in cut)
            )
            raise ModelError(
                f"nodes {cut} reach ground only through current sources ({', '.join(srcs)}): "
                "a cut-set of current sources, whose currents KCL cannot reconcile; add a "
                "resistor to ground."
            )
        uf = _UnionFind()
        for name, kind, a, b in branches:
            if kind == "voltage":
                if uf.find(canon(a)) == uf.find(canon(b)):
                    raise ModelError(
                        f"{self._where(name)} closes a loop of voltage sources (between "
                        f"nodes {a!r} and {b!r}): their voltages over-determine the loop; "
                        "add a series resistance or remove one source."
                    )
                uf.union(canon(a), canon(b))


#: from this many parts the initial momenta are one compiled call on the packed
#: interconnection (one trace per kind of part) instead of one eager call per part
_BATCH_MOMENTA = 8


@eqx.filter_jit
def _packed_momentum(system, q, v):
    return system.momentum(q, v, 0.0)


def _momenta(system, parts, q0, v0, offsets):
    """``p0 = ∂L/∂v(q0, v0)``: the parts' momenta, side by side (``L = Σ L_i``); NumPy,
    or JAX's where a part's parameter or the state is traced (a netlist read inside a
    traced fit)."""
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


def _kind(part: Part, coord: str) -> str:
    """The topology role of one branch: a controlled source's own per-branch roles
    (its sensing branch is an open circuit), else the part's role."""
    return dict(getattr(part, "branch_roles", ())).get(coord, part.role)


def _inductance(part: Part):
    return dict(part.parameters).get("inductance") if part.role == "inductor" else None


class _UnionFind:
    def __init__(self):
        self.parent: dict = {}

    def find(self, x):
        self.parent.setdefault(x, x)
        while self.parent[x] != x:
            self.parent[x] = self.parent[self.parent[x]]
            x = self.parent[x]
        return x

    def union(self, a, b):
        self.parent[self.find(a)] = self.find(b)
