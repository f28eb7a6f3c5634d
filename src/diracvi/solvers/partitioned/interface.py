r"""The interface of a partitioned step: which systems and rules it applies to, and the
Robin couplings of one coordinate and one row under a rule (see the package docstring)."""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ...discretization.equations import SCHEMES, new_momentum, ordered, residual
from ...discretization.rules import RULES, QuadratureRule, get_rule
from ...errors import ModelError
from ...model.interconnect import InterconnectedSystem
from ...model.system import LagrangeDiracSystem
from ...model.validate import check_choice

LOCAL_FACTORS = ("auto", "dense")


class PartitionLayout(NamedTuple):
    """How :class:`PartitionedSolver` splits a system (see :meth:`PartitionedSolver.layout`).

    ``groups``: the subsystem names stepped together with one ``jax.vmap``;
    ``interface``: ``"tridiagonal"``, ``"banded(kl, ku)"``, ``"dense"`` or ``"none"`` (no
    interaction rows): how the slot system ``T`` is solved;
    ``interface_size``: the number of slot unknowns (two per copy of a row joining two
    subsystems);
    ``local_factors``: per group, ``"banded(kl, ku)"`` (a banded LU of bandwidths
    ``kl``, ``ku``) or ``"dense"`` (an explicit inverse), as ``local_factors="auto"``
    picks them;
    ``row_copies``: copies of every interaction row (and of its multiplier) in the step:
    1, or 3 for ``"lobatto"`` (the row at the unknown end's stage and at the two stage
    rows);
    ``local_unknowns``: per group, the unknowns of one member: ``n + m``, or for
    ``"lobatto"`` ``3(n + m)``: ``q_other``, the two stage unknowns and the three stage
    multipliers, all kept local to the member.
    """

    groups: tuple[tuple[str, ...], ...]
    interface: str
    interface_size: int
    local_factors: tuple[str, ...] = ()
    row_copies: int = 1
    local_unknowns: tuple[int, ...] = ()


# ----------------------------------------------------------------------------- checks
def _node_is_known(rule: QuadratureRule, scheme: str) -> bool:
    """Does ``rule`` evaluate one-forms at the known end of the step (never the unknown)?"""
    known = np.array([0.3])
    for other in (np.array([1.7]), np.array([-2.9])):
        node = np.asarray(rule.constraint_node(scheme, *ordered(scheme, known, other)))
        if node.shape != known.shape or not np.array_equal(node, known):
            return False
    return True


def _as_rule(rule) -> QuadratureRule:
    if isinstance(rule, QuadratureRule):
        return rule
    return get_rule(check_choice("discretization", rule, tuple(RULES)))


def check_partitionable(system, rule="retraction", scheme: str = "plus") -> None:
    """Raise :class:`ModelError` unless the partitioned solver applies (host side)."""
    if not isinstance(system, InterconnectedSystem):
        raise ModelError(
            f"solver=PartitionedSolver() needs an interconnected system, but system="
            f"{system!r} is a single {type(system).__name__} with no subsystems to split. "
            "Fix: use solver=dv.NewtonSolver() (the default), or build the model from "
            "subsystems with dv.interconnect(...)."
        )
    scheme = check_choice("scheme", scheme, SCHEMES)
    rule = _as_rule(rule)
    if _node_is_known(rule, scheme):
        return
    for inter, (first, count) in zip(system.interactions, system._form_rows, strict=True):
        if inter._fn is not None:
            names = system.interaction_names[first : first + count]
            raise ModelError(
                f"solver=PartitionedSolver() cannot step {system.name!r} with "
                f"discretization={rule.name!r}, scheme={scheme!r}: the interaction with rows "
                f"{names} depends on the configuration, and this rule evaluates it at points "
                "that move with the unknowns (q̄ = (q_k + q_(k+1))/2 for 'midpoint', the "
                "stages Q_j for 'lobatto'), so the interface equations are not linear in them "
                "and do not split by subsystem. "
                "Fix: use solver=dv.NewtonSolver(), or discretization='retraction' (which "
                "evaluates the one-forms at the known configuration)."
            )


# ------------------------------------------------------------------- stage couplings
class _Couplings(NamedTuple):
    """How one interaction row enters a subsystem's step equations under a rule, per unit
    coefficient of ``B`` (rule constants, the same for every row and coordinate).

    ``copies``: the rows' copies (1, or 1 + stages: the row at the unknown end's stage,
    then one per stage row, each with its own multiplier); ``reaction[i, j]``: the share
    of copy ``j``'s multiplier in the coordinate line ``i`` (the momentum line, then the
    stage lines); ``rate[j, u]``: ``h ∂(copy j of B v)/∂(unknown u)`` (``q_other``, then
    the stage unknowns); ``momentum[j]``: copy ``j``'s multiplier in the explicit line;
    ``sign``: the sign the Robin weights take (see :func:`_couplings`).
    """

    copies: int
    reaction: np.ndarray
    rate: np.ndarray
    momentum: np.ndarray
    sign: float


_COUPLINGS: dict = {}


def _couplings(rule: QuadratureRule, scheme: str) -> _Couplings:
    """The rule's :class:`_Couplings`, read off its own step equations on a probe.

    Without stages: ``B_iᵀλ`` on the momentum line and ``(s/h) B_i`` (``s = ±1`` for
    (±)) in ``α``. With stages the probe is one coordinate with the constant one-form
    ``dx`` and ``L = 0``: its multipliers enter its lines and its one-form rows enter in
    the unknowns exactly as an interaction row's multipliers and rows do in the
    interconnection's equations (both are ``A`` of a constant one-form at each stage),
    so the coefficients are the derivatives of
    :func:`~diracvi.discretization.equations.residual` and
    :func:`~diracvi.discretization.equations.new_momentum` themselves, not a copy of their algebra.

    The Robin weights then take the sign of the scheme (see the module documentation:
    ``reaction · rate`` is then, like the mass block of the lines, never of opposite
    sign to it along a real eigendirection), so ``K_i`` is invertible for a massive or
    a massless coordinate."""
    key = (type(rule), rule.name, rule.stages, scheme)
    hit = _COUPLINGS.get(key)
    if hit is not None:
        return hit
    sign = 1.0 if scheme == "plus" else -1.0
    if not rule.stages:
        out = _Couplings(1, np.ones((1, 1)), np.full((1, 1), sign), np.zeros(1), 1.0)
    else:
        copies = 1 + rule.stages
        # natural layout of one coordinate and one row: [q_other, μ, S_1.., ν_1..]
        coord = np.array([0, *range(2, 2 + rule.stages)])
        mult = np.array([1, *range(2 + rule.stages, 2 + 2 * rule.stages)])
        with jax.ensure_compile_time_eval():
            probe = LagrangeDiracSystem(
                ("x",), lambda q, v: 0.0 * v[0], constraints=np.ones((1, 1)), name="probe"
            )
            zero = jnp.zeros(1)
            x = jnp.linspace(0.1, 0.7, 2 * copies)
            jac = np.asarray(
                jax.jacfwd(lambda x: residual(probe, rule, scheme, 1.0, zero, zero, x))(x)
            )
            mom = np.asarray(
                jax.jacfwd(lambda x: new_momentum(probe, rule, scheme, 1.0, zero, x))(x)
            )
        out = _Couplings(
            copies, jac[np.ix_(coord, mult)], jac[np.ix_(mult, coord)], mom[0, mult], sign
        )
    _COUPLINGS[key] = out
    return out


def _local_order(n: int, m: int, copies: int) -> np.ndarray:
    """``perm``: local unknown ``i`` is unknown ``perm[i]`` of the subsystem's own step
    (and local equation ``i`` its equation ``perm[i]``).

    The own step orders its unknowns by kind, ``[q_other, μ, S_1 … S_s, ν_1 … ν_s]``;
    locally they are interleaved per coordinate, ``[(q_other_c, S_1c … S_sc) for c]``,
    then per multiplier, so that a chain piece, whose coordinate ``c`` couples to ``c ± 1``
    at every stage, keeps a band of ``≈ 2·copies`` instead of ``≈ 2n`` (the identity
    without stages)."""
    stages = copies - 1

    def coord(k, c):
        return c if k == 0 else n + m + (k - 1) * n + c

    def mult(k, r):
        return n + r if k == 0 else n + m + stages * n + (k - 1) * m + r

    return np.array(
        [coord(k, c) for c in range(n) for k in range(copies)]
        + [mult(k, r) for r in range(m) for k in range(copies)],
        dtype=np.int64,
    )
