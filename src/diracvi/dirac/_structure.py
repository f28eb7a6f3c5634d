r"""A (linear) Dirac structure at one point of ``T*Q``: a subspace of ``V ⊕ V*``.

Paper §2.1: with ``V = T_{(q,p)}T*Q ≅ R^{2n}`` and the symmetric pairing

    ⟨⟨(v₁, α₁), (v₂, α₂)⟩⟩ = ⟨α₁, v₂⟩ + ⟨α₂, v₁⟩,

a Dirac structure is ``D ⊂ V ⊕ V*`` with ``D = D^⊥``, i.e. isotropic and of dimension
``dim V = 2n``. A vector of ``V ⊕ V*`` is stored as the 4n-array ``(v_q, v_p, α_q, α_p)``
(the paper's canonical coordinates), and ``D`` as an orthonormal basis of rows.
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError
from ._linalg import distance, kernel_basis, row_basis, subspace_gap

#: default tolerance of membership and equality tests (relative to O(1) data)
ATOL = 1e-9


def pairing_matrix(n: int) -> np.ndarray:
    """``G`` with ``xᵀ G y = ⟨⟨x, y⟩⟩`` on ``R^{4n} = V ⊕ V*``, ``V = R^{2n}``."""
    eye = np.eye(2 * n)
    zero = np.zeros((2 * n, 2 * n))
    return np.block([[zero, eye], [eye, zero]])


class DiracStructure:
    """A subspace ``D ⊂ V ⊕ V*`` at a point of ``T*Q``, ``Q = R^n``.

    Build one with :meth:`induced`, :meth:`interaction`, :meth:`direct_sum`,
    :meth:`tensor` or, for any user subspace (which need not be Dirac),
    :meth:`from_subspace`.

    Attributes:
        n: ``dim Q`` (so ``dim V = 2n`` and vectors of ``V ⊕ V*`` have length 4n).
        basis: orthonormal rows spanning ``D``, shape (dim D, 4n), columns ordered
            ``(v_q, v_p, α_q, α_p)``.
    """

    __hash__ = None  # mutable-free but compared by tolerance: not hashable

    def __init__(self, basis, n: int, *, orthonormal: bool = False):
        basis = np.atleast_2d(np.asarray(basis, dtype=np.float64))
        if basis.shape[1] != 4 * n:
            raise ModelError(
                f"basis has {basis.shape[1]} columns but n={n} needs 4n = {4 * n} "
                "(v_q, v_p, α_q, α_p)."
            )
        self.n = int(n)
        self.basis = basis if orthonormal else row_basis(basis)

    # ------------------------------------------------------------ constructors
    @classmethod
    def from_subspace(cls, basis) -> DiracStructure:
        """Any subspace spanned by the rows ``(v_q, v_p, α_q, α_p)`` of ``basis``.

        The result need not be a Dirac structure; :meth:`is_dirac` says whether it is.
        """
        basis = np.atleast_2d(np.asarray(basis, dtype=np.float64))
        if basis.ndim != 2 or basis.shape[1] % 4 or basis.shape[1] == 0:
            raise ModelError(
                f"basis has shape {basis.shape}: rows must be vectors (v_q, v_p, α_q, α_p) "
                "of length 4n for Q = R^n, e.g. shape (k, 8) for n = 2."
            )
        if not np.all(np.isfinite(basis)):
            raise ModelError("basis contains NaN or Inf.")
        return cls(basis, basis.shape[1] // 4)

    @classmethod
    def induced(cls, forms, q=None, *, n=None) -> DiracStructure:
        """``D_Δ`` of eq. (DiracStructCoord); see :func:`diracvi.dirac.induced`."""
        from ._constructions import induced

        return induced(forms, q, n=n)

    @classmethod
    def interaction(cls, forms, q=None, *, n=None) -> DiracStructure:
        """``D_int = Σ_int ⊕ Σ_int°``; see :func:`diracvi.dirac.interaction`."""
        from ._constructions import interaction

        return interaction(forms, q, n=n)

    @staticmethod
    def direct_sum(*structures: DiracStructure) -> DiracStructure:
        """``D₁ ⊕ D₂ ⊕ …`` on ``Q₁ × Q₂ × …``; see :func:`diracvi.dirac.direct_sum`."""
        from ._constructions import direct_sum

        return direct_sum(*structures)

    @staticmethod
    def tensor(da: DiracStructure, db: DiracStructure) -> DiracStructure:
        """``D_a ⊠ D_b``; see :func:`diracvi.dirac.tensor`."""
        from ._constructions import tensor

        return tensor(da, db)

    # ------------------------------------------------------------ views
    @property
    def dim(self) -> int:
        return self.basis.shape[0]

    @property
    def dim_v(self) -> int:
        """``dim V = 2n``."""
        return 2 * self.n

    def _vec(self, x) -> np.ndarray:
        if isinstance(x, tuple | list) and len(x) == 2:
            v, alpha = (np.asarray(a, dtype=np.float64).ravel() for a in x)
            x = np.concatenate([v, alpha])
        x = np.asarray(x, dtype=np.float64).ravel()
        if x.shape != (4 * self.n,):
            raise ModelError(
                f"x has {x.size} entries but an element of V ⊕ V* here has 4n = {4 * self.n}:"
                f" pass (v, α) with v, α of length {2 * self.n}, or one array of length "
                f"{4 * self.n} ordered (v_q, v_p, α_q, α_p)."
            )
        return x

    # ------------------------------------------------------------ tests
    def distance(self, x) -> float:
        """Euclidean distance of ``x = (v, α)`` from ``D``."""
        return distance(self.basis, self._vec(x))

    def contains(self, x, atol: float = ATOL) -> bool:
        """``(v, α) ∈ D`` up to ``atol · max(1, ‖(v, α)‖)``."""
        x = self._vec(x)
        return self.distance(x) <= atol * max(1.0, float(np.linalg.norm(x)))

    def gap(self, other: DiracStructure) -> float:
        """``‖P_D − P_{D'}‖₂`` (the sine of the largest principal angle; 1 if dims differ)."""
        self._check_same_space(other, "other")
        return subspace_gap(self.basis, other.basis)

    def equals(self, other: DiracStructure, atol: float = ATOL) -> bool:
        """``D = D'`` as subspaces, up to ``atol`` in :meth:`gap`."""
        return self.gap(other) <= atol

    def __eq__(self, other) -> bool:
        if not isinstance(other, DiracStructure):
            return NotImplemented
        return self.n == other.n and self.equals(other)

    def isotropy_defect(self) -> float:
        """``max |⟨⟨b_i, b_j⟩⟩|`` over the orthonormal basis (0 iff ``D ⊂ D^⊥``)."""
        half = 2 * self.n
        v, alpha = self.basis[:, :half], self.basis[:, half:]
        gram = alpha @ v.T + v @ alpha.T
        return float(np.max(np.abs(gram), initial=0.0))

    def is_isotropic(self, atol: float = ATOL) -> bool:
        return self.isotropy_defect() <= atol

    def is_dirac(self, atol: float = ATOL) -> bool:
        """``D = D^⊥``: isotropic and maximal (``dim D = dim V = 2n``)."""
        return self.dim == 2 * self.n and self.is_isotropic(atol)

    def orthogonal(self) -> DiracStructure:
        r"""``D^⊥ = {y : ⟨⟨x, y⟩⟩ = 0 ∀ x ∈ D}`` = the kernel of ``x ↦ (α_x, v_x)·y``."""
        half = 2 * self.n
        swapped = np.concatenate([self.basis[:, half:], self.basis[:, :half]], axis=1)
        return DiracStructure(kernel_basis(swapped), self.n, orthonormal=True)

    # ------------------------------------------------------------ geometry
    def distribution(self) -> np.ndarray:
        r"""``Δ_D = {v : (v, α) ∈ D for some α}``: orthonormal rows, shape (k, 2n)."""
        return row_basis(self.basis[:, : 2 * self.n])

    def two_form(self, basis=None, atol: float = ATOL) -> np.ndarray:
        r"""``ω_{Δ_D}(u_i, u_j) = ⟨α_{u_i}, u_j⟩`` on the rows ``u_i`` of ``basis``.

        ``α_{u}`` is any covector with ``(u, α_u) ∈ D``; the value does not depend on the
        choice because ``D = D^⊥`` (two choices differ by ``(0, α)`` ∈ D, and isotropy
        gives ``⟨α, u⟩ = 0`` for every ``u ∈ Δ_D``). ``basis`` defaults to
        :meth:`distribution`; its rows must lie in ``Δ_D``.
        """
        if not self.is_isotropic(atol):
            raise ModelError(
                f"two_form: this subspace is not isotropic (defect "
                f"{self.isotropy_defect():.2e}), so ⟨α_u, w⟩ depends on the choice of α_u "
                "and ω_{Δ_D} is not defined. Fix: use a Dirac structure (check is_dirac())."
            )
        half = 2 * self.n
        dist = self.distribution()
        u = dist if basis is None else np.atleast_2d(np.asarray(basis, dtype=np.float64))
        if u.shape[1] != half:
            raise ModelError(f"basis must have rows of length 2n = {half}; got {u.shape}.")
        for i, row in enumerate(u):
            if distance(dist, row) > atol * max(1.0, float(np.linalg.norm(row))):
                raise ModelError(
                    f"basis row {i} = {row.tolist()} is not in the distribution Δ_D of this "
                    "structure: ω_{Δ_D} is only defined on Δ_D. Use rows of distribution()."
                )
        v, alpha = self.basis[:, :half], self.basis[:, half:]
        # coefficients c with vᵀ c = u (least squares; exact since u ∈ Δ_D), α_u = αᵀ c
        coeff = np.linalg.lstsq(v.T, u.T, rcond=None)[0]
        alpha_u = (alpha.T @ coeff).T
        return alpha_u @ u.T

    # ------------------------------------------------------------ helpers
    def _check_same_space(self, other, arg: str) -> None:
        if not isinstance(other, DiracStructure):
            raise ModelError(f"{arg}={other!r} is not a DiracStructure.")
        if other.n != self.n:
            raise ModelError(
                f"{arg} lives on T*Q with dim Q = {other.n}, this one on dim Q = {self.n}: "
                "compare or combine structures on the same space (use direct_sum for "
                "different factors)."
            )

    def __repr__(self) -> str:
        tag = "Dirac" if self.is_dirac() else "not Dirac"
        return f"DiracStructure(n={self.n}, dim={self.dim}, {tag})"
