r"""Operations on discrete Dirac structures: the direct sum ``⊕`` and the product ``⊠_d``.

Paper §4.2. Both act on structures of the same side; ``⊕`` glues structures on
``Q₁, Q₂, …`` into one on ``Q = Q₁ × Q₂ × …``, ``⊠_d`` combines two on the same ``Q``.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ._discrete import DiscreteDiracStructure
from ._linalg import block_diag, row_basis
from ._tulczyjew import _point


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


__all__ = ["DirectSumDiscrete", "TensorDiscrete"]
