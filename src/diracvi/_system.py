r"""Lagrange–Dirac systems ``(L, Δ, F)`` on ``Q = R^n``.

Continuous equations (DESIGN.md §1)::

    q̇ = v,   A(q) v = 0,   ṗ = ∂L/∂q + F(q, v) + A(q)ᵀ μ,   p = ∂L/∂v,

with energy ``E(q, v) = ⟨∂L/∂v, v⟩ − L`` and power balance ``dE/dt = ⟨F, v⟩``.

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

from ._config import ensure_float64
from ._discretize import QuadratureRule
from ._errors import ModelError
from ._validate import (
    check_callable,
    check_forms_array,
    check_name,
    check_names,
    eval_shape,
)


class DiracSystem(eqx.Module):
    """What the discrete (±) equations need from a system on ``R^n``.

    ``coords`` names the n coordinates; ``constraint_names`` the rows of the one-form
    matrix (its multipliers and residuals are reported under these names).
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

    def lagrangian(self, q, v):
        raise NotImplementedError

    def force(self, q, v):
        raise NotImplementedError

    def constraint_forms(self, q):
        """``A(q)``, shape (m, n): row a is the one-form ω^a(q)."""
        raise NotImplementedError

    def energy(self, q, v):
        r"""``E(q, v) = ⟨∂L/∂v, v⟩ − L(q, v)``."""
        p = jax.grad(self.lagrangian, argnums=1)(q, v)
        return p @ v - self.lagrangian(q, v)

    def momentum(self, q, v):
        r"""The Legendre transform ``p = ∂L/∂v(q, v)``."""
        return jax.grad(self.lagrangian, argnums=1)(q, v)

    def multiplier_force(self, q, mu):
        """``A(q)ᵀ μ``: the constraint force the multipliers exert."""
        return self.constraint_forms(q).T @ mu

    def discrete_momenta(self, rule: QuadratureRule, qk, qk1, h):
        r"""``(−D₁L_d − f_d^−, D₂L_d + f_d^+)`` at ``(q_k, q_{k+1})``.

        These are the two discrete Legendre transforms of the forced system: the (+)
        equations read ``p_k = first + A(q_k)ᵀ μ`` and ``p_{k+1} = second``.
        """
        d1, d2 = jax.grad(
            lambda a, b: rule.discrete_lagrangian(self.lagrangian, a, b, h), argnums=(0, 1)
        )(qk, qk1)
        if not self.has_force:  # skip tracing a zero force
            return -d1, d2
        f_minus, f_plus = rule.discrete_forces(self.force, qk, qk1, h)
        return -d1 - f_minus, d2 + f_plus

    @property
    def has_force(self) -> bool:
        """Whether ``force`` can be nonzero (systems without one skip its quadrature)."""
        return True

    def discrete_constraints(self, rule: QuadratureRule, side: str, qk, qk1, h):
        """``ω_{d±}(q_k, q_{k+1})``, shape (m,)."""
        return rule.discrete_constraints(self.constraint_forms, side, qk, qk1, h)


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
    """A user callable (L, F or A) stored so that its parameters are PyTree leaves.

    An ``equinox.Module`` callable is split by :func:`equinox.partition`: its arrays are
    a dynamic field (traced, so subsystems that differ only in parameter values share one
    compiled program and can be stacked for ``jax.vmap``); the rest of it is static. A
    plain function, or a Module whose non-array part is unhashable, is kept whole as a
    static constant, as before (its captured arrays become compile-time constants).
    """

    arrays: Any
    rest: Callable = eqx.field(static=True)

    def __call__(self, *args):
        if self.arrays is None:
            return self.rest(*args)
        return eqx.combine(self.arrays, self.rest)(*args)


def _wrap(fn: Callable) -> _UserFunction:
    if isinstance(fn, eqx.Module):
        arrays, rest = eqx.partition(fn, eqx.is_array)
        try:
            hash(rest)
        except TypeError:  # e.g. a list field: cannot be static, so keep the old way
            return _UserFunction(None, _Opaque(fn))
        return _UserFunction(arrays, rest)
    return _UserFunction(None, _Opaque(fn))


class LagrangeDiracSystem(DiracSystem):
    r"""A Lagrange–Dirac system ``(L, Δ, F)``.

    Args:
        coords: names of the coordinates of ``Q = R^n`` (their order is the order of
            every array).
        lagrangian: ``L(q, v) -> scalar``, possibly degenerate; traceable by JAX.
        constraints: the one-forms ``ω^a`` spanning ``Δ°``, either a callable
            ``A(q) -> (m, n)`` or a constant (m, n) array. ``None`` means ``Δ = TQ``.
        force: external force ``F(q, v) -> (n,)`` (a covector).
        name: the system's name (used as prefix when it is interconnected).
        constraint_names: names of the m constraint rows (default ``"ω0"``, ``"ω1"``, ...).

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

    def __init__(
        self,
        coords,
        lagrangian,
        constraints=None,
        force=None,
        name: str | None = None,
        constraint_names=None,
    ):
        ensure_float64()
        self._coords = check_names("coords", coords)
        n = len(self._coords)
        self.name = "system" if name is None else check_name("name", name)
        self._lagrangian = _wrap(check_callable("lagrangian", lagrangian))
        out = eval_shape("lagrangian", lagrangian, (n,), (n,), signature="L(q, v)")
        if out.shape != ():
            raise ModelError(
                f"lagrangian returned an array of shape {out.shape} for q, v of shape ({n},): "
                "it must return a scalar (shape ()). Fix: sum the terms, e.g. "
                "return 0.5 * v @ M @ v - V(q)."
            )
        self._force = None
        if force is not None:
            self._force = _wrap(check_callable("force", force))
            out = eval_shape("force", force, (n,), (n,), signature="F(q, v)")
            if out.shape != (n,):
                raise ModelError(
                    f"force returned shape {out.shape}; it must return a covector of shape "
                    f"({n},), one component per coordinate {self._coords}."
                )
        self._forms_fn, self._forms_const = None, None
        m = 0
        if constraints is not None:
            if callable(constraints):
                self._forms_fn = _wrap(constraints)
                out = eval_shape("constraints", constraints, (n,), signature="A(q)")
                if out.ndim != 2 or out.shape[1] != n:
                    raise ModelError(
                        f"constraints returned shape {out.shape}; it must return an (m, {n}) "
                        f"matrix whose rows are one-forms over {self._coords}."
                    )
                m = out.shape[0]
            else:
                forms = check_forms_array("constraints", constraints, n, self._coords)
                self._forms_const = jnp.asarray(forms)
                m = forms.shape[0]
        if constraint_names is None:
            self._constraint_names = tuple(f"ω{a}" for a in range(m))
        else:
            names = check_names("constraint_names", constraint_names) if m else ()
            if len(names) != m:
                raise ModelError(
                    f"constraint_names has {len(names)} names but there are {m} constraint "
                    "rows: give one name per row."
                )
            self._constraint_names = names

    @property
    def coords(self) -> tuple[str, ...]:
        return self._coords

    @property
    def constraint_names(self) -> tuple[str, ...]:
        return self._constraint_names

    def lagrangian(self, q, v):
        return self._lagrangian(q, v)

    def force(self, q, v):
        if self._force is None:
            return _zero_force(q, v)
        return self._force(q, v)

    @property
    def has_force(self) -> bool:
        return self._force is not None

    def constraint_forms(self, q):
        if self._forms_fn is not None:
            return self._forms_fn(q)
        if self._forms_const is not None:
            return self._forms_const
        return jnp.zeros((0, self.n), dtype=q.dtype)

    def __repr__(self) -> str:
        return (
            f"LagrangeDiracSystem(name={self.name!r}, coords={self.coords}, "
            f"constraints={self.m}, force={'yes' if self._force else 'no'})"
        )
