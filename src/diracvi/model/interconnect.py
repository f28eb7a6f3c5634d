r"""Interconnection of Lagrange–Dirac subsystems (paper §4.1; Jacobs & Yoshimura 2014).

Subsystems ``(L^i, Δ_i, F_i)`` on ``Q_i`` are joined on ``Q = Q_1 × … × Q_N`` through an
interaction distribution ``Σ`` whose annihilator is spanned by one-forms ``α^b(q)`` (the
rows of ``B(q)``, l × dim Q). The discrete interconnected (+) equations are assembled per
subsystem, exactly as the paper's (int_eqns) and (forced_int_eqns)::

    p_k^i     = −D₁L_d^i − f_d^{i,−} + A_i(q_k^i)ᵀ μ_i + B_i(q_k)ᵀ λ
    0         =  ω^i_{d+}(q_k^i, q_{k+1}^i)             for each i
    0         =  α_{d+}(q_k, q_{k+1}) = B(node) v_k      (l equations)
    p_{k+1}^i =  D₂L_d^i + f_d^{i,+}

and the paper's theorem says these *are* the (+) equations of the monolithic system
``(Σ L^i, (⊕Δ_i) ∩ Σ)`` — :meth:`InterconnectedSystem.monolithic` builds it, so the claim
can be checked to round-off.
"""

from __future__ import annotations

import dataclasses
import itertools
import weakref
from collections import Counter
from collections.abc import Sequence

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..runtime.config import ensure_float64
from .interaction import Connection, Interaction
from .monolithic import monolithic
from .sparse_rows import SparseRows
from .stacked import Packing, pack
from .system import DiracSystem, LagrangeDiracSystem, StaticTuple
from .validate import check_name, eval_shape

#: packed copies by the id of their system (see InterconnectedSystem._packed)
_PACKED: dict = {}


def _prefixed(name: str, names: Sequence[str]) -> tuple[str, ...]:
    prefix = name + "."
    return tuple(prefix + n for n in names)


def _described(sub) -> tuple[str, tuple[str, ...], tuple[str, ...]]:
    """``(name, coords, constraint_names)`` of a subsystem: for diracvi's two classes
    (and subclasses that keep their properties) read from the fields as stored, past
    equinox's ``__getattribute__`` — a Python hook of about a microsecond per read, and
    a property reads twice (an interconnection of 10⁵ parts read 10⁶ attributes here)."""
    where = _FIELDS.get(type(sub))
    if where is None:
        where = _FIELDS.setdefault(type(sub), _fields_of(type(sub)))
    if not where:
        return sub.name, sub.coords, sub.constraint_names
    f = object.__getattribute__(sub, "__dict__")
    return f["name"], f[where[0]], f[where[1]]


#: class -> the fields its ``coords`` and ``constraint_names`` properties return
_FIELDS: dict = {}


def _fields_of(kind: type) -> tuple[str, ...]:
    for base, names in (
        (LagrangeDiracSystem, ("_coords", "_constraint_names")),
        (InterconnectedSystem, ("_coords", "_all_constraint_names")),
    ):
        if (
            issubclass(kind, base)
            and kind.coords is base.coords
            and kind.constraint_names is base.constraint_names
        ):
            return names
    return ()


def _index_of(subsystems, full: str, where: str, index: dict[str, int]) -> int:
    """The position of coordinate ``full`` in Q, or a ModelError naming what is wrong."""
    if full in index:
        return index[full]
    sub_name, _, coord = full.partition(".")
    subs = {s.name: s for s in subsystems}
    if sub_name not in subs:
        raise ModelError(
            f"{where}: {full!r} names subsystem {sub_name!r}, which is not part of "
            f"this interconnection; subsystems are {sorted(subs)}."
        )
    raise ModelError(
        f"{where}: subsystem {sub_name!r} has no coordinate {coord!r}; its "
        f"coordinates are {subs[sub_name].coords}."
    )


def _involved_subsystems(inter: Interaction, rows: int, owner, everyone):
    """Per row of a general interaction: the subsystems whose columns are nonzero.

    Only a constant matrix can be read here; a callable ``B(q)`` may involve any column,
    so its rows involve every subsystem (as does an all-zero row, which constrains
    nothing and leaves its λ undetermined, so it must not look decoupled).
    """
    if inter._fn is not None:
        return [everyone] * rows
    if inter._sparse is not None:  # O(non-zeros): the owners of each row's columns
        sparse = inter._sparse
        pairs = np.unique(np.stack([sparse.rows, owner[sparse.cols]], axis=1), axis=0)
        starts = np.searchsorted(pairs[:, 0], np.arange(rows + 1))
        subs = pairs[:, 1].tolist()
        return [tuple(subs[a:b]) or everyone for a, b in itertools.pairwise(starts.tolist())]
    forms = np.asarray(inter._const)
    out = []
    for row in forms:
        subs = tuple(sorted({int(k) for k in owner[np.nonzero(row)[0]]}))
        out.append(subs or everyone)
    return out


class InterconnectedSystem(DiracSystem):
    """Subsystems joined by interaction one-forms; itself a :class:`DiracSystem`, so it
    can be simulated, inspected, and interconnected again (hierarchical models).

    A :func:`connect` row ``dx − dy`` is kept as its two coordinate indices, not as a
    dense row over Q: its constraint and constraint force cost O(1) however large Q is.
    An :class:`Interaction` of a sparse matrix is kept as its triples
    (:meth:`incidence`): O(non-zeros). ``interactions`` holds the other (general)
    :class:`Interaction` objects.
    """

    subsystems: tuple[DiracSystem, ...]
    interactions: tuple[Interaction, ...]
    name: str = eqx.field(static=True)
    _offsets: tuple[int, ...] = eqx.field(static=True)
    _coords: tuple[str, ...] = eqx.field(static=True)
    _interaction_names: tuple[str, ...] = eqx.field(static=True)
    # connections: coordinate pair (x, y) of ``dx − dy`` and the interaction row it fills
    _port_index: tuple[tuple[int, int], ...] = eqx.field(static=True)
    _port_rows: tuple[int, ...] = eqx.field(static=True)
    # general interactions: the rows each one fills (first row, count)
    _form_rows: tuple[tuple[int, int], ...] = eqx.field(static=True)
    # the subsystems each interaction row involves (every one, for a callable B(q))
    _row_subsystems: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    # the rows of constant sparse interactions, placed in B (l × N), or None
    _incidence: SparseRows | None = eqx.field(static=True)
    # every row name (subsystems' own, prefixed, then the interaction rows): read per
    # trace many times over (``system.m``), so formed once
    _all_constraint_names: tuple[str, ...] = eqx.field(static=True)
    # set only on the copy :meth:`_packed` makes: alike subsystems' parameters stacked
    _packing: Packing | None

    def __init__(self, subsystems, interactions, name=None):
        ensure_float64()
        self.name = "interconnected" if name is None else check_name("name", name)
        if isinstance(subsystems, DiracSystem) or not isinstance(subsystems, Sequence):
            raise ModelError(f"systems={subsystems!r} must be a list of at least two subsystems.")
        subsystems = tuple(subsystems)
        if len(subsystems) < 2:
            raise ModelError(
                f"systems has {len(subsystems)} subsystem(s): an interconnection needs at "
                "least two (simulate a single system directly)."
            )
        for i, sub in enumerate(subsystems):
            if not isinstance(sub, DiracSystem):
                raise ModelError(
                    f"systems[{i}]={sub!r} is not a diracvi system: build it with "
                    "dv.LagrangeDiracSystem(...) or dv.interconnect(...)."
                )
        described = [_described(sub) for sub in subsystems]
        counts = Counter(name for name, _, _ in described)
        dupes = sorted(n for n, c in counts.items() if c > 1)
        if dupes:
            raise ModelError(
                f"subsystem names {dupes} are used more than once: give every subsystem "
                "a distinct name=... (coordinates are addressed as 'name.coordinate')."
            )
        self.subsystems = subsystems
        self._packing = None
        offsets = [0]
        for _, coords, _ in described:
            offsets.append(offsets[-1] + len(coords))
        self._offsets = StaticTuple(offsets)
        self._coords = StaticTuple(c for name, cs, _ in described for c in _prefixed(name, cs))
        if isinstance(interactions, Interaction | Connection) or not isinstance(
            interactions, Sequence
        ):
            raise ModelError(
                f"interactions={interactions!r} must be a list of dv.connect(...) or "
                "dv.Interaction(...) objects."
            )
        # coordinate -> position, for the ports (only they name coordinates)
        joined = any(isinstance(inter, Connection) for inter in interactions)
        index = {c: i for i, c in enumerate(self._coords)} if joined else {}
        owner = np.repeat(np.arange(len(subsystems)), np.diff(offsets))
        everyone = tuple(range(len(subsystems)))
        general, inames, ports, port_rows, form_rows, involved = [], [], [], [], [], []
        sparse = []  # (first row, SparseRows) of the constant sparse interactions
        for j, inter in enumerate(interactions):
            if isinstance(inter, Connection):
                # a module-level function: a method call on a half-built Module flattens
                # every subsystem (equinox binds methods as PyTrees), O(M²) for M pieces
                ia = _index_of(subsystems, inter.a, f"interactions[{j}]", index)
                ib = _index_of(subsystems, inter.b, f"interactions[{j}]", index)
                ports.append((ia, ib))
                port_rows.append(len(inames))
                involved.append(tuple(sorted({int(owner[ia]), int(owner[ib])})))
                inames.append(inter.name)
                continue
            if not isinstance(inter, Interaction):
                raise ModelError(
                    f"interactions[{j}]={inter!r} is not an interaction: use "
                    "dv.connect('a.x', 'b.y') or dv.Interaction(B)."
                )
            # (read from the class: a method read from a half-built Module is bound as a
            # PyTree and equinox checks its leaves, every subsystem's, at every call)
            rows = type(self)._rows(self, inter, j)
            inter = inter.lifted(len(self._coords))  # once its shape is known to be right
            given = inter.names or [f"λ{len(inames) + b}" for b in range(rows)]
            if len(given) != rows:
                raise ModelError(
                    f"interactions[{j}] has {rows} one-form rows but {len(given)} names: "
                    "give one name per row."
                )
            involved.extend(_involved_subsystems(inter, rows, owner, everyone))
            if inter._sparse is not None:  # kept as triples, not as a general interaction
                sparse.append((len(inames), inter._sparse))
            else:
                form_rows.append((len(inames), rows))
                general.append(inter)
            inames.extend(given)
        self.interactions = tuple(general)
        self._incidence = SparseRows.stack(sparse, len(inames), len(self._coords))
        self._interaction_names = StaticTuple(inames)
        self._port_index = StaticTuple(ports)
        self._port_rows = StaticTuple(port_rows)
        self._form_rows = StaticTuple(form_rows)
        self._row_subsystems = StaticTuple(involved)
        own = (c for name, _, rows in described if rows for c in _prefixed(name, rows))
        self._all_constraint_names = StaticTuple((*own, *inames))

    # ----------------------------------------------------------- construction
    def _rows(self, inter: Interaction, j: int) -> int:
        n = len(self._coords)
        if inter._sparse is not None:
            shape = inter._sparse.shape
        elif inter._const is not None:
            shape = tuple(inter._const.shape)
        else:
            shape = eval_shape(f"interactions[{j}]", inter._fn, (n,), signature="B(q)").shape
        if len(shape) != 2 or shape[1] != n:
            raise ModelError(
                f"interactions[{j}] gives one-forms of shape {shape}, but the "
                f"interconnected system has {n} coordinates {self._coords}: each row must "
                f"have {n} entries, in that order."
            )
        return shape[0]

    # -------------------------------------------------------------- packing
    def _packed(self) -> InterconnectedSystem:
        """The same interconnection with alike subsystems' parameters stacked once per
        group (:mod:`diracvi.model.stacked`): every per-subsystem term is then one ``jax.vmap``
        per group, so a compiled step takes a few arrays per kind of subsystem and its
        size does not grow with their number. Its ``subsystems`` are placeholders
        (names, sizes and flags only); :meth:`_member` gives one in full."""
        if self._packing is not None:
            return self
        hit = _PACKED.get(id(self))  # packed once per system (the netlist reader's
        if hit is not None and hit[0]() is self:  # momenta and the plan both ask)
            return hit[1]
        skeletons, packing = pack(self.subsystems)
        out = object.__new__(type(self))
        for f in dataclasses.fields(self):
            object.__setattr__(out, f.name, getattr(self, f.name))
        object.__setattr__(out, "subsystems", skeletons)
        object.__setattr__(out, "_packing", packing)
        key = id(self)
        _PACKED[key] = (weakref.ref(self, lambda _, c=_PACKED, key=key: c.pop(key, None)), out)
        return out

    def _member(self, i: int) -> DiracSystem:
        """Subsystem ``i`` with its parameters (also of a :meth:`_packed` system)."""
        if self._packing is None:
            return self.subsystems[i]
        return self._packing.member(i)

    def _members(self) -> tuple[DiracSystem, ...]:
        """Every subsystem in full (a packed system slices each out of its stacks: used
        only by the dense, O(n²) forms, never inside the time loop)."""
        if self._packing is None:
            return self.subsystems
        return tuple(self._packing.member(i) for i in range(len(self.subsystems)))

    def _kinds(self) -> tuple[DiracSystem, ...]:
        """One subsystem per group of a packed system (alike members share every flag),
        every subsystem otherwise."""
        if self._packing is None:
            return self.subsystems
        return tuple(self.subsystems[int(m[0])] for m in self._packing.tables.members)

    def _per_group(self, fn, *vectors):
        """``fn(subsystem, *blocks)`` for every subsystem, vmapped group by group;
        ``vectors`` are ``(x, kind)`` pairs of global vectors and their block kind."""
        pk = self._packing
        return pk.map(fn, *(pk.split(x, kind) for x, kind in vectors))

    # ------------------------------------------------------------- protocol
    @property
    def coords(self) -> tuple[str, ...]:
        return self._coords

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return self._all_constraint_names

    @property
    def interaction_names(self) -> tuple[str, ...]:
        """Names of the interaction rows (the last ``l`` multipliers, the λ's)."""
        return self._interaction_names

    @property
    def ports(self) -> tuple[tuple[str, str], ...]:
        """Coordinate pairs joined by :func:`connect`."""
        return tuple((self._coords[a], self._coords[b]) for a, b in self._port_index)

    @property
    def row_subsystems(self) -> tuple[tuple[int, ...], ...]:
        """For each interaction row, the indices of the subsystems it involves (its
        nonzero columns; every subsystem for a configuration-dependent ``Interaction``)."""
        return self._row_subsystems

    def _split(self, x):
        return [x[a:b] for a, b in zip(self._offsets[:-1], self._offsets[1:], strict=True)]

    @property
    def time_dependent(self) -> bool:
        return any(s.time_dependent for s in self._kinds())

    @property
    def affine_constraints(self) -> bool:
        return any(s.affine_constraints for s in self._kinds())

    @property
    def constraints_time_dependent(self) -> bool:
        return any(s.constraints_time_dependent for s in self._kinds())

    def lagrangian(self, q, v, t=0.0):
        r"""``L = Σ_i L^i(q_i, v_i, t)``."""
        if self._packing is not None:
            parts = self._per_group(lambda s, a, b: s.lagrangian(a, b, t), (q, "n"), (v, "n"))
            return sum(jnp.sum(e) for e in parts)
        return sum(
            sub.lagrangian(qi, vi, t)
            for sub, qi, vi in zip(self.subsystems, self._split(q), self._split(v), strict=True)
        )

    def force(self, q, v, t=0.0):
        r"""``F = Σ_i π_{Q_i}^* F_i``: each subsystem's force, pulled back to Q."""
        if self._packing is not None:
            parts = self._per_group(lambda s, a, b: s.force(a, b, t), (q, "n"), (v, "n"))
            return self._packing.join(parts, "n")
        return jnp.concatenate(
            [
                sub.force(qi, vi, t)
                for sub, qi, vi in zip(self.subsystems, self._split(q), self._split(v), strict=True)
            ]
        )

    def energy(self, q, v, t=0.0):
        if self._packing is not None:
            parts = self._per_group(lambda s, a, b: s.energy(a, b, t), (q, "n"), (v, "n"))
            return sum(jnp.sum(e) for e in parts)
        return sum(
            sub.energy(qi, vi, t)
            for sub, qi, vi in zip(self.subsystems, self._split(q), self._split(v), strict=True)
        )

    def momentum(self, q, v, t=0.0):
        r"""``p = (p^1, …, p^N)``: each subsystem's own momentum, side by side — ``∂L/∂v``
        of ``L = Σ L^i``, plus the charge of a part with a charge port
        (:class:`~diracvi.components.ChargePortPart`)."""
        if self._packing is not None:
            parts = self._per_group(lambda s, a, b: s.momentum(a, b, t), (q, "n"), (v, "n"))
            return self._packing.join(parts, "n")
        return jnp.concatenate(
            [
                jnp.atleast_1d(sub.momentum(qi, vi, t))
                for sub, qi, vi in zip(self.subsystems, self._split(q), self._split(v), strict=True)
            ]
        )

    def position_constraints(self, q, t=0.0):
        """Every subsystem's holonomic constraints ``g^i(q_i, t)``, stacked."""
        if self._packing is not None:
            parts = self._per_group(lambda s, a: s.position_constraints(a, t), (q, "n"))
            return self._packing.join(parts, "k")
        return jnp.concatenate(
            [
                sub.position_constraints(qi, t)
                for sub, qi in zip(self.subsystems, self._split(q), strict=True)
            ]
        )

    def _port_arrays(self):
        pairs = np.asarray(self._port_index, dtype=np.int64).reshape(-1, 2)
        return pairs[:, 0], pairs[:, 1], np.asarray(self._port_rows, dtype=np.int64)

    def _form_row_index(self) -> np.ndarray:
        return np.concatenate(
            [np.arange(a, a + c) for a, c in self._form_rows] or [np.zeros(0, np.int64)]
        )

    def general_forms(self, q):
        """The rows of the general :class:`Interaction` objects at ``q``, stacked
        (rows :meth:`_form_row_index` of ``B``); ``None`` if every row is a connection
        or a constant sparse row (:meth:`incidence`)."""
        if not self.interactions:
            return None
        return jnp.concatenate([i.forms(q) for i in self.interactions], axis=0)

    def interaction_forms(self, q):
        """``B(q)``, shape (l, N), dense."""
        forms = jnp.zeros((len(self._interaction_names), self.n), dtype=q.dtype)
        if self._port_index:
            a, b, rows = self._port_arrays()
            forms = forms.at[rows, a].set(1.0).at[rows, b].set(-1.0)
        if self._incidence is not None:
            inc = self._incidence
            forms = forms.at[inc.rows, inc.cols].add(inc.values)
        general = self.general_forms(q)
        if general is not None:
            forms = forms.at[self._form_row_index()].set(general)
        return forms

    def interaction_force(self, q, lam):
        r"""``B(q)ᵀ λ``; a connection row adds ``±λ`` at its two coordinates only."""
        force = jnp.zeros(self.n, dtype=lam.dtype)
        if self._port_index:
            a, b, rows = self._port_arrays()
            force = force.at[a].add(lam[rows]).at[b].add(-lam[rows])
        if self._incidence is not None:
            force = force + self._incidence.transpose_apply(lam)
        general = self.general_forms(q)
        if general is not None:
            force = force + general.T @ lam[self._form_row_index()]
        return force

    # ------------------------------------------ what the discrete maps read
    def port_arrays(self):
        """The connections as index arrays ``(x, y, row)`` (row ``row`` of ``B`` is
        ``dx − dy``), or ``None`` if there are none."""
        return self._port_arrays() if self._port_index else None

    def general_rows(self):
        """The rows of ``B`` that :meth:`general_forms` fills, or ``None`` if there are
        no general interactions."""
        return self._form_row_index() if self.interactions else None

    def incidence(self) -> SparseRows | None:
        """The constant sparse rows of ``B`` (interactions given as sparse matrices),
        placed in its ``(l, N)`` shape: ``incidence() @ v`` is ``B v`` on those rows and
        zero on the others; ``None`` if there are none."""
        return self._incidence

    def map_subsystems(self, fn, *vectors):
        """``fn(subsystem, *blocks)`` for every subsystem, on its blocks of the global
        coordinate-sized ``vectors`` (leading axis of length n); group by group under
        ``jax.vmap`` when alike subsystems are packed. The parts are read back with
        :meth:`join_subsystems`."""
        if self._packing is not None:
            return self._per_group(fn, *((x, "n") for x in vectors))
        return [
            fn(sub, *blocks)
            for sub, *blocks in zip(
                self.subsystems, *(self._split(x) for x in vectors), strict=True
            )
        ]

    def join_subsystems(self, parts, kind: str = "n"):
        """The per-subsystem ``parts`` of :meth:`map_subsystems` (each of size ``n_i`` for
        ``kind="n"``, ``m_i`` for ``"m"``) stacked in subsystem order."""
        if self._packing is not None:
            return self._packing.join(parts, kind)
        return jnp.concatenate(parts)

    @property
    def packed(self) -> bool:
        """Whether alike subsystems' parameters are stacked (see :meth:`_packed`)."""
        return self._packing is not None

    @property
    def has_offset(self) -> bool:
        return any(s.has_offset for s in self._kinds())

    @property
    def has_holonomic(self) -> bool:
        return any(self.holonomic_mask)

    def constraint_forms(self, q, t=0.0):
        r"""``[⊕ A_i(q_i, t); B(q)]``: a basis of ``((⊕Δ_i) ∩ Σ)°`` (the paper's choice)."""
        return self._block_diagonal_rows(q, t, "constraint_forms")

    def _block_diagonal_rows(self, q, t, rows: str):
        """``[⊕ R_i(q_i, t); B(q)]`` for the subsystems' ``rows`` method (each block padded
        with zeros to the columns of its subsystem), then the interaction rows."""
        if self._packing is not None and not self._any_holonomic():
            own = self._packed_blocks(q, t, rows)
            return jnp.concatenate([own, self.interaction_forms(q)], axis=0)
        blocks = []
        for k, skeleton in enumerate(self.subsystems):
            if skeleton.m == 0:  # no rows (most parts of a circuit): nothing to place
                continue
            sub, qi = self._member(k), q[self._offsets[k] : self._offsets[k + 1]]
            a = getattr(sub, rows)(qi, t)
            left = jnp.zeros((a.shape[0], self._offsets[k]))
            right = jnp.zeros((a.shape[0], self.n - self._offsets[k + 1]))
            blocks.append(jnp.concatenate([left, a, right], axis=1))
        blocks.append(self.interaction_forms(q))
        return jnp.concatenate(blocks, axis=0)

    def _any_holonomic(self) -> bool:
        """Whether any kind of subsystem has holonomic rows (then its ``one_forms`` rows
        are fewer than its ``m``: the packed row layout, by ``m``, does not apply)."""
        return any(any(s.holonomic_mask) for s in self._kinds())

    def _packed_blocks(self, q, t, rows: str):
        """``⊕ R_i(q_i, t)`` of a packed system without holonomic rows: each group's
        (G, m_g, n_g) blocks, vmapped, scattered once into the (m_own, n) matrix at
        the members' row and column blocks. Slicing each member out of the stacks
        instead put all of its parameters into the program, once per member."""
        pk, tables = self._packing, self._packing.tables
        total = sum(s * len(m) for s, m in zip(tables.sizes["m"], tables.members, strict=True))
        out = jnp.zeros((total, self.n), dtype=q.dtype)
        groups = [g for g, size in enumerate(tables.sizes["m"]) if size]
        if not groups:
            return out
        blocks = pk.map(lambda s, a: getattr(s, rows)(a, t), pk.split(q, "n"))
        for g in groups:
            r, c = tables.table("m", g), tables.table("n", g)
            out = out.at[r[:, :, None], c[:, None, :]].set(blocks[g])
        return out

    def _split_multipliers(self, mu):
        out, start = [], 0
        for sub in self.subsystems:
            out.append(mu[start : start + sub.m])
            start += sub.m
        return out, mu[start:]

    def multiplier_force(self, q, mu, t=0.0):
        r"""``A_i(q_i, t)ᵀ μ_i`` per subsystem, plus ``B(q)ᵀ λ`` over the whole of Q."""
        if self._packing is not None:
            own_rows = mu.shape[0] - len(self._interaction_names)
            parts = self._per_group(
                lambda s, a, b: s.multiplier_force(a, b, t), (q, "n"), (mu[:own_rows], "m")
            )
            return self._packing.join(parts, "n") + self.interaction_force(q, mu[own_rows:])
        mus, lam = self._split_multipliers(mu)
        own = jnp.concatenate(
            [
                sub.multiplier_force(qi, mi, t)
                for sub, qi, mi in zip(self.subsystems, self._split(q), mus, strict=True)
            ]
        )
        return own + self.interaction_force(q, lam)

    # ------------------------------------------------------------ monolithic
    @property
    def holonomic_mask(self) -> tuple[bool, ...]:
        """For each constraint row: is it a holonomic row of a subsystem?"""
        own = tuple(flag for sub in self.subsystems for flag in sub.holonomic_mask)
        return own + (False,) * len(self._interaction_names)

    def one_forms(self, q, t=0.0):
        r"""The one-form rows only: ``[⊕ A_i(q_i, t); B(q)]`` (holonomic rows left out)."""
        return self._block_diagonal_rows(q, t, "one_forms")

    def constraint_offset(self, q, t=0.0):
        """The affine terms of the one-form rows (zero for linear rows), or ``None``."""
        if self._packing is not None:
            if not self.has_offset:  # (the kinds' flags: no member sliced out)
                return None
            if not self._any_holonomic():
                parts = self._per_group(lambda s, a: _offset_or_zero(s, a, t), (q, "n"))
                inter = jnp.zeros(len(self._interaction_names), dtype=q.dtype)
                return jnp.concatenate([self._packing.join(parts, "m"), inter])
        if not any(s.constraint_offset(qi, t) is not None for s, qi in self._pairs(q)):
            return None
        parts = []
        for sub, qi in self._pairs(q):
            b = sub.constraint_offset(qi, t)
            rows = sum(not flag for flag in sub.holonomic_mask)
            parts.append(jnp.zeros(rows, dtype=qi.dtype) if b is None else b)
        parts.append(jnp.zeros(len(self._interaction_names), dtype=q.dtype))
        return jnp.concatenate(parts)

    def _pairs(self, q):
        return zip(self._members(), self._split(q), strict=True)

    def monolithic(self) -> LagrangeDiracSystem:
        r"""The single system ``(Σ L^i, (⊕Δ_i) ∩ Σ, Σ π_i^* F_i)`` on the same coordinates.

        Its one-forms are the stacked ``[⊕A_i; B]`` (with the subsystems' affine terms),
        its holonomic constraints the stacked ``g_i``, its rows in the interconnection's
        order, and its step equations are formed by differentiating the summed discrete
        Lagrangian in one piece — a different computation from the per-subsystem
        assembly, which is what makes the comparison a check of the paper's theorem.
        """
        return monolithic(self)

    @property
    def has_force(self) -> bool:
        return any(s.has_force for s in self._kinds())

    def __repr__(self) -> str:
        subs = ", ".join(f"{s.name}({s.n})" for s in self.subsystems)
        return (
            f"InterconnectedSystem(name={self.name!r}, subsystems=[{subs}], "
            f"interactions={len(self._interaction_names)})"
        )


def _offset_or_zero(sub, q, t):
    """``sub``'s one-form offset ``b(q, t)``, zeros where it has none."""
    b = sub.constraint_offset(q, t)
    return jnp.zeros(sub.m, dtype=q.dtype) if b is None else b


def interconnect(systems, interactions, name: str | None = None) -> InterconnectedSystem:
    r"""Join subsystems through interaction one-forms into one :class:`InterconnectedSystem`.

    Coordinates are named ``"subsystem.coordinate"`` in the order of ``systems``;
    multipliers are each subsystem's μ's (prefixed), then the interactions' λ's.
    """
    return InterconnectedSystem(systems, interactions, name=name)
