r"""A (linear) Dirac structure at one point of ``T*Q``: a subspace of ``V ⊕ V*``.

Paper §2.1: with ``V = T_{(q,p)}T*Q ≅ R^{2n}`` and the symmetric pairing

    ⟨⟨(v₁, α₁), (v₂, α₂)⟩⟩ = ⟨α₁, v₂⟩ + ⟨α₂, v₁⟩,

a Dirac structure is ``D ⊂ V ⊕ V*`` with ``D = D^⊥``, i.e. isotropic and of dimension
``dim V = 2n``. A vector of ``V ⊕ V*`` is stored as the 4n-array ``(v_q, v_p, α_q, α_p)``
(the paper's canonical coordinates), and ``D`` as an orthonormal basis of rows.

The paper's continuous constructions follow the class, pointwise: ``D_Δ``, ``D_int``,
``⊕``, ``⊠``. All return a :class:`DiracStructure` at one point ``(q, p)`` of ``T*Q``;
none depends on ``p`` (the structures are lifted from distributions on ``Q``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._forms import as_forms_function, check_regular, evaluate
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
        return induced(forms, q, n=n)

    @classmethod
    def interaction(cls, forms, q=None, *, n=None) -> DiracStructure:
        """``D_int = Σ_int ⊕ Σ_int°``; see :func:`diracvi.dirac.interaction`."""
        return interaction(forms, q, n=n)

    @staticmethod
    def direct_sum(*structures: DiracStructure) -> DiracStructure:
        """``D₁ ⊕ D₂ ⊕ …`` on ``Q₁ × Q₂ × …``; see :func:`diracvi.dirac.direct_sum`."""
        return direct_sum(*structures)

    @staticmethod
    def tensor(da: DiracStructure, db: DiracStructure) -> DiracStructure:
        """``D_a ⊠ D_b``; see :func:`diracvi.dirac.tensor`."""
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


# ------------------------------------------------ the paper's constructions
def _forms_at(arg: str, forms, q, n) -> np.ndarray:
    if forms is None:
        if n is None:
            raise ModelError(f"{arg}=None (no one-forms) needs n=<dim Q>.")
        return np.zeros((0, int(n)))
    if callable(forms):
        check_regular(arg, forms, q)
        return evaluate(arg, forms, q)
    mat = evaluate(arg, forms, None, n)
    check_regular(arg, mat)  # constant: only the redundancy warning can fire
    return mat


def induced(forms, q=None, *, n: int | None = None) -> DiracStructure:
    r"""``D_{Δ_Q}(q, p)`` from the constraint one-forms, eq. (DiracStructCoord):

        D_Δ(q, p) = {(v_q, v_p, α_q, α_p) | v_q ∈ Δ(q), α_p = v_q, α_q + v_p ∈ Δ°(q)}

    with ``Δ(q) = ker A(q)`` and ``Δ°(q) = span`` of the rows of ``A(q)``. It is spanned by
    ``(a, 0, 0, a)`` for ``a ∈ Δ``, ``(0, e_j, −e_j, 0)`` for every ``j`` and ``(0, 0, b, 0)``
    for ``b ∈ Δ°``: ``(n − r) + n + r = 2n`` vectors.

    Args:
        forms: ``A`` as an (m, n) array, a callable ``A(q)`` (then ``q`` is required and
            the rank is checked to be locally constant), or ``None`` for ``Δ = TQ``
            (then pass ``n``).
        q: the configuration, for a callable ``A``.
    """
    a = _forms_at("forms", forms, q, n)
    n = a.shape[1]
    delta, ann = kernel_basis(a), row_basis(a)
    zeros = np.zeros
    rows = [np.concatenate([d, zeros(n), zeros(n), d]) for d in delta]
    rows += [np.concatenate([zeros(n), e, -e, zeros(n)]) for e in np.eye(n)]
    rows += [np.concatenate([zeros(n), zeros(n), b, zeros(n)]) for b in ann]
    return DiracStructure(np.array(rows).reshape(-1, 4 * n), n)


def interaction(forms, q=None, *, n: int | None = None) -> DiracStructure:
    r"""The standard interaction structure ``D_int = Σ_int ⊕ Σ_int°`` (paper §2.2).

    ``Σ_int = (Tπ_Q)^{-1}(Σ_Q) = {(v_q, v_p) | v_q ∈ Σ_Q}`` and
    ``Σ_int° = {(α_q, 0) | α_q ∈ Σ_Q°}``, where ``Σ_Q°`` is spanned by the rows of
    ``forms`` (the interaction one-forms ``α^b`` over all of ``Q``). Its distribution is
    ``Σ_int`` and its two-form is zero.
    """
    b = _forms_at("forms", forms, q, n)
    n = b.shape[1]
    sigma, ann = kernel_basis(b), row_basis(b)
    zeros = np.zeros
    rows = [np.concatenate([s, zeros(n), zeros(n), zeros(n)]) for s in sigma]
    rows += [np.concatenate([zeros(n), e, zeros(n), zeros(n)]) for e in np.eye(n)]
    rows += [np.concatenate([zeros(n), zeros(n), c, zeros(n)]) for c in ann]
    return DiracStructure(np.array(rows).reshape(-1, 4 * n), n)


def direct_sum(*structures: DiracStructure) -> DiracStructure:
    r"""``D₁ ⊕ D₂`` on ``T*(Q₁ × Q₂)`` (paper §2.2, "direct sum"):

        (D₁ ⊕ D₂)(q, p) = {((v₁, v₂), (α₁, α₂)) | (v_i, α_i) ∈ D_i(q_i, p_i)}.

    Coordinates are re-ordered to those of ``T*Q`` with ``q = (q₁, q₂)``,
    ``p = (p₁, p₂)``: a vector is ``(v_{q1}, v_{q2}, v_{p1}, v_{p2}, α_{q1}, α_{q2},
    α_{p1}, α_{p2})``. Any number of factors is allowed.
    """
    if not structures:
        raise ModelError("direct_sum needs at least one DiracStructure.")
    for i, d in enumerate(structures):
        if not isinstance(d, DiracStructure):
            raise ModelError(f"direct_sum argument {i} = {d!r} is not a DiracStructure.")
    n = sum(d.n for d in structures)
    rows = []
    offset = 0
    for d in structures:
        for row in d.basis:
            out = np.zeros(4 * n)
            for block in range(4):  # v_q, v_p, α_q, α_p
                out[block * n + offset : block * n + offset + d.n] = row[
                    block * d.n : (block + 1) * d.n
                ]
            rows.append(out)
        offset += d.n
    # the factors are orthogonal to each other, so the stacked rows stay orthonormal
    return DiracStructure(np.array(rows).reshape(-1, 4 * n), n, orthonormal=True)


def tensor(da: DiracStructure, db: DiracStructure) -> DiracStructure:
    r"""The Dirac tensor product (paper §2.2, Jacobs–Yoshimura):

        D_a ⊠ D_b = {(v, α) | ∃β: (v, α + β) ∈ D_a, (v, −β) ∈ D_b}.

    Write ``x_a = (v_a, γ_a) ∈ D_a`` and ``x_b = (v_b, γ_b) ∈ D_b`` in their bases with
    coefficients ``(c_a, c_b)``. The conditions say ``v_a = v_b = v``, ``γ_a = α + β`` and
    ``γ_b = −β``, i.e. ``α = γ_a + γ_b``. So ``D_a ⊠ D_b`` is the image of the linear map
    ``(c_a, c_b) ↦ (v_a, γ_a + γ_b)`` restricted to the kernel of ``(c_a, c_b) ↦ v_a − v_b``:
    one kernel and one image, no sampling.
    """
    if not isinstance(da, DiracStructure) or not isinstance(db, DiracStructure):
        raise ModelError("tensor(da, db) needs two DiracStructure arguments.")
    da._check_same_space(db, "db")
    half = 2 * da.n
    va, ga = da.basis[:, :half].T, da.basis[:, half:].T
    vb, gb = db.basis[:, :half].T, db.basis[:, half:].T
    ker = kernel_basis(np.concatenate([va, -vb], axis=1))  # rows = (c_a, c_b)
    image = np.concatenate([va, np.zeros_like(vb)], axis=1), np.concatenate([ga, gb], axis=1)
    vecs = np.concatenate([image[0] @ ker.T, image[1] @ ker.T], axis=0).T
    return DiracStructure(vecs.reshape(-1, 4 * da.n), da.n)


def _split_dims(forms: Sequence, dims, q) -> list[int]:
    if dims is not None:
        dims = [int(d) for d in dims]
        if len(dims) != len(forms):
            raise ModelError(
                f"dims={dims} has {len(dims)} entries for {len(forms)} subsystems: give one "
                "dim Q_i per subsystem."
            )
        return dims
    out = []
    for i, f in enumerate(forms):
        if f is None or callable(f):
            raise ModelError(
                f"forms[{i}] is {'None' if f is None else 'callable'}, so dim Q_{i + 1} is "
                "unknown: pass dims=(n_1, n_2, ...)."
            )
        out.append(np.atleast_2d(np.asarray(f, dtype=np.float64)).shape[1])
    return out


def combined_forms(forms: Sequence, sigma, dims: Sequence[int]) -> Callable:
    r"""``q ↦`` the rows ``ω̃_i^a = (…, ω_i^a(q_i), …)`` then ``α^b(q)``: a basis choice
    for ``((Δ₁ ⊕ … ⊕ Δ_N) ∩ Σ)°`` as in the paper's §4.1."""
    fns = [
        as_forms_function(f"forms[{i}]", f, d)[0]
        for i, (f, d) in enumerate(zip(forms, dims, strict=True))
    ]
    sig_fn = as_forms_function("sigma", sigma, sum(dims))[0]
    bounds = np.cumsum([0, *dims])

    def forms_fn(q):
        blocks = []
        for i, fn in enumerate(fns):
            a = fn(q[bounds[i] : bounds[i + 1]])
            left = jnp.zeros((a.shape[0], bounds[i]))
            right = jnp.zeros((a.shape[0], bounds[-1] - bounds[i + 1]))
            blocks.append(jnp.concatenate([left, a, right], axis=1))
        blocks.append(sig_fn(q))
        return jnp.concatenate(blocks, axis=0)

    return forms_fn


def interconnection(forms: Sequence, sigma, q, *, dims=None) -> DiracStructure:
    r"""``(D_{Δ₁} ⊕ … ⊕ D_{Δ_N}) ⊠ D_int`` at ``q = (q₁, …, q_N)``, computed with ⊠.

    By the Jacobs–Yoshimura proposition this is ``D_{(Δ₁ ⊕ … ⊕ Δ_N) ∩ Σ}`` *when the
    intersection is clean*. Pointwise, ⊠ cannot tell, so this function first checks
    that the combined one-forms have locally constant rank at ``q`` and raises
    :class:`ModelError` if they do not.

    Args:
        forms: per subsystem, ``A_i`` as an (m_i, n_i) array, a callable ``A_i(q_i)`` or
            ``None`` (``Δ_i = TQ_i``; then pass ``dims``).
        sigma: the interaction one-forms ``B`` over all of ``Q``: (l, n) array or callable.
        q: the configuration on ``Q = Q₁ × … × Q_N``.
        dims: ``(n_1, …, n_N)``, needed when some ``forms[i]`` is callable or ``None``.
    """
    q = np.asarray(q, dtype=np.float64)
    dims = _split_dims(forms, dims, q)
    if sum(dims) != q.shape[0]:
        raise ModelError(
            f"q has {q.shape[0]} entries but the subsystems have dims {dims} "
            f"(total {sum(dims)}): pass q on Q = Q_1 × … × Q_N."
        )
    check_regular("(Δ1 ⊕ … ⊕ ΔN) ∩ Σ one-forms", combined_forms(forms, sigma, dims), q)
    bounds = np.cumsum([0, *dims])
    parts = []
    for i, f in enumerate(forms):
        qi = q[bounds[i] : bounds[i + 1]]
        a = np.zeros((0, dims[i])) if f is None else evaluate(f"forms[{i}]", f, qi, dims[i])
        parts.append(induced(a))
    b = evaluate("sigma", sigma, q, q.shape[0])
    return tensor(direct_sum(*parts), interaction(b))


__all__ = ["combined_forms", "direct_sum", "induced", "interaction", "interconnection", "tensor"]
