r"""The registry of quadrature rules: one table that turns a name into the rule that turns
L, ω and F into L_d, ω_{d±} and f_d^± (one file per rule; the protocol in :mod:`.base`).

A discretization is a quadrature rule applied *alike* to the Lagrangian, the constraint
one-forms and the forces (DESIGN.md §1). With ``v_k = (q_{k+1} − q_k)/h`` (the inverse of
the vector-space retraction ``R_q(v) = q + h v``):

- ``"retraction"`` (the paper's, order 1): ``L_d = h L(q_k, v_k)``,
  ``ω_{d+} = A(q_k) v_k``, ``(f_d^−, f_d^+) = (h F(q_k, v_k), 0)``;
- ``"midpoint"`` (symmetric, order 2): ``L_d = h L(q̄, v_k)``, ``ω_{d±} = A(q̄) v_k``,
  ``(f_d^−, f_d^+) = (h/2 F(q̄, v_k), h/2 F(q̄, v_k))``,

with ``q̄ = (q_k + q_{k+1})/2``; the (−) constraint of the retraction rule is
``ω_{d−} = A(q_{k+1}) v_k``.

Time-dependent models ``L(q, v, t)``, ``F(q, v, t)``, ``A(q, t) v + b(q, t) = 0`` see time
at the rule's own node: the retraction rule evaluates L and F at ``t_k`` and ``ω_{d±}`` at
the time of its configuration node (``t_k`` for (+), ``t_{k+1}`` for (−)); the midpoint
rule evaluates everything at ``t_k + h/2``. The affine term ``b`` of a constraint is
discretized with the same rule as ``A``: ``ω_{d±} = A(node±, t±) v_k + b(node±, t±)``.

Forces follow the discrete Lagrange–d'Alembert principle
``f_d^∓ ≈ ∫ F · ∂q(t)/∂q_{k,k+1} dt`` along the straight segment
``q(t) = q_k + t v_k``: the left-point rule sees ``∂q(0)/∂q_k = 1``, ``∂q(0)/∂q_{k+1} = 0``;
the midpoint rule sees ``1/2`` for each end.

``"lobatto"`` (order 4) is Lobatto IIID in Hamilton–Pontryagin form: three stage
velocities at ``t_k + (0, ½, 1) h``, stage positions ``Q_i = q_k + h Σ_j a_ij V_j``, and
L, the forces, the inputs and the one-forms evaluated at the stages. Its stage positions
``Q₁, Q₂`` and one multiplier vector per stage are extra unknowns of the step (see
:class:`Lobatto` and ``docs/discretizations.md``).
"""

from __future__ import annotations

from ..errors import ModelError
from .base import QuadratureRule
from .lobatto import Lobatto
from .midpoint import Midpoint
from .names import BUILT_IN
from .retraction import Retraction

#: every rule by name: ``simulate(discretization=…)``, the CLI, the docs and the checks
#: read this one table
RULES: dict[str, type[QuadratureRule]] = {
    "retraction": Retraction,
    "midpoint": Midpoint,
    "lobatto": Lobatto,
}


_INSTANCES: dict[str, QuadratureRule] = {}


def register_rule(rule: type[QuadratureRule]) -> type[QuadratureRule]:
    """Add a rule class to :data:`RULES` under its instances' ``name`` (usable as a
    decorator); ``discretization=name`` then selects it everywhere."""
    if not (isinstance(rule, type) and issubclass(rule, QuadratureRule)):
        raise ModelError(
            f"register_rule({rule!r}): pass a subclass of "
            "diracvi.discretization.base.QuadratureRule."
        )
    name = rule().name
    if name in RULES and RULES[name] is not rule:
        raise ModelError(
            f"a rule named {name!r} is registered already ({RULES[name].__name__}): give "
            "the new rule another name."
        )
    RULES[name] = rule
    _INSTANCES.pop(name, None)
    return rule


def unregister_rule(name: str) -> None:
    """Remove the rule ``name`` from :data:`RULES` (the built-in ones stay)."""
    if name in BUILT_IN:
        raise ModelError(f"the built-in rule {name!r} cannot be removed.")
    RULES.pop(name, None)
    _INSTANCES.pop(name, None)


def rule_names() -> tuple[str, ...]:
    """The names of every registered rule, built-in ones first."""
    return tuple(RULES)


def get_rule(name: str) -> QuadratureRule:
    """The rule called ``name`` (rules are immutable, so one instance serves every run)."""
    if name not in _INSTANCES:
        _INSTANCES[name] = RULES[name]()
    return _INSTANCES[name]


__all__ = [
    "RULES",
    "Lobatto",
    "Midpoint",
    "QuadratureRule",
    "Retraction",
    "get_rule",
    "register_rule",
    "rule_names",
    "unregister_rule",
]
