r"""Newton on a step Jacobian that is banded after reordering, but for a few full rows and columns.

A circuit's step Jacobian ``J`` (s × s, ``s = n + m``) is sparse: each unknown meets its
device's and its nodes' few neighbours. Ordered by reverse Cuthill–McKee
(``scipy.sparse.csgraph.reverse_cuthill_mckee`` on the symmetrized pattern) a chain of
stages becomes banded — except for a *hub*, an unknown that meets every stage (the supply
node's multiplier meets every p-channel transistor) and alone makes the band as wide
as the matrix. The hubs are put last, as a border of ``k`` rows and columns:

.. math::

    P J P^T = \begin{pmatrix} A & B \\ C & D \end{pmatrix},

``A`` ((s − k) × (s − k)) banded with bandwidths ``(kl, ku)``, ``B``, ``C``, ``D`` full.
With ``A = L U`` (banded LU with partial pivoting, :mod:`.banded`) and the Schur
complement ``S = D − C A^{-1} B`` (k × k, dense LU), ``J x = b`` is

.. math::

    y = A^{-1} b_1, \quad S x_2 = b_2 − C y, \quad x_1 = y − (A^{-1} B) x_2 .

Forming the Jacobian takes ``kl + ku + 1`` compressed JVPs for ``A`` (columns of one
colour ``j mod (kl + ku + 1)`` meet disjoint core rows) and ``k`` for the border columns,
through one linearization, and ``k`` transposed products (VJPs) for the border rows —
against ``s`` JVPs of ``jax.jacfwd``; the factorization is O(s·kl·(kl+ku) + s·k²)
against ``(2/3) s³``. Everything is ``jax`` code inside the compiled program (and as
differentiable as the dense solve). :class:`BorderedNewtonSolver` is
:class:`~diracvi.solvers.newton.NewtonSolver` with these factors: the same chord
iteration, junction limiting, fresh Jacobian before giving up and residual test.

**The border** (:func:`plan`, host side, once per system — cached by its content, so a
netlist read again reuses it): starting from none, the unknown of highest degree whose
removal narrows the RCM band of the rest the most is moved to the border (with a neighbour
where it alone would leave the core structurally singular) while that lowers the Jacobian's
cost in tangents, ``kl + ku + 1 + 2k``. The core ``A`` must be structurally nonsingular (a
perfect matching of its rows to its columns,
``scipy.sparse.csgraph.maximum_bipartite_matching``): then ``A`` is nonsingular at almost
every point.

**A singular core** (:func:`factorize`): at a point where ``A`` is singular or nearly so
and ``J`` is not (a row of the core whose terms all vanish there, its hub's term aside),
the block elimination fails where a dense LU pivots past it. Each factorization therefore
checks itself on one probe, ``b = J·1`` solved by the factors as ``x̂``: where the factors
or ``x̂`` are not finite, or the componentwise backward error

.. math::

    \max_i \frac{|b - J \hat x|_i}{(|J|\,|\hat x| + |b|)_i}

exceeds ``BACKWARD_ERROR`` (a backward-stable solve leaves a few units of round-off), the
solves of these factors are made by a dense LU of ``J``, assembled from the same products
(no further tangent), under ``lax.cond``. A ``J`` that is itself singular still gives
non-finite solves, which Newton reports as a singular step. The probe costs one solve and
two products with the band, O(s·(kl + ku + k)).

**When** (:func:`plan`): from ``MIN_SIZE`` unknowns on, the structure is used when it
needs at most a quarter of the dense Jacobian's tangents, ``kl + ku + 1 + 2k ≤ s / 4``,
and the dense solve is kept otherwise (small or densely coupled systems). Measured on
chains of CMOS inverters (docs/performance.md): at a share of 0.32 (4 inverters) the
bordered factorization was 19 % cheaper than the dense one and its solves 40 % dearer,
about even over a solve's few iterations; the quarter leaves such cases dense.

The pattern is read by :func:`~diracvi.solvers.sparsity.step_pattern` (random points,
``finite_rows``). An entry it missed would alias into another entry of its colour: the
Jacobian is then wrong, Newton slower, the residual — and so the answer — still exact.
"""

from __future__ import annotations

import hashlib
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np

from ..discretization.equations import unknown_count
from ..errors import ModelError
from ..runtime.fingerprint import Unstorable, canonical
from . import banded
from .base import StepResult
from .limiting import junction_limiter
from .newton import NewtonSolver, chord_newton
from .sparsity import step_pattern

#: at most this fraction of the dense Jacobian's ``s`` tangents, or the dense solve is kept
TANGENT_SHARE = 0.25
#: below this many unknowns the dense solve is kept without reading the pattern (which
#: costs 2–4 s of CPU): a dense factorization costs little there (0.77 ms at 89 unknowns,
#: 2.4 ms at 171) and the band's solves more than dense ones; at 132 (the corpus deck
#: xy_sandler1, band 8, border 4, its Jacobian's condition number ~1e15) the bordered
#: run took 57 326 Newton iterations against 48 477 and 21.3 s of CPU against 19.8
MIN_SIZE = 200
#: the border's size is at most this (its Schur complement is a dense k × k LU)
MAX_BORDER = 16
#: a probe's componentwise backward error above this sends the solves to a dense LU: a
#: backward-stable solve leaves a few units of round-off (measured: 1.4e-14 median, 4e-13
#: at most, at 16 states along the 8-inverter chain's run); √ε, where a solve has lost half
#: its digits to a badly conditioned core, is far from both that and the O(1) of a singular one
BACKWARD_ERROR = 2.0**-26


def _rcm(sym: np.ndarray, core: np.ndarray):
    """RCM order of ``core`` (indices) and the bandwidths ``(kl, ku)`` it gives ``sym``."""
    # SciPy only here and in _nonsingular: a plan is made from MIN_SIZE unknowns on, and
    # importing scipy.sparse.csgraph (≈ 0.25 CPU s) is most of a small deck's imports
    # beyond JAX's (issue 30)
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    sub = sym[np.ix_(core, core)]
    order = reverse_cuthill_mckee(csr_matrix(sub), symmetric_mode=True)
    return core[order], banded.bandwidths(sub[np.ix_(order, order)])


def _cost(kl: int, ku: int, k: int) -> int:
    """Tangents to form the Jacobian: the band's colours, the border's columns and rows."""
    return kl + ku + 1 + 2 * k


def structure(pattern: np.ndarray):
    """``(perm, k, kl, ku)`` for a boolean step-Jacobian pattern: ``perm`` the core in RCM
    order then the ``k`` border unknowns, ``(kl, ku)`` the core's bandwidths in that order
    (see the module documentation). The core is structurally nonsingular."""
    size = pattern.shape[0]
    pattern = np.asarray(pattern, bool)
    sym = pattern | pattern.T | np.eye(size, dtype=bool)
    border: list[int] = []
    core = np.arange(size)
    order, (kl, ku) = _rcm(sym, core)
    while len(border) < min(MAX_BORDER, size - 2):
        degree = sym[np.ix_(core, core)].sum(axis=1)
        best = None
        # candidates: the unknowns of the 8 largest degrees (a hub meets many); one
        # whose removal leaves the core structurally singular goes with a neighbour (the
        # supply's multiplier with the source's charge, whose only other term it is)
        top = np.sort(degree)[::-1][min(7, degree.size - 1)]  # the 8th largest, ties kept
        for c in core[degree >= top]:
            for group in [(c,)] + [(c, j) for j in core[sym[c, core]] if j != c]:
                rest = core[~np.isin(core, group)]
                if not _nonsingular(pattern, rest):
                    continue
                o, (l_, u_) = _rcm(sym, rest)
                cost = _cost(l_, u_, len(border) + len(group))
                if best is None or cost < best[0]:
                    best = (cost, group, o, l_, u_)
                if len(group) == 1:
                    break  # the hub alone will do
        if best is None or best[0] >= _cost(kl, ku, len(border)):
            break
        border += [int(i) for i in best[1]]
        core = core[~np.isin(core, best[1])]
        order, kl, ku = best[2], best[3], best[4]
    perm = np.concatenate([order, np.asarray(border, dtype=order.dtype)])
    return perm, len(border), kl, ku


def _nonsingular(pattern: np.ndarray, core: np.ndarray) -> bool:
    """Has ``pattern[core, core]`` a perfect matching (structural full rank)?"""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching

    match = maximum_bipartite_matching(csr_matrix(pattern[np.ix_(core, core)]), perm_type="column")
    return bool(np.all(match >= 0))


_PLANS: dict = {}
_PLANS_SIZE = 64


def _content_key(system, rule, scheme: str):
    """A key for everything :func:`plan` reads, or ``None`` where it cannot be printed.

    The plan is a function of the step's pattern, and the pattern
    (:func:`~diracvi.solvers.sparsity.step_pattern`) of the traced residual program, the
    integer arrays (kept as they are: incidence and index tables carry the topology) and,
    through the points taken at the system's own parameters (``finite_rows``), its
    floating arrays' values. So the key is the system and the rule printed whole with
    every array by value (:func:`~diracvi.runtime.fingerprint.canonical`: the program
    store's printing, which determines the traced program), and the scheme: a netlist
    read again (``spice.run`` of the same deck) gives the same key, any changed value
    another one. Unprintable systems (a user's Python function kept whole, traced values)
    give ``None`` and are cached by identity."""
    try:
        text = canonical((system, rule), values=True)
    except Unstorable:
        return None
    return ("content", hashlib.sha256(text.encode()).hexdigest(), scheme)


def plan(system, rule, scheme: str = "plus"):
    """The structured solve for ``system``'s step (``(perm, k, kl, ku)``, see
    :func:`structure`), or ``None`` where the dense solve is cheaper or the core is not
    structurally nonsingular. Host side, cached by the system's content
    (:func:`_content_key`; by identity where it has none)."""
    size = unknown_count(system, rule)
    if size < MIN_SIZE:
        return None
    content = _content_key(system, rule, scheme)
    key = (id(system), rule.name, scheme) if content is None else content
    hit = _PLANS.get(key)
    if hit is not None and (content is not None or hit[0] is system):
        return hit[1]
    pattern = step_pattern(system, rule, scheme, ("bordered", *key), finite_rows=True)
    perm, k, kl, ku = structure(pattern)
    core = perm[: size - k]
    fits = _cost(kl, ku, k) <= TANGENT_SHARE * size and _nonsingular(pattern, core)
    found = (tuple(int(i) for i in perm), k, kl, ku) if fits else None
    # by identity the system is kept alive (its id is not reused); by content it need not be
    _PLANS[key] = (system if content is None else None, found)
    while len(_PLANS) > _PLANS_SIZE:
        _PLANS.pop(next(iter(_PLANS)))
    return found


def newton_for(system, rule, scheme: str = "plus", **options) -> NewtonSolver:
    """The loop's Newton solver for ``system``: :class:`BorderedNewtonSolver` where
    :func:`plan` finds a structure, else the dense :class:`NewtonSolver` (``options``
    passed to either)."""
    found = plan(system, rule, scheme)
    if found is None:
        return NewtonSolver(**options)
    perm, k, kl, ku = found
    return BorderedNewtonSolver(perm=perm, border=k, kl=kl, ku=ku, **options)


class Layout(NamedTuple):
    """The order of a step's unknowns for the bordered solve (host side, static)."""

    perm: np.ndarray  # the core (RCM) then the border
    border: int  # k
    kl: int
    ku: int

    @property
    def size(self) -> int:
        return self.perm.size

    @property
    def width(self) -> int:
        return self.kl + self.ku + 1


def factorize(fn, x, layout: Layout, *, fallback: bool = True):
    """The factors of ``J = ∂fn/∂x`` at ``x`` (see the module documentation) and ``J``'s
    parts ``(A by rows, B, (C D))``, signed (for the residual test's magnitudes and the
    dense fallback). ``fallback``: check the factors on a probe and solve by a dense LU
    where they fail it (see "A singular core"); ``False`` trusts them (tests)."""
    k, kl, ku, width, size = layout.border, layout.kl, layout.ku, layout.width, layout.size
    inner, outer = layout.perm[: size - k], layout.perm[size - k :]
    # the tangents: the band's colours on the core columns, then the border's columns
    tangents = np.zeros((width + k, size))
    tangents[:width, inner] = banded.seeds(size - k, kl, ku)
    tangents[width + np.arange(k), outer] = 1.0
    r, jvp = jax.linearize(fn, x)
    products = jax.vmap(jvp)(jnp.asarray(tangents, r.dtype))  # (width + k, s)
    rows = banded.from_products(products[:width][:, inner], kl, ku)
    lu = banded.lu(rows, kl, ku)
    b = products[width:][:, inner].T  # (s − k, k)
    if k:
        # the border rows, (C D): k products of the transposed linearization
        (c_d,) = jax.vmap(jax.linear_transpose(jvp, x))(jnp.eye(size, dtype=r.dtype)[outer])
    else:
        c_d = jnp.zeros((0, size), r.dtype)
    parts = (rows, b, c_d)
    # the probe b = J·1 (see "A singular core") rides along A⁻¹ B as one more column: the
    # band's solve costs its scans' steps, hardly their width
    probe = product(parts, jnp.ones(size, r.dtype), layout)
    columns = jnp.concatenate([b, probe[inner][:, None]], axis=1) if fallback else b
    solved = banded.solve(lu, columns, kl, ku)
    ainv_b, y = solved[:, :k], (solved[:, k] if fallback else None)
    if k:
        c = c_d[:, inner]
        d = products[width:][:, outer].T
        s_lu, s_piv = jsl.lu_factor(d - c @ ainv_b)
    else:
        c = jnp.zeros((0, size), r.dtype)
        s_lu, s_piv = jnp.zeros((0, 0), r.dtype), jnp.zeros(0, jnp.int32)
    factors = (*lu, ainv_b, c, s_lu, s_piv)
    dense = jnp.asarray(False)
    if fallback:
        # the block elimination's componentwise backward error on the probe
        x2 = jsl.lu_solve((s_lu, s_piv), probe[outer] - c @ y) if k else probe[outer]
        got = jnp.zeros(size, r.dtype).at[inner].set(y - ainv_b @ x2).at[outer].set(x2)
        error = jnp.abs(probe - product(parts, got, layout))
        scale = magnitude(parts, jnp.abs(got), layout) + jnp.abs(probe)
        finite = jnp.all(jnp.isfinite(got)) & jnp.all(jnp.isfinite(s_lu))
        dense = ~finite | jnp.any(error > BACKWARD_ERROR * scale)
    return (*factors, dense), parts


def empty_factors(layout: Layout, dtype):
    """Zeros shaped as :func:`factorize`'s result (a chunk's initial solver state)."""
    k, kl, size = layout.border, layout.kl, layout.size
    core = size - k
    factors = (
        jnp.zeros((core, layout.width), dtype),  # U rows
        jnp.zeros((core, kl), dtype),  # multipliers
        jnp.zeros(core if kl else 0, jnp.int32),  # pivots
        jnp.zeros((core, k), dtype),  # A⁻¹ B
        jnp.zeros((k, core), dtype),  # C
        jnp.zeros((k, k), dtype),  # LU of S
        jnp.zeros(k, jnp.int32),
        jnp.asarray(False),  # solve by the dense fallback
    )
    parts = (
        jnp.zeros((core, layout.width), dtype),  # A by rows
        jnp.zeros((core, k), dtype),  # B
        jnp.zeros((k, size), dtype),  # (C D)
    )
    return factors, parts


def _block_solve(factors, b, layout: Layout):
    """``x`` with ``J x = b`` by block elimination with the band's and the Schur
    complement's factors."""
    upper, lower, pivots, ainv_b, c, s_lu, s_piv = factors
    k, size = layout.border, layout.size
    inner, outer = layout.perm[: size - k], layout.perm[size - k :]
    y = banded.solve((upper, lower, pivots), b[inner], layout.kl, layout.ku)
    if k:
        x2 = jsl.lu_solve((s_lu, s_piv), b[outer] - c @ y)
        y = y - ainv_b @ x2
    else:
        x2 = b[outer]
    return jnp.zeros(size, b.dtype).at[inner].set(y).at[outer].set(x2)


def dense_matrix(parts, layout: Layout):
    """``J`` (s × s, the unknowns' order) assembled from :func:`factorize`'s parts."""
    rows, b, c_d = parts
    k, kl, size, width = layout.border, layout.kl, layout.size, layout.width
    inner, outer = layout.perm[: size - k], layout.perm[size - k :]
    col = np.arange(size - k)[:, None] - kl + np.arange(width)[None, :]
    inside = (col >= 0) & (col < size - k)  # R is zero outside: added to a clipped column
    core_rows = jnp.zeros((size - k, size), rows.dtype)
    core_rows = core_rows.at[np.arange(size - k)[:, None], inner[np.clip(col, 0, size - k - 1)]]
    core_rows = core_rows.add(jnp.where(jnp.asarray(inside), rows, 0.0))
    core_rows = core_rows.at[:, outer].set(b)
    return jnp.zeros((size, size), rows.dtype).at[inner].set(core_rows).at[outer].set(c_d)


def solve(both, b, layout: Layout):
    """``x`` with ``J x = b`` from :func:`factorize`'s result: block elimination, or a
    dense LU of ``J`` where the factors failed their probe."""
    factors, parts = both
    *blocks, dense = factors

    def by_dense(b):
        return jsl.lu_solve(jsl.lu_factor(dense_matrix(parts, layout)), b)

    return jax.lax.cond(dense, by_dense, lambda b: _block_solve(blocks, b, layout), b)


def product(parts, v, layout: Layout):
    """``J v`` from :func:`factorize`'s parts (``v`` in the unknowns' order)."""
    rows, b, c_d = parts
    k, kl, size, width = layout.border, layout.kl, layout.size, layout.width
    inner, outer = layout.perm[: size - k], layout.perm[size - k :]
    col = np.arange(size - k)[:, None] - kl + np.arange(width)[None, :]
    inside = (col >= 0) & (col < size - k)  # R is zero outside; the gather is clipped
    v1 = v[inner][np.clip(col, 0, size - k - 1)]
    band = jnp.sum(jnp.where(jnp.asarray(inside), rows * v1, 0.0), axis=1) + b @ v[outer]
    return jnp.zeros(size, v.dtype).at[inner].set(band).at[outer].set(c_d @ v)


def magnitude(parts, v, layout: Layout):
    """``|J| v`` from :func:`factorize`'s parts (``v`` in the unknowns' order)."""
    return product(jax.tree.map(jnp.abs, parts), v, layout)


class BorderedNewtonSolver(NewtonSolver):
    """:class:`NewtonSolver` with the step Jacobian formed and factorized as a band plus a
    border (see the module documentation; :func:`newton_for` builds one from a system).

    Args (beyond :class:`NewtonSolver`'s):
        perm: the unknowns in the solve's order, the core (RCM) then the border.
        border: the border's size ``k``.
        kl, ku: the core's lower and upper bandwidths in that order.
    """

    perm: tuple = eqx.field(static=True, default=())
    border: int = eqx.field(static=True, default=0)
    kl: int = eqx.field(static=True, default=0)
    ku: int = eqx.field(static=True, default=0)

    def layout(self, eqs) -> Layout:
        size = eqs.size
        if sorted(self.perm) != list(range(size)):
            raise ModelError(
                f"BorderedNewtonSolver(perm=…): must order the step's {size} unknowns, "
                f"got {len(self.perm)} entries; build it with bordered.newton_for(system, rule)."
            )
        return Layout(np.asarray(self.perm, dtype=np.intp), self.border, self.kl, self.ku)

    def init(self, eqs):
        return (*empty_factors(self.layout(eqs), eqs.q.dtype), jnp.asarray(False))

    def solve(self, eqs, guess, state, atol=None) -> StepResult:
        """Solve ``eqs.residual(x) = 0`` from ``guess`` (``atol``: see
        :meth:`NewtonSolver.solve`)."""
        fn = eqs.residual
        layout = self.layout(eqs)
        # each equation's size: the known momentum and the linearized change over the step
        x_ref = eqs.reference()
        known = jnp.zeros(eqs.size, dtype=eqs.q.dtype).at[: eqs.p.shape[0]].set(jnp.abs(eqs.p))
        # with the force terms a law computes (StepEquations.force_sizes, as NewtonSolver)
        with_forces = eqs.bounds_forces

        def row_scale(both, x):
            linear = known + magnitude(both[1], jnp.abs(x - x_ref), layout)
            return linear + eqs.force_sizes(x) if with_forces else linear

        factors, parts, valid = state
        x, status, iterations, res_norm, (factors, parts) = chord_newton(
            self,
            fn,
            lambda x: factorize(fn, x, layout),
            lambda both, r: solve(both, -r, layout),
            guess,
            (factors, parts),
            valid,
            eqs.scale(),
            limit=junction_limiter(eqs) if self.limit_junctions else None,
            row_scale=row_scale,
            reference=x_ref,
            atol=atol,
        )
        return StepResult(x, status, iterations, res_norm, (factors, parts, status == 0))
