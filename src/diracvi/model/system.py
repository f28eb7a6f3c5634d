r"""Lagrange–Dirac systems ``(L, Δ, F)`` on ``Q = R^n``.

Continuous equations (DESIGN.md §1), with time-dependent inputs allowed::

    q̇ = v,   A(q, t) v + b(q, t) = 0,   g(q, t) = 0,
    ṗ = ∂L/∂q + F(q, v, t) + A(q, t)ᵀ μ + ∇g(q, t)ᵀ ν,   p = ∂L/∂v,

with energy ``E(q, v, t) = ⟨∂L/∂v, v⟩ − L`` and power balance
``dE/dt = ⟨F, v⟩ − ∂L/∂t − ⟨Aᵀμ + ∇gᵀν, v⟩`` (the last term vanishes for linear,
autonomous constraints: ideal constraints do no work unless they are driven).

:class:`DiracSystem` is the small protocol the step equations use; a single
:class:`LagrangeDiracSystem` and an interconnection of several both implement it, so the
same residual code serves both (and the interconnected one assembles its pieces per
subsystem, as in the paper).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..runtime.config import ensure_float64
from ..runtime.program import Program, lift
from .signature import takes_time
from .validate import (
    check_callable,
    check_forms_array,
    check_name,
    check_names,
    eval_shape,
)


class StaticTuple(tuple):
    """A tuple kept in a static field of a system (coordinate and row names, index
    tables): one PyTree leaf to JAX, so equinox's checks of every static field at
    construction do not walk its entries (10⁶ names of a large interconnection, 10⁴
    systems of 100 names each); it compares and hashes as the tuple it is."""

    __slots__ = ()


class DiracSystem(eqx.Module):
    """What the discrete (±) equations need from a system on ``R^n``.

    ``coords`` names the n coordinates; ``constraint_names`` the rows of the constraints
    (one-forms first, then holonomic rows, per subsystem; their multipliers and residuals
    are reported under these names). Every method takes the time ``t`` last; autonomous
    systems ignore it.
    """

    @property
    def coords(self) -> tuple[str, ...]:
        raise NotImplementedError

    @property
    def constraint_names(self) -> tuple[str, ...]:
        raise NotImplementedError

    @property
    def n(self) -> int:
        return len(self.coords)

    @property
    def m(self) -> int:
        return len(self.constraint_names)

    @property
    def time_dependent(self) -> bool:
        """Whether any of L, F, A, b or g depends on time."""
        return False

    @property
    def constraints_time_dependent(self) -> bool:
        """Whether the constraint one-forms (or holonomic constraints) depend on time."""
        return False

    @property
    def affine_constraints(self) -> bool:
        """Whether any constraint is affine (``b ≠ 0``) or holonomic: not a linear
        distribution ``Δ``, so :math:`D_Δ` is not defined for it."""
        return False

    def lagrangian(self, q, v, t=0.0):
        raise NotImplementedError

    def force(self, q, v, t=0.0):
        raise NotImplementedError

    def constraint_forms(self, q, t=0.0):
        """``A(q, t)``, shape (m, n): row a is the one-form ω^a(q) (``dg`` for a
        holonomic row ``g``)."""
        raise NotImplementedError

    def position_constraints(self, q, t=0.0):
        """The holonomic constraints ``g(q, t)`` stacked, shape (k,) (empty if none)."""
        return jnp.zeros((0,), dtype=jnp.result_type(q))

    @property
    def holonomic_mask(self) -> tuple[bool, ...]:
        """For each constraint row: is it a holonomic row (``g = 0``, not a one-form)?"""
        return (False,) * self.m

    def one_forms(self, q, t=0.0):
        """The one-form rows of :meth:`constraint_forms` (holonomic rows left out)."""
        return self.constraint_forms(q, t)

    def constraint_offset(self, q, t=0.0):
        """The affine terms ``b(q, t)`` of the one-form rows, or ``None`` (linear)."""
        return None

    def energy(self, q, v, t=0.0):
        r"""``E(q, v, t) = ⟨∂L/∂v, v⟩ − L(q, v, t)``."""
        p = jax.grad(self.lagrangian, argnums=1)(q, v, t)
        return p @ v - self.lagrangian(q, v, t)

    def momentum(self, q, v, t=0.0):
        r"""The Legendre transform ``p = ∂L/∂v(q, v, t)``."""
        return jax.grad(self.lagrangian, argnums=1)(q, v, t)

    def multiplier_force(self, q, mu, t=0.0):
        """``A(q, t)ᵀ μ``: the constraint force the multipliers exert."""
        return self.constraint_forms(q, t).T @ mu

    @property
    def has_force(self) -> bool:
        """Whether ``force`` can be nonzero (systems without one skip its quadrature)."""
        return True

    @property
    def has_offset(self) -> bool:
        """Whether :meth:`constraint_offset` can be nonzero (affine one-form rows)."""
        return False

    @property
    def has_holonomic(self) -> bool:
        """Whether there are holonomic rows ``g(q, t) = 0``."""
        return False

    def order_rows(self, rows):
        """The one-form rows then the holonomic rows, put in the system's row order."""
        return rows


def _zero_force(q, v):
    return jnp.zeros_like(v)


class _Opaque:
    """A plain user function seen by JAX/equinox as one hashable constant.

    Equality is the identity of the wrapped function, so two systems built from the same
    function have equal static structure (and batch together in the partitioned solver),
    and nothing is ever hashed by value.
    """

    __slots__ = ("fn",)

    def __init__(self, fn: Callable):
        self.fn = fn

    def __call__(self, *args):
        return self.fn(*args)

    def __eq__(self, other) -> bool:
        return isinstance(other, _Opaque) and other.fn is self.fn

    def __hash__(self) -> int:
        return id(self.fn)

    def __repr__(self) -> str:
        return f"<{getattr(self.fn, '__name__', 'user function')}>"


class _UserFunction(eqx.Module):
    """A user callable (L, F, A, b or g) stored so that its parameters are PyTree leaves.

    An ``equinox.Module`` callable is split by :func:`equinox.partition`: its arrays are
    a dynamic field (traced, so subsystems that differ only in parameter values share one
    compiled program and can be stacked for ``jax.vmap``); the rest of it is static. A
    plain function (a closure, a lambda) is traced once to a :class:`~._program.Program`
    with its captured arrays and float constants lifted out as the dynamic field, so
    closures built in a loop are alike exactly when they compute the same thing. What
    cannot be traced that way is kept whole as a static constant (its captured arrays
    become compile-time constants). ``driven`` records whether it takes the time as its
    last argument.
    """

    arrays: Any
    rest: Callable = eqx.field(static=True)
    driven: bool = eqx.field(static=True, default=False)

    def __call__(self, *args, t):
        args = (*args, t) if self.driven else args
        if isinstance(self.rest, Program):
            return self.rest(self.arrays, *args)
        fn = self.rest if self.arrays is None else eqx.combine(self.arrays, self.rest)
        return fn(*args)


def _wrap(fn: Callable, driven: bool = False) -> _UserFunction:
    if isinstance(fn, eqx.Module):
        arrays, rest = eqx.partition(fn, eqx.is_array)
        try:
            hash(rest)
        except TypeError:  # e.g. a list field: cannot be static, so keep the old way
            return _UserFunction(None, _Opaque(fn), driven)
        return _UserFunction(arrays, rest, driven)
    return _UserFunction(None, _Opaque(fn), driven)


#: ``(timed, output shape)`` of ``equinox.Module`` callables by what decides both: the
#: class (its ``__call__`` signature), the static part and the shapes of the arrays
_MODULE_FORMS: dict = {}
_MODULE_FORMS_LIMIT = 256


def _module_key(fn, shapes, autonomous: str):
    """The cache key of a Module callable, its ``(arrays, rest)`` split, or ``None``."""
    arrays, rest = eqx.partition(fn, eqx.is_array)
    leaves, treedef = jax.tree.flatten(arrays)
    key = (type(fn), rest, treedef, tuple((tuple(a.shape), str(a.dtype)) for a in leaves))
    key += (tuple(tuple(s) for s in shapes), autonomous)
    try:
        hash(key)
    except TypeError:  # e.g. a list field: cannot be static (see _wrap)
        return None, None
    return key, (arrays, rest)


def _user_function(arg: str, fn, shapes, autonomous: str, driven: str):
    """Wrap user callable ``fn`` after deciding its form once; return it and the shape
    and dtype it returns (traced abstractly on float64 arrays of ``shapes``).

    A Module's form and output shape depend only on its class, its static part and the
    shapes of its arrays: a model of 10⁴ alike pieces reads the signature and traces
    once, not 10⁴ times (each costs ~0.3 ms), and every check below still applies."""
    check_callable(arg, fn)
    if isinstance(fn, eqx.Module) and not isinstance(getattr(fn, "__self__", None), DiracSystem):
        key, split = _module_key(fn, shapes, autonomous)
        hit = _MODULE_FORMS.get(key) if key is not None else None
        if hit is not None:
            return _UserFunction(split[0], split[1], hit[0]), hit[1]
        wrapped, out = _user_function_uncached(arg, fn, shapes, autonomous, driven)
        if key is not None and isinstance(wrapped.rest, type(split[1])):
            if len(_MODULE_FORMS) >= _MODULE_FORMS_LIMIT:
                _MODULE_FORMS.clear()
            _MODULE_FORMS[key] = (wrapped.driven, out)
        return wrapped, out
    return _user_function_uncached(arg, fn, shapes, autonomous, driven)


def _user_function_uncached(arg: str, fn, shapes, autonomous: str, driven: str):
    if isinstance(getattr(fn, "__self__", None), DiracSystem):
        # a system's own method (L, F, A of another system) takes t as documented
        timed = True
    else:
        timed = takes_time(arg, fn, autonomous, driven)
    if timed is None:  # signature unreadable: the autonomous form if it traces
        try:
            out = eval_shape(arg, fn, *shapes, signature=autonomous)
            return _wrap(fn, False), out
        except ModelError:
            timed = True
    shapes = [*shapes, *([()] if timed else [])]
    if not isinstance(fn, eqx.Module):
        # one trace gives both the program and the output shape; a function that fails
        # to trace is traced again below for the error message
        lifted = lift(fn, shapes)
        if lifted is not None:
            program, consts, out = lifted
            return _UserFunction(consts, program, bool(timed)), out
    out = eval_shape(arg, fn, *shapes, signature=driven if timed else autonomous)
    return _wrap(fn, bool(timed)), out


#: coordinate tuples already checked (pieces of a torn model share their local names)
_COORDS: dict = {}
_COORDS_LIMIT = 256


def _checked_coords(coords) -> StaticTuple:
    """``check_names("coords", coords)``, remembered for a tuple of strings that passed."""
    try:
        key = tuple(coords) if isinstance(coords, tuple | list) else None
        hit = _COORDS.get(key) if key is not None else None
    except TypeError:  # an unhashable entry: the check below names it
        key = hit = None
    if hit is not None and all(type(c) is str for c in key):
        return hit
    names = StaticTuple(check_names("coords", coords))
    if key is not None:
        if len(_COORDS) >= _COORDS_LIMIT:
            _COORDS.clear()
        _COORDS[key] = names
    return names


class LagrangeDiracSystem(DiracSystem):
    r"""A Lagrange–Dirac system ``(L, Δ, F)``, possibly driven and with holonomic loops.

    Equations (``t`` only where the callables take it)::

        p = ∂L/∂v(q, v, t),   ṗ = ∂L/∂q + F(q, v, t) + A(q, t)ᵀ μ + ∇g(q, t)ᵀ ν,
        A(q, t) v + b(q, t) = 0,   g(q, t) = 0.

    Args:
        coords: names of the coordinates of ``Q = R^n`` (their order is the order of
            every array).
        lagrangian: ``L(q, v)`` or ``L(q, v, t)`` -> scalar, possibly degenerate;
            traceable by JAX.
        constraints: the one-forms ``ω^a`` spanning ``Δ°``, either a callable
            ``A(q) -> (m, n)`` / ``A(q, t)``, or a constant (m, n) array. ``None`` means
            ``Δ = TQ``.
        force: external force ``F(q, v)`` or ``F(q, v, t)`` -> (n,) (a covector).
        name: the system's name (used as prefix when it is interconnected).
        constraint_names: names of the m one-form rows (default ``"ω0"``, ``"ω1"``, ...).
        constraint_offset: the affine term ``b`` of ``A v + b = 0`` — a callable
            ``b(q)`` / ``b(q, t)`` -> (m,) or a constant (m,) array. It prescribes
            velocities: a current source ``i(t)`` in a branch, a prescribed motion.
            Discretized with the same rule as ``A`` (same node, same time).
        holonomic: position constraints ``g(q)`` or ``g(q, t)`` -> (k,), enforced exactly
            at every step: ``g(q_{k+1}, t_{k+1}) = 0`` for the (+) scheme,
            ``g(q_k, t_k) = 0`` for (−), with the reaction ``∇g(·)ᵀν`` on the known end's
            momentum line, like ``A(·)ᵀμ`` (a variational, SHAKE-type placement that
            keeps the rule's order). Their rows follow the one-form rows.
        holonomic_names: names of the k holonomic rows (default ``"g0"``, ``"g1"``, ...).

    Whether a callable depends on time is read once from its signature (two or three
    positional parameters for L and F, one or two for A, b and g); a callable that
    accepts both forms is refused as ambiguous.

    Any of the callables may be an ``equinox.Module`` (a callable PyTree): its arrays are
    then leaves of the system, so systems that differ only in those values share one
    compiled program, and :class:`~diracvi.PartitionedSolver` batches them with
    ``jax.vmap``. Arrays captured by a plain function are compile-time constants.
    """

    _coords: tuple[str, ...] = eqx.field(static=True)
    _constraint_names: tuple[str, ...] = eqx.field(static=True)
    name: str = eqx.field(static=True)
    _lagrangian: _UserFunction
    _force: _UserFunction | None
    _forms_fn: _UserFunction | None
    _forms_const: jax.Array | None
    _offset_fn: _UserFunction | None
    _offset_const: jax.Array | None
    _holonomic: _UserFunction | None
    _m_forms: int = eqx.field(static=True)
    # a permutation of the stacked rows [one-forms; holonomic] (monolithic() keeps the
    # interconnection's row order with it); None for the natural order
    _row_order: tuple[int, ...] | None = eqx.field(static=True)

    def __init__(
        self,
        coords,
        lagrangian,
        constraints=None,
        force=None,
        name: str | None = None,
        constraint_names=None,
        constraint_offset=None,
        holonomic=None,
        holonomic_names=None,
    ):
        ensure_float64()
        self._coords = _checked_coords(coords)
        n = len(self._coords)
        self.name = "system" if name is None else check_name("name", name)
        self._row_order = None
        self._lagrangian, out = _user_function(
            "lagrangian", lagrangian, [(n,), (n,)], "L(q, v)", "L(q, v, t)"
        )
        if out.shape != ():
            raise ModelError(
                f"lagrangian returned an array of shape {out.shape} for q, v of shape ({n},): "
                "it must return a scalar (shape ()). Fix: sum the terms, e.g. "
                "return 0.5 * v @ M @ v - V(q)."
            )
        self._force = None
        if force is not None:
            self._force, out = _user_function("force", force, [(n,), (n,)], "F(q, v)", "F(q, v, t)")
            if out.shape != (n,):
                raise ModelError(
                    f"force returned shape {out.shape}; it must return a covector of shape "
                    f"({n},), one component per coordinate {self._coords}."
                )
        self._forms_fn, self._forms_const = None, None
        m = 0
        if constraints is not None:
            if callable(constraints):
                self._forms_fn, out = _user_function(
                    "constraints", constraints, [(n,)], "A(q)", "A(q, t)"
                )
                if out.ndim != 2 or out.shape[1] != n:
                    raise ModelError(
                        f"constraints returned shape {out.shape}; it must return an (m, {n}) "
                        f"matrix whose rows are one-forms over {self._coords}."
                    )
                m = out.shape[0]
            elif isinstance(constraints, jax.core.Tracer):
                # a traced constant (a parameter being differentiated): shape checks only
                forms = jnp.atleast_2d(jnp.asarray(constraints, dtype=jnp.float64))
                if forms.ndim != 2 or forms.shape[1] != n:
                    raise ModelError(
                        f"constraints has shape {forms.shape} but there are {n} coordinates "
                        f"{self._coords}: pass an (m, {n}) array, one row per one-form."
                    )
                self._forms_const = forms
                m = forms.shape[0]
            else:
                forms = check_forms_array("constraints", constraints, n, self._coords)
                self._forms_const = jax.device_put(forms)  # no per-shape program
                m = forms.shape[0]
        self._m_forms = m
        self._offset_fn, self._offset_const = None, None
        if constraint_offset is not None:
            self._set_offset(constraint_offset, n, m)
        self._holonomic = None
        k = 0
        if holonomic is not None:
            self._holonomic, out = _user_function("holonomic", holonomic, [(n,)], "g(q)", "g(q, t)")
            if out.ndim != 1 or out.shape[0] == 0:
                raise ModelError(
                    f"holonomic returned shape {out.shape}; it must return a 1-D array of "
                    "shape (k,), one entry per position constraint g_i(q) = 0 (k ≥ 1; wrap "
                    "a single constraint as jnp.array([g])), e.g. "
                    "lambda q: jnp.array([q @ q - 1.0])."
                )
            k = out.shape[0]
        self._constraint_names = StaticTuple(_row_names(constraint_names, m, holonomic_names, k))

    def _set_offset(self, offset, n: int, m: int) -> None:
        if m == 0:
            raise ModelError(
                f"constraint_offset={offset!r} was given without constraints: b is the "
                "affine term of A(q, t) v + b(q, t) = 0, so pass constraints=A as well "
                "(for a prescribed velocity of coordinate j, A is the row e_j)."
            )
        if callable(offset):
            self._offset_fn, out = _user_function(
                "constraint_offset", offset, [(n,)], "b(q)", "b(q, t)"
            )
            shape = out.shape
        elif isinstance(offset, jax.core.Tracer):  # a traced constant: shape checks only
            self._offset_const = jnp.asarray(offset, dtype=jnp.float64)
            shape = self._offset_const.shape
        else:
            try:
                const = np.asarray(offset, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise ModelError(
                    f"constraint_offset={offset!r} is neither callable nor numeric: pass "
                    f"b(q), b(q, t) or a constant array of shape ({m},)."
                ) from exc
            if not np.all(np.isfinite(const)):
                raise ModelError("constraint_offset contains NaN or Inf: b must be finite.")
            self._offset_const = jax.device_put(const)
            shape = const.shape
        if shape != (m,):
            raise ModelError(
                f"constraint_offset has shape {shape}, but there are {m} constraint rows: "
                f"b must have shape ({m},), one entry per row of A (A v + b = 0)."
            )

    @property
    def coords(self) -> tuple[str, ...]:
        return self._coords

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return self._constraint_names

    @property
    def time_dependent(self) -> bool:
        parts = (self._lagrangian, self._force, self._forms_fn, self._offset_fn, self._holonomic)
        return any(p is not None and p.driven for p in parts)

    @property
    def constraints_time_dependent(self) -> bool:
        return any(p is not None and p.driven for p in (self._forms_fn, self._holonomic))

    @property
    def affine_constraints(self) -> bool:
        offset = self._offset_fn is not None or self._offset_const is not None
        return offset or self._holonomic is not None

    def lagrangian(self, q, v, t=0.0):
        return self._lagrangian(q, v, t=t)

    def force(self, q, v, t=0.0):
        if self._force is None:
            return _zero_force(q, v)
        return self._force(q, v, t=t)

    @property
    def has_force(self) -> bool:
        return self._force is not None

    def one_forms(self, q, t=0.0):
        """``A(q, t)``, shape (m₁, n): the one-form rows only."""
        if self._forms_fn is not None:
            return self._forms_fn(q, t=t)
        if self._forms_const is not None:
            return self._forms_const
        return jnp.zeros((0, self.n), dtype=jnp.result_type(q))

    def constraint_offset(self, q, t=0.0):
        """``b(q, t)``, shape (m₁,), or ``None`` when the constraints are linear."""
        if self._offset_fn is not None:
            return self._offset_fn(q, t=t)
        return self._offset_const

    @property
    def holonomic_mask(self) -> tuple[bool, ...]:
        mask = (False,) * self._m_forms + (True,) * (self.m - self._m_forms)
        return mask if self._row_order is None else tuple(mask[i] for i in self._row_order)

    def position_constraints(self, q, t=0.0):
        if self._holonomic is None:
            return jnp.zeros((0,), dtype=jnp.result_type(q))
        return self._holonomic(q, t=t)

    def _ordered(self, rows):
        return rows if self._row_order is None else rows[np.asarray(self._row_order)]

    def constraint_forms(self, q, t=0.0):
        forms = self.one_forms(q, t)
        if self._holonomic is not None:
            grad = jax.jacfwd(lambda x: self._holonomic(x, t=t))(q)
            forms = jnp.concatenate([forms, grad], axis=0)
        return self._ordered(forms)

    def order_rows(self, rows):
        return self._ordered(rows)

    @property
    def has_holonomic(self) -> bool:
        return self._holonomic is not None

    @property
    def has_offset(self) -> bool:
        return self._has_offset

    @property
    def _has_offset(self) -> bool:
        return self._offset_fn is not None or self._offset_const is not None

    def __repr__(self) -> str:
        k = 0 if self._holonomic is None else self.m - self._m_forms
        extra = f", holonomic={k}" if k else ""
        driven = ", time-dependent" if self.time_dependent else ""
        return (
            f"LagrangeDiracSystem(name={self.name!r}, coords={self.coords}, "
            f"constraints={self._m_forms}{extra}, force={'yes' if self._force else 'no'}"
            f"{driven})"
        )


def _row_names(constraint_names, m: int, holonomic_names, k: int) -> tuple[str, ...]:
    if constraint_names is None:
        forms = tuple(f"ω{a}" for a in range(m))
    else:
        forms = check_names("constraint_names", constraint_names) if m else ()
        if len(forms) != m:
            raise ModelError(
                f"constraint_names has {len(forms)} names but there are {m} constraint "
                "rows: give one name per row."
            )
    if holonomic_names is None:
        held = tuple(f"g{a}" for a in range(k))
    else:
        held = check_names("holonomic_names", holonomic_names) if k else ()
        if len(held) != k:
            raise ModelError(
                f"holonomic_names has {len(held)} names but holonomic returns {k} "
                "constraints: give one name per entry of g."
            )
    clash = sorted(set(forms) & set(held))
    if clash:
        raise ModelError(
            f"constraint_names and holonomic_names share {clash}: every row needs its own "
            "name (multipliers and residuals are reported by name)."
        )
    return forms + held


def with_row_order(system: LagrangeDiracSystem, order, names) -> LagrangeDiracSystem:
    """``system`` with its constraint rows permuted to ``order`` and named ``names``.

    Used by ``InterconnectedSystem.monolithic()`` so the monolithic system lists its
    rows (subsystem by subsystem, holonomic ones among them) exactly as the
    interconnection does. The fields are static, so this sets them on the new object
    before anyone has seen it.
    """
    object.__setattr__(system, "_row_order", tuple(int(i) for i in order))
    object.__setattr__(system, "_constraint_names", tuple(names))
    return system
