r"""Discrete Dirac structures (paper §2.3, §4.2): ``D^{d±}_Δ`` and ``D^{d+}_int``.

A discrete structure is a set of pairs ``((z₀, z₁), α)`` with ``z₀ = (q₀, p₀)``,
``z₁ = (q₁, p₁)`` consecutive points of ``T*Q`` and ``α`` a covector at

- ``ẑ = (q₀, p₁) ∈ Q × Q*`` for ``side="plus"`` (the paper's ``(z, z⁺)``, ``α_ẑ``), with
  components ``(α_q, α_{p⁺})``;
- ``z̃ = (p₀, q₁) ∈ Q* × Q`` for ``side="minus"`` (the paper's ``(z⁻, z)``, ``α_z̃``),
  with components ``(α_{p⁻}, α_q)``.

Every structure here has the same shape: a *distribution condition* ``c(q₀, q₁) = 0``
(a vector of discrete constraints) and, over each ``(z₀, z₁)``, an *affine fibre*
``{α : α − o(z₀, z₁) ∈ W(q)}`` with offset ``o`` and a linear subspace ``W``. Membership
is measured by a residual: the largest of ``‖c‖∞``, the base-point mismatch (when ``α``
is given with its base point, as ``𝔇^±L_d`` is) and the distance of ``α − o`` from ``W``.

The operations (paper §4.2) act on structures of the same side: the direct sum ``⊕``
glues structures on ``Q₁, Q₂, …`` into one on ``Q = Q₁ × Q₂ × …``, ``⊠_d`` combines two
on the same ``Q``.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._forms import as_forms_function
from ._linalg import (
    batched_rowspace_residual,
    block_diag,
    distance,
    kernel_basis,
    row_basis,
    subspace_gap,
)
from ._tulczyjew import _point, as_rule, check_side

#: default tolerance of membership tests, relative to max(1, size of the data)
ATOL = 1e-9


class DiscreteDiracStructure:
    """Base class: a distribution condition and an affine α-fibre (see module docs).

    Subclasses implement :meth:`constraint_matrix` and :meth:`fiber`.
    Build them with :meth:`induced`, :meth:`interaction`, :meth:`direct_sum`,
    :meth:`tensor`.
    """

    side: str
    n: int

    # ------------------------------------------------------------ constructors
    @classmethod
    def induced(cls, forms, rule="retraction", *, h: float = 1.0, side="plus", n=None):
        """``D^{d±}_Δ`` (Leok–Ohsawa, paper §2.3); see :class:`InducedDiscrete`."""
        return InducedDiscrete(forms, rule, h=h, side=side, n=n)

    @classmethod
    def interaction(cls, forms, rule="retraction", *, h: float = 1.0, side="plus", n=None):
        """``D^{d+}_int`` (paper §4.2, Definition); see :class:`InteractionDiscrete`."""
        return InteractionDiscrete(forms, rule, h=h, side=side, n=n)

    @staticmethod
    def direct_sum(*parts):
        """``D^{d+}_{Δ1} ⊕ D^{d+}_{Δ2}`` (paper Definition (discrete_dirac_struct_sum))."""
        return DirectSumDiscrete(*parts)

    @staticmethod
    def tensor(a, b):
        """``D₁ ⊠_d D₂`` (paper §4.2, Definition of ⊠_d)."""
        return TensorDiscrete(a, b)

    # ------------------------------------------------------------ interface
    def constraint_matrix(self, q0, q1) -> np.ndarray:
        """``M(q₀, q₁)`` with ``c(q₀, q₁) = M(q₀, q₁) (q₁ − q₀)``, shape (k, n).

        Every discrete distribution here is of that form: the rules evaluate the one-forms
        at a node and apply them to ``v_k = (q₁ − q₀)/h`` (DESIGN.md §1).
        """
        raise NotImplementedError

    def fiber(self, z0, z1) -> tuple[np.ndarray, np.ndarray]:
        """``(o, W)``: the α-fibre over ``(z₀, z₁)`` is ``o + span(rows of W)``."""
        raise NotImplementedError

    def constraint(self, q0, q1) -> np.ndarray:
        """The discrete distribution condition at ``(q₀, q₁)`` (zero on the structure)."""
        q0, q1 = np.asarray(q0, dtype=np.float64), np.asarray(q1, dtype=np.float64)
        return self.constraint_matrix(q0, q1) @ (q1 - q0)

    def base_point(self, z0, z1) -> np.ndarray:
        """``ẑ = (q₀, p₁)`` (plus) or ``z̃ = (p₀, q₁)`` (minus)."""
        (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
        return np.concatenate([q0, p1] if self.side == "plus" else [p0, q1])

    # ------------------------------------------------------------ membership
    def _alpha(self, z0, z1, alpha) -> tuple[np.ndarray, float]:
        """``alpha`` (2n covector, or 4n ``(base, covector)``) → (covector, base mismatch)."""
        alpha = np.asarray(alpha, dtype=np.float64).ravel()
        if alpha.size == 4 * self.n:
            base, cov = alpha[: 2 * self.n], alpha[2 * self.n :]
            mismatch = float(np.max(np.abs(base - self.base_point(z0, z1)), initial=0.0))
            return cov, mismatch
        if alpha.size != 2 * self.n:
            raise ModelError(
                f"alpha has {alpha.size} entries; here it must be a covector of length "
                f"2n = {2 * self.n} or a point (base, covector) of length 4n = {4 * self.n} "
                "(as returned by dirac_differential_plus/minus)."
            )
        return alpha, 0.0

    def residual(self, z0, z1, alpha) -> float:
        """``max(‖c(q₀, q₁)‖∞, base mismatch, dist(α − o, W))``: 0 iff a member."""
        cov, mismatch = self._alpha(z0, z1, alpha)
        (q0, _), (q1, _) = _point("z0", z0), _point("z1", z1)
        offset, basis = self.fiber(z0, z1)
        con = float(np.max(np.abs(self.constraint(q0, q1)), initial=0.0))
        return max(con, mismatch, distance(basis, cov - offset))

    def membership(self, z0, z1, alpha, atol: float = ATOL) -> tuple[float, bool]:
        """``(residual, residual ≤ atol · max(1, ‖data‖∞))``."""
        res = self.residual(z0, z1, alpha)
        return res, res <= atol * _scale(z0, z1, alpha)

    def contains(self, z0, z1, alpha, atol: float = ATOL) -> bool:
        """``((z₀, z₁), α) ∈ D`` up to ``atol`` (relative to the size of the data)."""
        return self.membership(z0, z1, alpha, atol)[1]

    # ------------------------------------------------------------ comparison
    def fiber_gap(self, other: DiscreteDiracStructure, z0, z1) -> float:
        """How far the α-fibres of two structures over ``(z₀, z₁)`` are from equal."""
        self._check_compatible(other)
        o1, w1 = self.fiber(z0, z1)
        o2, w2 = other.fiber(z0, z1)
        shift = distance(w1, o1 - o2) / max(1.0, float(np.max(np.abs(o1), initial=0.0)))
        return max(subspace_gap(w1, w2), shift)

    def project(self, z0, z1, *, tol: float = 1e-13, max_steps: int = 100):
        """Move ``(z₀, z₁)`` onto the discrete distribution ``c = 0``.

        The (+) distribution constrains ``q₁`` (the paper: "Δ^{d+} constrains only q⁺")
        and the (−) one ``q₀``, so only that end moves. Returns the projected ``(z₀, z₁)``
        or ``None`` if the iteration does not converge.
        """
        (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
        plus = self.side == "plus"
        size = max(1.0, float(np.max(np.abs(np.concatenate([q0, q1])), initial=0.0)))
        a, b = q0.copy(), q1.copy()
        for _ in range(max_steps):
            mat = self.constraint_matrix(a, b)
            c = mat @ (b - a)
            if c.size == 0 or np.max(np.abs(c)) <= tol * size * max(1.0, np.abs(mat).max()):
                return (a, p0), (b, p1)
            # freeze M at the current pair and project the step q₁ − q₀ onto ker M: exact in
            # one sweep when M does not depend on the moving end (the retraction rule),
            # a contraction for a short step otherwise (the midpoint rule)
            ker = kernel_basis(mat)
            step = ker.T @ (ker @ (b - a))
            if plus:
                b = a + step
            else:
                a = b - step
        return None

    def sample_points(self, samples: int = 12, seed: int = 0, scale: float = 1.0):
        """Random ``(z₀, z₁)`` pairs with ``q₁`` near ``q₀`` (a short step)."""
        rng = np.random.default_rng(seed)
        n = self.n
        out = []
        for _ in range(samples):
            q0 = scale * rng.standard_normal(n)
            q1 = q0 + 0.3 * scale * rng.standard_normal(n)
            p0, p1 = rng.standard_normal(n), rng.standard_normal(n)
            out.append(((q0, p0), (q1, p1)))
        return out

    def discrepancy(self, other: DiscreteDiracStructure, points=None, **sample_kw) -> float:
        """The largest disagreement of two structures over sampled ``(z₀, z₁)``.

        At every sample (default: :meth:`sample_points`): the α-fibres are compared at the
        raw point; then the point is projected onto each structure's discrete
        distribution in turn, where the *other* structure's condition must vanish and the
        fibres must agree again. Zero (to round-off) iff the structures coincide on the
        sampled fibres.
        """
        self._check_compatible(other)
        points = self.sample_points(**sample_kw) if points is None else points
        worst, projected_any = 0.0, False
        for z0, z1 in points:
            worst = max(worst, self.fiber_gap(other, z0, z1))
            for a, b in ((self, other), (other, self)):
                on = a.project(z0, z1)
                if on is None:
                    continue
                projected_any = True
                (q0, _), (q1, _) = on
                size = max(1.0, float(np.max(np.abs(np.concatenate([q0, q1])))))
                con = float(np.max(np.abs(b.constraint(q0, q1)), initial=0.0)) / size
                worst = max(worst, con, self.fiber_gap(other, *on))
        if not projected_any:
            raise ModelError(
                "discrepancy: no sample could be projected onto either discrete distribution "
                "(the projection did not converge); pass points=[((q0, p0), (q1, p1)), ...] "
                "that lie near the distributions."
            )
        return worst

    def equals(self, other: DiscreteDiracStructure, atol: float = ATOL, **kw) -> bool:
        """``True`` iff :meth:`discrepancy` ≤ ``atol`` over the sampled points."""
        return self.discrepancy(other, **kw) <= atol

    def _check_compatible(self, other) -> None:
        if not isinstance(other, DiscreteDiracStructure):
            raise ModelError(f"{other!r} is not a DiscreteDiracStructure.")
        if other.side != self.side or other.n != self.n:
            raise ModelError(
                f"cannot combine or compare a ({self.side}) structure on dim Q = {self.n} "
                f"with a ({other.side}) one on dim Q = {other.n}: both must have the same "
                "side and the same Q."
            )

    def __repr__(self) -> str:
        return f"{type(self).__name__}(side={self.side!r}, n={self.n})"


def _scale(z0, z1, alpha) -> float:
    (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
    data = np.concatenate([q0, p0, q1, p1, np.asarray(alpha, dtype=np.float64).ravel()])
    return max(1.0, float(np.max(np.abs(data), initial=0.0)))


class _FromForms(DiscreteDiracStructure):
    """Shared by ``D^{d±}_Δ`` and ``D^{d±}_int``: one-forms discretized by a rule."""

    def __init__(self, forms, rule, *, h, side, n):
        self.side = check_side(side)
        self.rule = as_rule(rule)
        self.h = float(h)
        if not self.h > 0:
            raise ModelError(f"h={h!r} must be a positive step.")
        self.forms, n = as_forms_function("forms", forms, n)
        if n is None:
            raise ModelError(
                "forms is a callable A(q), so dim Q is unknown: pass n=<dim Q> as well."
            )
        self.n = int(n)

    def _constraint(self, q0, q1):
        # ω_{d±}(q₀, q₁): the rule's discrete one-forms (retraction: A(q₀ or q₁) v_k,
        # midpoint: A(q̄) v_k), with v_k = (q₁ − q₀)/h
        forms = self.forms
        return self.rule.discrete_constraints(lambda q, t: forms(q), self.side, q0, q1, self.h)

    def constraint(self, q0, q1) -> np.ndarray:
        q0, q1 = jnp.asarray(q0, dtype=jnp.float64), jnp.asarray(q1, dtype=jnp.float64)
        return np.asarray(self._constraint(q0, q1), dtype=np.float64).ravel()

    def constraint_matrix(self, q0, q1) -> np.ndarray:
        node = self.rule.constraint_node(self.side, jnp.asarray(q0), jnp.asarray(q1))
        return np.asarray(self.forms(node), dtype=np.float64).reshape(-1, self.n) / self.h

    def _offset(self, q0, p0, q1, p1):
        raise NotImplementedError

    def fiber(self, z0, z1):
        (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
        q = q0 if self.side == "plus" else q1  # the base configuration of Δ°_{Q×Q*}
        ann = row_basis(np.asarray(self.forms(jnp.asarray(q)), dtype=np.float64))
        zeros = np.zeros_like(ann)
        blocks = [ann, zeros] if self.side == "plus" else [zeros, ann]
        return self._offset(q0, p0, q1, p1), np.concatenate(blocks, axis=1)

    def batched_parts(self, q0, p0, q1, p1, alpha):
        r"""Vectorized membership over K pairs: the pieces of the residual.

        Args: ``q0, p0, q1, p1`` of shape (K, n); ``alpha`` (K, 2n) covectors or (K, 4n)
        ``(base, covector)``. Returns a dict of arrays: ``constraint`` (K, m) = ``c``;
        ``base`` (K, 2n) = base mismatch (zeros if no base was given); ``fiber`` (K, 2n) =
        the part of ``α − o`` outside ``W``; ``nu`` (K, m) = least-squares coefficients of
        the part inside, on the rows of ``A(q)``.
        """
        q0, p0, q1, p1 = (np.asarray(a, dtype=np.float64) for a in (q0, p0, q1, p1))
        alpha = np.asarray(alpha, dtype=np.float64)
        n = self.n
        plus = self.side == "plus"
        expected_base = np.concatenate([q0, p1] if plus else [p0, q1], axis=1)
        if alpha.shape[1] == 4 * n:
            base, alpha = alpha[:, : 2 * n] - expected_base, alpha[:, 2 * n :]
        else:
            base = np.zeros_like(expected_base)
        offset = self._offset(q0, p0, q1, p1)
        diff = alpha - offset
        q = q0 if plus else q1
        # eager vmap: a jit here would recompile for every new structure
        forms = np.asarray(jax.vmap(self.forms)(jnp.asarray(q)), dtype=np.float64)
        # W = Δ°(q) in the q-slot, 0 in the other slot: that slot of α − o must vanish
        inside, other = (diff[:, :n], diff[:, n:]) if plus else (diff[:, n:], diff[:, :n])
        outside, nu = batched_rowspace_residual(forms, inside)
        fiber = np.concatenate([outside, other] if plus else [other, outside], axis=1)
        constraint = np.asarray(jax.vmap(self._constraint)(jnp.asarray(q0), jnp.asarray(q1)))
        return {"constraint": constraint, "base": base, "fiber": fiber, "nu": nu}

    def residual(self, z0, z1, alpha) -> float:
        (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
        alpha = np.asarray(alpha, dtype=np.float64).ravel()
        self._alpha(z0, z1, alpha)  # validates the length
        parts = self.batched_parts(q0[None], p0[None], q1[None], p1[None], alpha[None])
        return float(combine(parts)[0])


def combine(parts: dict) -> np.ndarray:
    """Per-pair residual ``max(‖c‖∞, ‖base‖∞, ‖fibre‖₂)`` from :meth:`batched_parts`."""

    def inf(a):
        return np.max(np.abs(a), axis=1, initial=0.0)

    return np.maximum.reduce(
        [inf(parts["constraint"]), inf(parts["base"]), np.linalg.norm(parts["fiber"], axis=1)]
    )


class InducedDiscrete(_FromForms):
    r"""The discrete induced Dirac structures ``D^{d±}_Δ`` (paper §2.3, Leok–Ohsawa):

        D^{d+}_Δ = {((z, z⁺), α_ẑ) | (q, q⁺) ∈ Δ^{d+}_Q, α_ẑ − Ω^♭_{d+}(z, z⁺) ∈ Δ°_{Q×Q*}}
        D^{d−}_Δ = {((z⁻, z), α_z̃) | (q⁻, q) ∈ Δ^{d−}_Q, α_z̃ − Ω^♭_{d−}(z⁻, z) ∈ Δ°_{Q*×Q}}

    with ``Δ^{d±}_Q = {ω_{d±} = 0}`` (the rule's discrete one-forms),
    ``Ω^♭_{d+}(z, z⁺) = (q, p⁺, p, q⁺)``, ``Ω^♭_{d−}(z⁻, z) = (p⁻, q, −q⁻, −p)``,
    ``Δ°_{Q×Q*} = {(β, 0) | β ∈ Δ°(q)}`` and ``Δ°_{Q*×Q} = {(0, β) | β ∈ Δ°(q)}``. So the
    fibre over ``((q₀, p₀), (q₁, p₁))`` is ``(p₀, q₁) + Δ°(q₀) × {0}`` (plus) or
    ``(−q₀, −p₁) + {0} × Δ°(q₁)`` (minus). (The paper's §2.3 display writes
    ``Δ_{Q×Q*}``; the annihilator ``Δ°_{Q×Q*}`` defined just above it, and used in §4.2, is
    meant.)

    Args:
        forms: ``A(q)`` (m, n) callable (then pass ``n``), constant array, or ``None``.
        rule: ``"retraction"`` / ``"midpoint"`` or a ``QuadratureRule``: how ``ω_{d±}``
            is formed (DESIGN.md §1).
        h: the step in ``v_k = (q₁ − q₀)/h``; the zero set does not depend on it, the
            size of the constraint residual does.
        side: ``"plus"`` or ``"minus"``.
    """

    def __init__(self, forms, rule="retraction", *, h=1.0, side="plus", n=None):
        super().__init__(forms, rule, h=h, side=side, n=n)

    def _offset(self, q0, p0, q1, p1):
        # the fibre components of Ω^♭_{d+} = (q, p⁺ | p, q⁺) and Ω^♭_{d−} = (p⁻, q | −q⁻, −p)
        if self.side == "plus":
            return np.concatenate([p0, q1], axis=-1)
        return np.concatenate([-q0, -p1], axis=-1)


class InteractionDiscrete(_FromForms):
    r"""The standard discrete interaction structure (paper §4.2, Definition):

        D^{d+}_int = {((z, z⁺), α_ẑ) | (q, q⁺) ∈ Σ^{d+}_Q, α_ẑ − Ω^{d+}_int(z, z⁺) ∈ Σ°_{Q×Q*}}

    with ``Ω^{d+}_int(z, z⁺) = (q, p⁺, 0, 0)``: the fibre over ``(z, z⁺)`` is
    ``Σ°(q) × {0}``. ``forms`` are the interaction one-forms ``α^b`` on all of ``Q``.
    ``side="minus"`` gives the mirror image ``{0} × Σ°(q)`` over ``(z⁻, z)`` with
    ``Ω^{d−}_int = 0`` — not in the paper, provided for symmetry.
    """

    def __init__(self, forms, rule="retraction", *, h=1.0, side="plus", n=None):
        super().__init__(forms, rule, h=h, side=side, n=n)

    def _offset(self, q0, p0, q1, p1):
        return np.zeros((*np.shape(q0)[:-1], 2 * self.n))


# ------------------------------------------------ ⊕ and ⊠_d
class DirectSumDiscrete(DiscreteDiracStructure):
    r"""``D^{d+}_{Δ1} ⊕ D^{d+}_{Δ2}`` (paper Definition (discrete_dirac_struct_sum_coord_def)):

        {((z, z⁺), α_ẑ) | ((q₁, p₁, q₁⁺, p₁⁺), (q₁, p₁⁺, α_{q1}, α_{p1})) ∈ D^{d+}_{Δ1}
                      and ((q₂, p₂, q₂⁺, p₂⁺), (q₂, p₂⁺, α_{q2}, α_{p2})) ∈ D^{d+}_{Δ2}}

    with coordinates partitioned as ``(z, z⁺) = (q₁, q₂, p₁, p₂, q₁⁺, q₂⁺, p₁⁺, p₂⁺)`` and
    ``α_ẑ = (α_{q1}, α_{q2}, α_{p1}, α_{p2})``. The (−) version is the same with
    ``α_z̃ = (α_{p⁻1}, α_{p⁻2}, α_{q1}, α_{q2})``. Any number of factors.

    The paper's Lemma (discrete direct sum): with one separable rule for all the
    one-forms, this equals ``D^{d+}_{Δ1 ⊕ Δ2}`` (tested in ``tests/test_dirac_discrete.py``).
    """

    def __init__(self, *parts: DiscreteDiracStructure):
        if not parts:
            raise ModelError("direct_sum needs at least one DiscreteDiracStructure.")
        for i, part in enumerate(parts):
            if not isinstance(part, DiscreteDiracStructure):
                raise ModelError(f"direct_sum argument {i} = {part!r} is not discrete.")
            if part.side != parts[0].side:
                raise ModelError(
                    f"direct_sum argument {i} is a ({part.side}) structure but argument 0 is "
                    f"({parts[0].side}): sum structures of the same side."
                )
        self.parts = tuple(parts)
        self.side = parts[0].side
        self.n = sum(p.n for p in parts)
        self._bounds = np.cumsum([0, *(p.n for p in parts)])

    def _slices(self):
        return [slice(a, b) for a, b in zip(self._bounds[:-1], self._bounds[1:], strict=True)]

    def constraint_matrix(self, q0, q1):
        blocks = [
            p.constraint_matrix(q0[s], q1[s])
            for p, s in zip(self.parts, self._slices(), strict=True)
        ]
        return block_diag(*blocks).reshape(-1, self.n)

    def fiber(self, z0, z1):
        (q0, p0), (q1, p1) = _point("z0", z0), _point("z1", z1)
        n = self.n
        offset = np.zeros(2 * n)
        rows = []
        for part, s in zip(self.parts, self._slices(), strict=True):
            o, w = part.fiber((q0[s], p0[s]), (q1[s], p1[s]))
            k = part.n
            # each half (2n) of α is split by coordinates: first half [s], second n + [s]
            offset[s], offset[n + s.start : n + s.stop] = o[:k], o[k:]
            block = np.zeros((w.shape[0], 2 * n))
            block[:, s], block[:, n + s.start : n + s.stop] = w[:, :k], w[:, k:]
            rows.append(block)
        return offset, np.concatenate(rows, axis=0)


class TensorDiscrete(DiscreteDiracStructure):
    r"""The discrete Dirac tensor product (paper §4.2, Definition of ``⊠_d``):

        D₁ ⊠_d D₂ = {((z, z⁺), α_ẑ) | ∃β_ẑ: ((z, z⁺), α_ẑ + β_ẑ) ∈ D₁,
                                            ((z, z⁺), −β_ẑ) ∈ D₂}.

    Both memberships require the pair to satisfy both distribution conditions. With
    the fibres ``o_i + W_i``, the conditions are ``α + β = o₁ + W₁ᵀa₁`` and
    ``−β = o₂ + W₂ᵀa₂``: :meth:`witness` solves them for the best β by least squares over
    ``(a₁, a₂)``, and the membership residual is what that best β leaves over. The
    fibre of the product is therefore ``(o₁ + o₂) + (W₁ + W₂)``.
    """

    def __init__(self, a: DiscreteDiracStructure, b: DiscreteDiracStructure):
        if not isinstance(a, DiscreteDiracStructure):
            raise ModelError(f"tensor: first argument {a!r} is not a DiscreteDiracStructure.")
        a._check_compatible(b)
        self.a, self.b = a, b
        self.side, self.n = a.side, a.n

    def constraint_matrix(self, q0, q1):
        return np.concatenate(
            [self.a.constraint_matrix(q0, q1), self.b.constraint_matrix(q0, q1)], axis=0
        )

    def fiber(self, z0, z1):
        o1, w1 = self.a.fiber(z0, z1)
        o2, w2 = self.b.fiber(z0, z1)
        return o1 + o2, row_basis(np.concatenate([w1, w2], axis=0))

    def witness(self, z0, z1, alpha) -> tuple[np.ndarray, float]:
        """The least-squares ``β_ẑ`` and the residual it leaves in ``−β ∈ o₂ + W₂``."""
        cov, _ = self._alpha(z0, z1, alpha)
        o1, w1 = self.a.fiber(z0, z1)
        o2, w2 = self.b.fiber(z0, z1)
        # unknowns (a₁, a₂): W₁ᵀa₁ + W₂ᵀa₂ = α − o₁ − o₂  (then β = o₁ + W₁ᵀa₁ − α)
        mat = np.concatenate([w1, w2], axis=0).T
        rhs = cov - o1 - o2
        if mat.shape[1]:
            coeff = np.linalg.lstsq(mat, rhs, rcond=None)[0]
        else:
            coeff = np.zeros(0)
        a1, a2 = coeff[: w1.shape[0]], coeff[w1.shape[0] :]
        beta = o1 + w1.T @ a1 - cov
        left_over = float(np.linalg.norm(-beta - o2 - w2.T @ a2))
        return beta, left_over

    def residual(self, z0, z1, alpha) -> float:
        _, mismatch = self._alpha(z0, z1, alpha)
        (q0, _), (q1, _) = _point("z0", z0), _point("z1", z1)
        con = float(np.max(np.abs(self.constraint(q0, q1)), initial=0.0))
        return max(con, mismatch, self.witness(z0, z1, alpha)[1])


__all__ = [
    "ATOL",
    "DirectSumDiscrete",
    "DiscreteDiracStructure",
    "InducedDiscrete",
    "InteractionDiscrete",
    "TensorDiscrete",
    "combine",
]
