r"""Consistent initial data: joined ports at equal positions, momenta in the Legendre image.

Two things an initial state ``(q₀, p₀)`` must satisfy that the step equations cannot
repair on their own:

* **ports** joined by :func:`~diracvi.connect` hold ``ẋ = ẏ``; the position-level
  interconnection ``x = y`` then holds for all time only if it holds at t = 0;
* **holonomic constraints** ``g(q, t) = 0``: the scheme enforces them at every new
  step, so a start off ``g(q₀, t₀) = 0`` would jump onto the constraint in the first step;
* **momenta** of a degenerate Lagrangian satisfy the primary constraint
  ``p₀ ∈ ∂L/∂v(q₀, ·) + span A(q₀)ᵀ``. For L quadratic in v (mechanics, circuits,
  gyrators) that set is the affine space ``∂L/∂v(q₀, 0) + range W + range A(q₀)ᵀ`` with
  ``W = ∂²L/∂v²``, which is what is measured (and projected onto) here. ``A`` includes
  the rows ``∇g`` of holonomic constraints (their reactions are constraint forces too).

Everything is evaluated at the initial time ``t₀`` (driven models).
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np

from ..runtime.compile import run_once_jit
from .system import DiracSystem


class InconsistentInitialDataWarning(UserWarning):
    """The initial state violates an interconnection or the primary constraint."""


def _port_pairs(system, offset: int = 0) -> list[np.ndarray]:
    """Index pairs ``(a, b)`` of the coordinates joined by :func:`connect`, at every level
    of nesting: an interconnection's coordinates are its subsystems', in order, so a
    subsystem's pairs are shifted by the coordinates before it."""
    own = getattr(system, "_port_index", None)
    if own is None and getattr(system, "ports", ()):  # named ports of another kind of system
        index = {c: i for i, c in enumerate(system.coords)}
        own = [(index[a], index[b]) for a, b in system.ports]
    pairs = [np.asarray(own, dtype=np.int64).reshape(-1, 2) + offset] if own else []
    for sub in getattr(system, "subsystems", ()):
        pairs += _port_pairs(sub, offset)
        offset += sub.n
    return pairs


def _port_groups(system) -> list[np.ndarray]:
    """Coordinates tied together by chains of connections: the connected components (of
    more than one coordinate) of the graph whose edges are the connections, each sorted,
    in the order of their first coordinate. (Vectorized: a Python union–find over the
    coordinates took 1.8 s for a torn chain of 10⁶ masses.)"""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    pairs = _port_pairs(system)
    if not pairs:
        return []
    edges = np.concatenate(pairs)
    n = system.n
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, labels = connected_components(graph.tocsr(), directed=False)
    tied = np.nonzero(np.bincount(labels)[labels] > 1)[0]  # ascending
    order = tied[np.argsort(labels[tied], kind="stable")]
    groups = np.split(order, np.nonzero(np.diff(labels[order]))[0] + 1)
    return sorted(groups, key=lambda g: int(g[0]))


#: the Legendre data is evaluated at this many (q, t) rows at once, so one compiled program
#: serves the checker's construction (zero, the probe, the probe at later times) and every
#: later check of a nonlinear model (the row padded); above ``_BATCH_LIMIT`` coordinates
#: the n × n blocks are large and the rows go one at a time
_ROWS = 4
_BATCH_LIMIT = 256


@run_once_jit
def _legendre_rows(system, qs, ts):
    """Per row ``(q, t)``: ``∂L/∂v(q, 0, t)``, ``W = ∂²L/∂v²(q, 0, t)``, ``A(q, t)`` and the
    slope ``G = ∂/∂q ∂L/∂v(q, 0, t)`` (with W and A constant, ``∂L/∂v(q, 0) = g₀ + G q``)."""

    def momentum_at_rest(q, t):
        return jax.grad(system.lagrangian, argnums=1)(q, jnp.zeros_like(q), t)

    def one(q, t):
        w = jax.hessian(system.lagrangian, argnums=1)(q, jnp.zeros_like(q), t)
        slope = jax.jacfwd(momentum_at_rest)(q, t)
        return momentum_at_rest(q, t), w, system.constraint_forms(q, t), slope

    return jax.vmap(one)(qs, ts)


def _legendre_pieces(system, rows):
    """:func:`_legendre_rows` at the rows ``(q, t)``, as NumPy arrays stacked over rows.

    Rows go in batches of a fixed size (the last padded by repeating its final row), so
    every call on a system reuses one compiled program."""
    size = _ROWS if system.n <= _BATCH_LIMIT else 1
    qs = np.stack([np.asarray(q, dtype=np.float64) for q, _ in rows])
    ts = np.array([float(t) for _, t in rows])
    pad = -len(rows) % size
    qs = np.concatenate([qs, np.repeat(qs[-1:], pad, axis=0)])
    ts = np.concatenate([ts, np.repeat(ts[-1:], pad)])
    parts = [
        [np.asarray(a) for a in _legendre_rows(system, qs[i : i + size], ts[i : i + size])]
        for i in range(0, len(qs), size)
    ]
    return [np.concatenate(group)[: len(rows)] for group in zip(*parts, strict=True)]


@run_once_jit
def _holonomic_residual(system, q, t):
    """``g(q, t)``: compiled, not evaluated operation by operation (which cost a four-bar
    linkage's warm ``simulate`` call about 2 ms of its 3)."""
    return system.position_constraints(q, t)


@run_once_jit
def _holonomic_pieces(system, q, t):
    """``g(q, t)`` and its Jacobian (empty when there are no holonomic rows)."""
    return system.position_constraints(q, t), jax.jacfwd(system.position_constraints)(q, t)


def _onto_holonomic(system, q, t, iterations: int = 20):
    """The nearest ``q`` with ``g(q, t) = 0``: Gauss–Newton minimal-norm corrections."""
    for _ in range(iterations):
        # t as an array: a Python float would be static, one program per time
        pieces = _holonomic_pieces(system, np.asarray(q, dtype=np.float64), np.float64(t))
        g, jac = (np.asarray(a) for a in pieces)
        if np.max(np.abs(g), initial=0.0) <= 1e-15 * max(1.0, float(np.max(np.abs(q)))):
            break
        q = q - np.linalg.lstsq(jac, g, rcond=None)[0]
    return q


#: rank threshold of the complement, relative to the largest singular value of ``[W, Aᵀ]``
_COMPLEMENT_RCOND = 1e-12
#: from this many coordinates on the complement is found block by block (see below)
_BLOCKWISE_FROM = 200


def _complement(w, forms) -> np.ndarray:
    """``I − B B⁺`` for ``B = [W, Aᵀ]``: the part of a covector no momentum can reach.

    It is the orthogonal projector onto ``ker Bᵀ = ker W ∩ ker A`` (``W`` symmetric), so
    with ``Z`` an orthonormal basis of ``ker W`` and ``N`` one of ``ker (A Z)`` it is
    ``(Z N)(Z N)ᵀ``. ``W`` of a model built from parts is block diagonal (each part's
    velocities enter its own kinetic energy), so ``Z`` comes from the blocks' own
    eigendecompositions and ``A Z`` has one column per massless direction: O(Σ block³)
    instead of the SVD of the whole ``n × (n + m)`` matrix (a torn chain of 1000 masses:
    ≈ 10 s → milliseconds). Small models take the SVD as before."""
    n = w.shape[0]
    if n == 0:
        return np.eye(0)
    if n < _BLOCKWISE_FROM:
        basis = np.concatenate([w, forms.T], axis=1)
        return np.eye(n) - basis @ np.linalg.pinv(basis, rcond=_COMPLEMENT_RCOND)
    blocks = _diagonal_blocks(w)
    eigen = [np.linalg.eigh(w[np.ix_(b, b)]) for b in blocks]
    # the SVD's threshold: relative to ‖B‖₂ ≥ max(‖W‖₂, ‖A‖₂) (within a factor √2)
    scale = max(
        max((float(np.max(np.abs(vals), initial=0.0)) for vals, _ in eigen), default=0.0),
        float(np.linalg.norm(forms, 2)) if forms.size else 0.0,
    )
    tol = _COMPLEMENT_RCOND * scale
    columns = []
    for b, (vals, vecs) in zip(blocks, eigen, strict=True):
        null = vecs[:, np.abs(vals) <= tol]
        if null.shape[1]:
            z = np.zeros((n, null.shape[1]))
            z[b] = null
            columns.append(z)
    if not columns:
        return np.zeros((n, n))
    z = np.concatenate(columns, axis=1)
    if forms.size:
        _, sv, vt = np.linalg.svd(forms @ z)
        rank = int(np.sum(sv > tol))
        z = z @ vt[rank:].T
    return z @ z.T


def _diagonal_blocks(w) -> list[np.ndarray]:
    """The index sets of the diagonal blocks of ``w`` (connected components of its
    sparsity pattern, exact zeros), each sorted."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    count, labels = connected_components(csr_matrix(w != 0), directed=False)
    order = np.argsort(labels, kind="stable")
    return np.split(order, np.cumsum(np.bincount(labels, minlength=count))[:-1])


#: above this many coordinates the momentum check (a dense n × n Hessian and a
#: least-squares solve) is skipped; ports are still checked
MOMENTUM_CHECK_LIMIT = 3000
#: up to this many coordinates a warm call's check is one precomputed matrix product
QUICK_CHECK_LIMIT = 256


class Checker:
    """Consistency of initial data for one system, with what can be precomputed kept.

    ``linear=True`` (systems whose step equations are affine: W and A constant and
    ``∂L/∂v(q, 0)`` affine in q) precomputes the complement projector once, so a check
    is a matrix–vector product; it is verified at ``q_probe`` and otherwise dropped.
    """

    def __init__(
        self,
        system: DiracSystem,
        linear: bool = False,
        q_probe=None,
        t_probe=0.0,
        momentum_limit: int = MOMENTUM_CHECK_LIMIT,
    ):
        self.system = system
        self._momentum_limit = momentum_limit  # above it, momenta are not checked
        self.holonomic = any(getattr(system, "holonomic_mask", ()))
        self.groups = [np.asarray(g) for g in _port_groups(system)]
        # every member of a group against its first: one gather for the common case
        self._pairs = (
            (
                np.concatenate([np.repeat(g[0], len(g) - 1) for g in self.groups]).astype(int),
                np.concatenate([g[1:] for g in self.groups]).astype(int),
            )
            if self.groups
            else None
        )
        self._linear = None
        if linear and system.n <= momentum_limit:
            probe = np.zeros(system.n) if q_probe is None else np.asarray(q_probe)
            scale = 1.0 + np.max(np.abs(probe), initial=0.0)
            # a driven system keeps this path only if nothing here moves with time either
            times = [0.0]
            if system.time_dependent:
                times += [t_probe, t_probe + 1.37 * (1.0 + abs(t_probe))]
            rows = [(np.zeros(system.n), 0.0)] + [(probe, t) for t in times]
            g, w, forms, slope = _legendre_pieces(system, rows)
            g0, slope0 = g[0], slope[0]
            same = all(
                np.allclose(w[0], w[i], rtol=1e-12, atol=1e-12)
                and np.allclose(forms[0], forms[i], rtol=1e-12, atol=1e-12)
                and np.allclose(g0 + slope0 @ probe, g[i], rtol=1e-12, atol=1e-12 * scale)
                for i in range(1, len(rows))
            )
            if same:
                self._linear = (g0, slope0, _complement(w[0], forms[0]))
        self._quick = self._quick_check()

    def _quick_check(self):
        """``(M, c)`` for :meth:`accepts`, or ``None`` (holonomic rows, the general path,
        or a model too large for a dense ``(pairs + n) × 2n`` matrix)."""
        if self._linear is None or self.holonomic or self.system.n > QUICK_CHECK_LIMIT:
            return None
        n = self.system.n
        g0, slope, comp = self._linear
        a, b = self._pairs if self._pairs is not None else (np.zeros(0, int), np.zeros(0, int))
        ports = np.zeros((len(a), 2 * n))
        ports[np.arange(len(a)), a] = 1.0  # rows q[a] − q[b]: exact differences
        ports[np.arange(len(a)), b] = -1.0
        # momenta: comp (p − g0 − slope q), the distance _momentum_projection measures
        momenta = np.concatenate([-comp @ slope, comp], axis=1)
        # Each row divided by half its threshold in check() at the smallest scales (1):
        # ‖M z − c‖₂ ≤ 1 then passes there whatever the rounding of the two formulas
        # (ports: the spread of a group is at most twice its largest pair difference).
        tol = np.concatenate([np.full(len(a), 0.25e-12), np.full(n, 0.5e-10)])
        matrix = np.concatenate([ports, momenta]) / tol[:, None]
        offset = np.concatenate([np.zeros(len(a)), comp @ g0]) / tol
        return matrix, (offset if np.any(offset) else None)

    def accepts(self, q0, p0) -> bool:
        """Whether ``(q0, p0)`` certainly passes :meth:`check` (one matrix–vector product
        for a linear model); ``False`` means only that :meth:`check` must decide."""
        if self._quick is None:
            return False
        matrix, offset = self._quick
        r = matrix @ np.concatenate((q0, p0))
        if offset is not None:
            r -= offset
        return bool(r @ r <= 1.0)

    def quick_test(self):
        """``(M, c)``: data ``z = (q0, p0)``, finite, with ``‖M z − c‖₂ ≤ 1`` pass
        :meth:`check` (``c`` may be ``None``: zero). ``None`` if there is no such test."""
        return self._quick

    def _momentum_projection(self, q, p, t=0.0):
        if self.system.n > self._momentum_limit:
            return p  # the dense Hessian would not fit: ports are checked, momenta not
        if self._linear is not None:
            g0, slope, comp = self._linear
            return p - comp @ (p - g0 - slope @ q)
        return _momentum_projection(self.system, q, p, t)

    def violations(self, q0, p0, t0=0.0) -> dict[str, float]:
        """``{"ports": max |x − y|, "holonomic": max |g(q₀, t₀)|, "momenta": distance
        of p₀ from the consistent set}``."""
        q0, p0 = np.asarray(q0), np.asarray(p0)
        ports = 0.0
        if self._pairs is not None and np.any(q0[self._pairs[0]] != q0[self._pairs[1]]):
            ports = max(np.ptp(q0[g]) for g in self.groups)
        held = 0.0
        if self.holonomic:
            q = np.asarray(q0, dtype=np.float64)
            g = np.asarray(_holonomic_residual(self.system, q, np.float64(t0)))
            held = float(np.max(np.abs(g), initial=0.0))
        proj = self._momentum_projection(q0, p0, t0)
        return {
            "ports": float(ports),
            "holonomic": held,
            "momenta": float(np.max(np.abs(p0 - proj), initial=0.0)),
        }

    def project(self, q0, p0, t0=0.0):
        """The nearest consistent state: joined ports at their mean, ``q₀`` moved onto
        ``g = 0`` (least change), then p₀ projected."""
        q = np.array(q0, dtype=np.float64)
        for _ in range(3 if self.holonomic and self.groups else 1):
            for group in self.groups:
                q[group] = q[group].mean()
            if self.holonomic:
                q = _onto_holonomic(self.system, q, t0)
        return q, self._momentum_projection(q, np.asarray(p0, dtype=np.float64), t0)

    def check_batch(self, q0, p0, *, project_initial: bool, t0=0.0):
        """:meth:`check` for rows of initial states (one warning, for the worst row)."""
        if self._linear is not None and not project_initial and not self.holonomic:
            g0, slope, comp = self._linear
            off = (p0 - g0 - q0 @ slope.T) @ comp.T
            ports = [np.ptp(q0[:, g], axis=1) for g in self.groups]
            score = np.max(np.abs(off), axis=1) + (np.max(ports, axis=0) if ports else 0.0)
            worst = int(np.argmax(score))
            self.check(q0[worst], p0[worst], project_initial=False, stacklevel=4)
            return q0, p0
        rows = [
            self.check(q, p, project_initial=project_initial, stacklevel=4, t0=t0)
            for q, p in zip(q0, p0, strict=True)
        ]
        return np.stack([r[0] for r in rows]), np.stack([r[1] for r in rows])

    def check(self, q0, p0, *, project_initial: bool, stacklevel: int = 3, t0=0.0):
        """Warn about (or, with ``project_initial``, repair) inconsistent initial data."""
        found = self.violations(q0, p0, t0)
        q_scale = max(1.0, float(np.max(np.abs(q0))))
        p_scale = max(1.0, float(np.max(np.abs(p0))))
        bad_q = found["ports"] > 1e-12 * q_scale
        bad_g = found["holonomic"] > 1e-12 * q_scale
        bad_p = found["momenta"] > 1e-10 * p_scale
        if not (bad_q or bad_g or bad_p):
            return q0, p0
        if project_initial:
            return self.project(q0, p0, t0)
        parts = []
        if bad_g:
            names = [
                c
                for c, h in zip(
                    self.system.constraint_names, self.system.holonomic_mask, strict=True
                )
                if h
            ]
            parts.append(
                f"q0 is off the holonomic constraints {names} by up to "
                f"{found['holonomic']:.3e} (|g(q0, t0)|); the first step will jump onto them"
            )
        if bad_q:
            groups = [[self.system.coords[i] for i in g] for g in self.groups]
            parts.append(
                f"joined ports differ in position by up to {found['ports']:.3e} "
                f"(groups {groups}); their interconnection x = y will be off by that forever"
            )
        if bad_p:
            parts.append(
                f"p0 is {found['momenta']:.3e} away from the momenta a degenerate Lagrangian "
                "allows (∂L/∂v + Aᵀμ); the scheme will carry a spurious oscillation"
            )
        warnings.warn(
            "Inconsistent initial data: " + "; ".join(parts) + ". Pass project_initial=True "
            "to simulate() to start from the nearest consistent state "
            "(dv.project_initial_state).",
            InconsistentInitialDataWarning,
            stacklevel=stacklevel,  # warn → Checker.check → simulate → the user's call
        )
        return q0, p0


def _momentum_projection(system, q, p, t=0.0):
    g, w, forms, _ = (a[0] for a in _legendre_pieces(system, [(q, t)]))
    basis = np.concatenate([w, forms.T], axis=1)
    if basis.size == 0:
        return g
    coef, *_ = np.linalg.lstsq(basis, p - g, rcond=None)
    return g + basis @ coef


def violations(system: DiracSystem, q0, p0) -> dict[str, float]:
    """``{"ports": max |x − y|, "momenta": distance of p₀ from the consistent set}``."""
    return Checker(system).violations(q0, p0)


def project(system: DiracSystem, q0, p0):
    """The nearest consistent state: joined ports at their mean, then p₀ projected."""
    return Checker(system).project(q0, p0)


def check(system: DiracSystem, q0, p0, *, project_initial: bool):
    """Warn about (or, with ``project_initial``, repair) inconsistent initial data."""
    return Checker(system).check(q0, p0, project_initial=project_initial)
