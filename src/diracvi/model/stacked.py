r"""Alike subsystems stored once per group: stacked parameters, stepped with ``jax.vmap``.

An interconnection of M subsystems assembles its equations subsystem by subsystem,
``E = Σ_i E^i(q_i, v_i)``, ``p = ⊕_i p^i``, ``ω_d = ⊕_i ω_d^i``. Written as Python loops,
a model torn into 10⁴ pieces traces 10⁴ copies of each term and hands the compiled
program 2·10⁴ parameter arrays; XLA then needs minutes to hours for it. Subsystems that
are alike — the same PyTree structure and static fields (names aside) and the same leaf
shapes (:func:`structure_key`) — compute the same function of different numbers, so a
group ``G = {i_1 < … < i_G}`` is stored as

    S_G = stack(θ_{i_1}, …, θ_{i_G})     (one array per parameter leaf, leading axis G)

and every per-subsystem term becomes one ``jax.vmap`` over ``S_G``: the program has a
few operands per *kind* of subsystem, and its size does not grow with their number.

A subsystem's block of a global vector (its coordinates, its constraint rows) is read
as a reshaped slice when consecutive subsystems of one group lie side by side — a
*run* — and only when a model has many short runs (pieces of different kinds
interleaved) through an index table of the group's positions.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
from functools import cached_property

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

#: above this many runs, a group's blocks are gathered and scattered through one index
#: table per group instead of one slice per run (the program stays O(groups) in size)
MAX_RUNS = 64


#: the entry of a subsystem's instance dictionary (not a field: no PyTree sees it) by
#: which a copy of another subsystem with one array leaf replaced says so, as
#: ``(token, leaf)``: subsystems with equal tokens have equal structure keys, and
#: ``leaf`` is their only array leaf. :func:`pack` then flattens one of them, not each
#: (``components/electrical.py`` makes a netlist's R, L and C this way: 10⁵ flattenings
#: were a third of the packing of a 10⁵-element ladder).
ALIKE = "__alike__"


def structure_key(sub):
    """What must agree for two subsystems to be stacked: the PyTree structure with every
    static field (the subsystem's own name aside — it enters no equation) and, per leaf,
    the shape and dtype of an array or the value of anything else."""
    return _keyed(sub)[0]


def _keyed(sub):
    """``(structure_key(sub), the array leaves of sub)`` from one flattening."""
    kind = type(sub)
    names = _field_names(kind)
    if "name" in names:
        proxy = object.__new__(kind)
        fields = _dict(proxy)
        fields.update(_dict(sub))  # (a dataclass keeps every field in its __dict__)
        fields["name"] = ""
    else:
        proxy = sub
    leaves, treedef = jax.tree_util.tree_flatten(proxy)
    parts, arrays = [], []
    for leaf in leaves:
        if eqx.is_array(leaf):  # (a dtype is its own key: its str() costs microseconds)
            parts.append(("array", leaf.shape, leaf.dtype))
            arrays.append(leaf)
        else:
            try:
                hash(leaf)
                parts.append(("value", type(leaf), leaf))
            except TypeError:
                parts.append(("object", id(leaf)))
    return (treedef, tuple(parts)), arrays


@functools.cache
def _field_names(kind: type) -> tuple[str, ...]:
    """The dataclass fields of ``kind`` (none for another class)."""
    if not dataclasses.is_dataclass(kind):
        return ()
    return tuple(f.name for f in dataclasses.fields(kind))


def _dict(obj) -> dict:
    """``vars(obj)``, read past equinox's ``__getattribute__`` (a Python-level hook that
    costs about a microsecond per read: building a model of 10⁴ parts reads millions)."""
    return object.__getattribute__(obj, "__dict__")


class Skeletons(tuple):
    """The subsystems of a packed interconnection with their arrays replaced by
    ``jax.ShapeDtypeStruct`` placeholders (names, sizes and flags stay readable; any
    arithmetic on a placeholder fails loudly). A tuple *subclass* is one PyTree leaf,
    so flattening the system does not walk 10⁴ subsystems; it compares and hashes by
    identity (it is static data of one packing).

    ``groups``, set by :func:`pack`: ``(members, firsts)``, the indices of each group
    and its first member's skeleton; every member's skeleton is its group's first
    with the member's own name (:func:`_renamed`). The program store's key prints
    these (:meth:`__stored__`), not every skeleton."""

    groups = None  # (an instance attribute once packed: no __slots__, so it can be set)

    def __stored__(self):
        """What the program store's key (:mod:`diracvi.runtime.fingerprint`) prints: each
        group's first skeleton in full, the groups' members (by value) and every name.
        That determines every skeleton — a member is its group's first renamed — in
        time independent of the member count: printing 3001 skeletons one by one was
        0.13 s of every build of a 1000-stage ladder's sparse map, and grew with N."""
        if self.groups is None:  # (not made by pack: each skeleton in full)
            return ("Skeletons", tuple(self))
        members, firsts = self.groups
        digests = tuple(
            hashlib.sha256(np.ascontiguousarray(m).tobytes()).hexdigest() for m in members
        )
        names = tuple(_name(s, "") for s in self)
        return ("Skeletons", len(self), digests, firsts, names)

    def __hash__(self) -> int:
        return id(self)

    def __eq__(self, other) -> bool:
        return self is other

    def __ne__(self, other) -> bool:
        return self is not other


def _is_placeholder(leaf) -> bool:
    return isinstance(leaf, jax.ShapeDtypeStruct)


def _placeholder(leaf):
    if eqx.is_array(leaf):
        return jax.ShapeDtypeStruct(np.shape(leaf), jnp.result_type(leaf))
    return leaf


def _name(sub, default: str) -> str:
    """``sub.name`` (``default`` if it has none), from its fields where it is one."""
    own = _dict(sub)
    return own["name"] if "name" in own else getattr(sub, "name", default)


def _renamed(skeleton, name: str):
    """``skeleton`` with another ``name`` (a shallow copy: every other field is shared)."""
    if _name(skeleton, name) == name:
        return skeleton
    copy = object.__new__(type(skeleton))
    fields, own = _dict(copy), _dict(skeleton)
    for field in _field_names(type(skeleton)):
        fields[field] = own[field] if field in own else getattr(skeleton, field)
    fields["name"] = name
    return copy


def _stack_leaves(columns):
    """One stacked array per leaf position (NumPy on the host when every value is
    concrete: a device transfer per group and leaf, not per subsystem)."""
    out = []
    for xs in columns:
        if any(isinstance(x, jax.core.Tracer) for x in xs):
            out.append(jnp.stack(xs))
        else:
            # (device_put, not jnp.asarray: that compiles a copy program per new shape,
            # ~0.1 s for each group size a model brings)
            out.append(jax.device_put(np.stack([np.asarray(x) for x in xs])))
    return out


class Tables:
    """Host-side description of the groups of a packing (static; compared by identity).

    ``members[g]``: subsystem indices of group g (ascending); ``group_of[i]``,
    ``position[i]``: subsystem i's group and place in it; ``rests[g]``: the first member
    with its arrays partitioned out (``equinox.combine`` with a slice of the stacks gives
    a member); ``runs``: ``(g, a, b)`` for maximal stretches of consecutive subsystems
    that are members ``a … b−1`` of group g, in subsystem order; ``sizes[kind][g]``: the
    block size of a member of g in a global vector of that kind (``"n"`` coordinates,
    ``"m"`` own constraint rows, ``"k"`` holonomic rows).
    """

    def __init__(self, members, rests, skeletons):
        self.members = tuple(members)
        count = sum(len(m) for m in members)
        self.group_of = np.empty(count, dtype=np.int64)
        self.position = np.empty(count, dtype=np.int64)
        for g, mem in enumerate(self.members):
            self.group_of[mem] = g
            self.position[mem] = np.arange(len(mem))
        runs, start = [], 0
        for i in range(1, count + 1):
            if i == count or self.group_of[i] != self.group_of[start]:
                g = int(self.group_of[start])
                runs.append((g, int(self.position[start]), int(self.position[start]) + i - start))
                start = i
        self.runs = tuple(runs)
        self.rests = tuple(rests)
        self.skeletons = skeletons
        first = [skeletons[int(m[0])] for m in self.members]
        self.sizes = {
            "n": tuple(s.n for s in first),
            "m": tuple(s.m for s in first),
            "k": tuple(sum(s.holonomic_mask) for s in first),
        }

    def __stored__(self):
        """What the program store's key prints for these tables (diracvi.runtime.store): the
        groups and each group's first member; the rest follows from them and from the
        skeletons, which are the packed system's ``subsystems`` and printed there (the
        tables are reachable only through that system's packing)."""
        return ("Tables", self.members, self.rests, len(self.skeletons))

    @cached_property
    def _starts(self) -> dict:
        out = {}
        for kind, sizes in self.sizes.items():
            each = np.asarray(sizes, dtype=np.int64)[self.group_of]
            out[kind] = np.concatenate([[0], np.cumsum(each)[:-1]]).astype(np.int64)
        return out

    def starts(self, kind: str) -> np.ndarray:
        """Where each subsystem's block of ``kind`` starts in the global vector."""
        return self._starts[kind]

    def table(self, kind: str, g: int) -> np.ndarray:
        """(G, size) global positions of group g's blocks of ``kind``."""
        size = self.sizes[kind][g]
        return self.starts(kind)[self.members[g]][:, None] + np.arange(size)

    @property
    def sliced(self) -> bool:
        """Whether blocks are read and written as one slice per run."""
        return len(self.runs) <= MAX_RUNS


class Packing(eqx.Module):
    """The stacked parameters of every group (``stacks[g]``: the members' array leaves
    under the first member's structure, leading axis G) and their :class:`Tables`."""

    stacks: tuple
    tables: Tables = eqx.field(static=True)

    # --------------------------------------------------------------- members
    def _restructured(self, i: int, leaves):
        """``(arrays, rest)`` of subsystem ``i`` (its own name in both) with ``leaves``
        as its arrays."""
        arrays, rest = eqx.partition(self.tables.skeletons[i], _is_placeholder)
        return jax.tree.unflatten(jax.tree.structure(arrays), leaves), rest

    def member(self, i: int):
        """Subsystem ``i`` in full (its arrays sliced out of the stacks)."""
        g, j = int(self.tables.group_of[i]), int(self.tables.position[i])
        arrays, rest = self._restructured(i, [a[j] for a in jax.tree.leaves(self.stacks[g])])
        return eqx.combine(arrays, rest)

    def group_stack(self, members: np.ndarray):
        """The stacked parameters of ``members`` (all of one group) under the structure
        of the first of them: a slice of the group's stacks when they are consecutive
        members, else a gather."""
        return self._restructured(int(members[0]), jax.tree.leaves(self._group_stack(members)))[0]

    def _group_stack(self, members: np.ndarray):
        tables = self.tables
        g = int(tables.group_of[members[0]])
        if not np.all(tables.group_of[members] == g):
            raise ValueError("group_stack: the members belong to different groups")
        pos = tables.position[members]
        if np.array_equal(pos, np.arange(pos[0], pos[0] + len(pos))):
            a, b = int(pos[0]), int(pos[0]) + len(pos)
            if (a, b) == (0, len(tables.members[g])):
                return self.stacks[g]
            return jax.tree.map(lambda x: x[a:b], self.stacks[g])
        index = jnp.asarray(pos)
        return jax.tree.map(lambda x: x[index], self.stacks[g])

    def map(self, fn, *args):
        """``[vmap over the members of g of fn(member, *args_g)]`` for every group g;
        each of ``args`` is a list with one (G, …) array per group."""
        out = []
        for g, (stack, rest) in enumerate(zip(self.stacks, self.tables.rests, strict=True)):

            def one(arrays, *a, rest=rest):
                return fn(eqx.combine(arrays, rest), *a)

            out.append(jax.vmap(one)(stack, *(a[g] for a in args)))
        return out

    # --------------------------------------------------------------- layout
    def split(self, x, kind: str):
        """Per group, the (G, size, …) blocks of ``kind`` of the global vector ``x``
        (leading axis: the blocks of every subsystem in order; trailing axes kept)."""
        tables = self.tables
        trail = x.shape[1:]
        if not tables.sliced:
            return [x[jnp.asarray(tables.table(kind, g))] for g in range(len(tables.members))]
        parts = [[] for _ in tables.members]
        starts = tables.starts(kind)
        for g, a, b in tables.runs:
            size = tables.sizes[kind][g]
            at = int(starts[tables.members[g][a]])
            parts[g].append(x[at : at + (b - a) * size].reshape(b - a, size, *trail))
        return [p[0] if len(p) == 1 else jnp.concatenate(p) for p in parts]

    def join(self, parts, kind: str):
        """The global vector of ``kind`` from per-group (G, size, …) blocks."""
        tables = self.tables
        trail = parts[0].shape[2:]
        if tables.sliced:
            pieces = [
                parts[g][a:b].reshape(-1, *trail)
                for g, a, b in tables.runs
                if tables.sizes[kind][g]
            ]
            if not pieces:
                return jnp.zeros((0, *trail), dtype=parts[0].dtype)
            return pieces[0] if len(pieces) == 1 else jnp.concatenate(pieces)
        total = sum(s * len(m) for s, m in zip(tables.sizes[kind], tables.members, strict=True))
        out = jnp.zeros((total, *trail), dtype=parts[0].dtype)
        for g, part in enumerate(parts):
            if tables.sizes[kind][g]:
                out = out.at[jnp.asarray(tables.table(kind, g))].set(part)
        return out


def pack(subsystems) -> tuple[Skeletons, Packing]:
    """Group alike ``subsystems`` and stack each group's array leaves once (host side)."""
    keyed: dict = {}
    arrays_of = []  # each subsystem's array leaves (one flattening per subsystem)
    tokens: dict = {}  # ALIKE token -> the structure key of its first subsystem
    for i, sub in enumerate(subsystems):
        alike = _dict(sub).get(ALIKE)
        key = None if alike is None else tokens.get(alike[0])
        if key is None:
            key, arrays = _keyed(sub)
            if alike is not None:
                tokens[alike[0]] = key
        else:
            arrays = [alike[1]]
        keyed.setdefault(key, []).append(i)
        arrays_of.append(arrays)
    members = [np.asarray(m, dtype=np.int64) for m in keyed.values()]
    # groups in the order of their first member: a chain's runs then follow its order
    members.sort(key=lambda m: int(m[0]))
    skeletons: list = [None] * len(subsystems)
    stacks, rests = [], []
    for mem in members:
        first = subsystems[int(mem[0])]
        arrays, rest = eqx.partition(first, eqx.is_array)
        treedef = jax.tree.structure(arrays)
        columns = zip(*(arrays_of[int(i)] for i in mem), strict=True)
        stacks.append(jax.tree.unflatten(treedef, _stack_leaves(columns)))
        rests.append(rest)
        skeleton = jax.tree.map(_placeholder, first)
        for i in mem.tolist():
            skeletons[i] = _renamed(skeleton, _name(subsystems[i], ""))
    skeletons = Skeletons(skeletons)
    skeletons.groups = (tuple(members), tuple(skeletons[int(m[0])] for m in members))
    return skeletons, Packing(tuple(stacks), Tables(members, rests, skeletons))
