r"""The rule protocol: what a quadrature rule must say about one step ``[t_k, t_k + h]``.

A discretization is a quadrature rule applied *alike* to the Lagrangian, the constraint
one-forms and the forces (DESIGN.md §1). With ``v_k = (q_{k+1} − q_k)/h``::

    L_d = h L(node, v_k, t_node),   (f_d^−, f_d^+) = (w⁻, w⁺) h F(node, v_k, t_node),
    ω_{d±} = A(node±, t±) v_k + b(node±, t±)

:class:`QuadratureRule` declares every hook. Writing a rule (the pattern of scipy's
``OdeSolver`` docstring):

- **A two-point rule** (no internal stages): subclass :class:`QuadratureRule` in one new
  file, set ``name`` and ``order`` in ``__init__``, implement the six abstract hooks
  :meth:`~QuadratureRule.node`, :meth:`~QuadratureRule.time_node`,
  :meth:`~QuadratureRule.constraint_node`, :meth:`~QuadratureRule.constraint_time`,
  :meth:`~QuadratureRule.force_weights` and :meth:`~QuadratureRule.impulse_share`, and
  register it with :func:`diracvi.discretization.rules.register_rule`. The default
  :meth:`~QuadratureRule.discrete_lagrangian`, :meth:`~QuadratureRule.discrete_forces`,
  :meth:`~QuadratureRule.discrete_constraints` and :meth:`~QuadratureRule.step_energy`
  apply those nodes and weights; override them only for a different quadrature.
- **A staged rule** (``stages > 0`` internal stage positions and multipliers per step,
  see :mod:`diracvi.discretization.lobatto`): also override :attr:`stages` and the
  staged hooks below (:meth:`~QuadratureRule.nodes` … :meth:`~QuadratureRule.stage_guess`,
  :meth:`~QuadratureRule.holonomic_rows` where ``g`` is imposed);
  the step's unknowns are then ``x = (q_other, μ, S₁ … S_s, ν₁ … ν_s)`` and
  :mod:`diracvi.discretization.equations` assembles them.

Rules are immutable (``eqx.Module``) and compared by value: one instance serves every run.
A rule never sees a system: it evaluates the callables it is handed (``L``, ``F``,
``A``, ``b``); the discrete maps that feed it a system's data live in
:mod:`diracvi.discretization.maps`.
"""

from __future__ import annotations

import abc
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp

from ..errors import ModelError


class QuadratureRule(eqx.Module):
    """A rule for discretizing L, ω and F on one step ``[q_k, q_{k+1}]``."""

    name: str = eqx.field(static=True)
    order: int = eqx.field(static=True)

    # ------------------------------------------------------------ every rule
    @property
    def stages(self) -> int:
        """Internal stages per step (extra unknowns ``(Q, ν)`` of the step equations)."""
        return 0

    @abc.abstractmethod
    def node(self, qk, qk1):
        """The configuration at which L, F (and E for diagnostics) are evaluated."""

    @abc.abstractmethod
    def time_node(self, tk, h):
        """The time at which L, F (and E) are evaluated on the step ``[t_k, t_k + h]``."""

    @abc.abstractmethod
    def constraint_node(self, side: str, qk, qk1):
        """The configuration at which ω_{d±} evaluates the one-forms A(q)."""

    @abc.abstractmethod
    def constraint_time(self, side: str, tk, h):
        """The time that goes with :meth:`constraint_node`."""

    @abc.abstractmethod
    def force_weights(self) -> tuple[float, float]:
        """Weights ``(w⁻, w⁺)`` with ``f_d^∓ = w^∓ h F(node, v_k)``."""

    @abc.abstractmethod
    def impulse_share(self) -> float:
        """The share of a step's constraint impulse that belongs to the far end of the step.

        The (±) equations put the whole impulse ``A(·)ᵀμ`` on the known end's momentum
        line, so the stepped momentum lags the true one by this share of it (½ for the
        symmetric midpoint rule; 0 for the first-order left-point rule, whose force
        quadrature puts everything on the left end anyway).
        """

    def step_energy(self, energy: Callable, qk, qk1, h, tk=0.0, stage=None):
        """The energy reported for a step: ``E(node, v_k, t_node)``."""
        return energy(self.node(qk, qk1), (qk1 - qk) / h, self.time_node(tk, h))

    def discrete_lagrangian(self, lagrangian: Callable, qk, qk1, h, tk=0.0):
        r"""``L_d(q_k, q_{k+1}) = h L(node, (q_{k+1} − q_k)/h, t_node)``."""
        return h * lagrangian(self.node(qk, qk1), (qk1 - qk) / h, self.time_node(tk, h))

    def discrete_forces(self, force: Callable, qk, qk1, h, tk=0.0):
        r"""``(f_d^−, f_d^+)``: the rule applied to ``∫ F · ∂q/∂q_{k,k+1} dt``."""
        f = h * force(self.node(qk, qk1), (qk1 - qk) / h, self.time_node(tk, h))
        w_minus, w_plus = self.force_weights()
        return w_minus * f, w_plus * f

    def discrete_constraints(self, forms: Callable, side: str, qk, qk1, h, tk=0.0, offset=None):
        r"""``ω_{d±}(q_k, q_{k+1}) = A(node±, t±) (q_{k+1} − q_k)/h + b(node±, t±)``.

        ``forms(q, t)`` gives ``A``; ``offset(q, t)`` the affine term ``b`` (or ``None``).
        """
        node, t = self.constraint_node(side, qk, qk1), self.constraint_time(side, tk, h)
        out = forms(node, t) @ ((qk1 - qk) / h)
        return out if offset is None else out + offset(node, t)

    # ------------------------------------------------------------ staged rules
    # A two-point rule has no stages: these hooks answer for it where an answer exists
    # (no stage unknowns, no increments) and refuse where none does.
    def _no_stages(self, hook: str):
        raise ModelError(
            f"discretization={self.name!r} is a two-point rule: it has no internal stages, "
            f"so {hook} is undefined. Fix: call it with a staged rule (stages > 0)."
        )

    def nodes(self, qk, stage, qk1, h, tk):
        """``(Q_j, V_j, t_j)`` at every stage of the step (staged rules)."""
        self._no_stages("nodes")

    def pullback(self, covectors):
        """Covectors at the stage positions → their pull-back to ``(q_k, S, q_{k+1})``:
        the triple ``(left, stage, right)`` (staged rules)."""
        self._no_stages("pullback")

    def reaction_covectors(self, multiplier_force, side, qk, stage, qk1, h, tk, mu, nu, held=None):
        """The constraint reactions at the stages, from ``multiplier_force(q, μ, t) =
        A(q, t)ᵀ μ``; ``held`` (a boolean per row, or ``None`` when there are none) marks
        the holonomic rows (staged rules). :meth:`pullback` takes what this returns."""
        self._no_stages("reaction_covectors")

    def holonomic_points(self, side, qk, stage, qk1, h, tk):
        """Where ``g(q, t) = 0`` is imposed: ``((q_end, t_end), ((Q, t), …))`` (staged
        rules)."""
        self._no_stages("holonomic_points")

    def holonomic_rows(self, held_at, side, qk, stage, qk1, h, tk):
        """The holonomic rows of a step, ``(g at the unknown end, stage rows (k, stages))``,
        from ``held_at(q, t) = g(q, t)`` (staged rules). By default ``g`` at each of
        :meth:`holonomic_points`; a rule that imposes combinations of stage values
        overrides this."""
        (q_end, t_end), points = self.holonomic_points(side, qk, stage, qk1, h, tk)
        return held_at(q_end, t_end), jnp.stack([held_at(q, t) for q, t in points], axis=-1)

    def tableau(self):
        """``(a, â, b)``: the partitioned Runge–Kutta coefficients of a staged rule's
        positions (``a``), momenta (``â``) and weights (``b``) over its nodes — the form in
        which its step is checked stage by stage (:mod:`diracvi.dirac._stagewise`)."""
        self._no_stages("tableau")

    def stage_from_unknowns(self, side: str, qk, qk1, unknowns):
        """The stage positions ``S`` (shape (n, stages)) from the step's stage unknowns;
        ``None`` for a two-point rule."""
        return None

    def stage_guess(self, q, q_other_guess):
        """Starting stage unknowns, shape (n, stages) (empty for a two-point rule)."""
        return jnp.zeros((q.shape[0], 0), dtype=q.dtype)

    def increment_stages(self) -> tuple[int, ...]:
        """The stage unknowns the affine map carries as increments ``S_j − q`` from the
        known end (they stay near it); none for a two-point rule."""
        return ()


__all__ = ["QuadratureRule"]
