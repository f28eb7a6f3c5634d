r"""Variable steps for a linear circuit on the sparse step map, a host loop.

A linear (affine) interconnection's (+) midpoint step of size ``h`` from ``z = (q, p)``
at ``t`` is, in increments ``y = (q_other − q, μ)`` (:mod:`diracvi.solvers.sparse_affine`),

    J_x(h) y = −(r₀(t; h) + J_z(h) z),      p_other − p = P₀(t; h) + P_z(h) z + P_x(h) y.

:func:`adaptive_sparse` marches it with exactly the error control of
:mod:`diracvi.driver.adaptive` — step doubling (one step of ``H`` against two of ``H/2``),
the same per-coordinate, per-velocity and per-node-potential tests with
:data:`~diracvi.driver.step_error.SAFETY`, the same acceptance rule, breakpoints landed
exactly, the two fine steps recorded — so :mod:`diracvi.spice._resample` reads its
:class:`~diracvi.driver.adaptive.AdaptiveRun` unchanged. It differs in how a step is
solved: the compiled loop runs Newton on the dense step equations (dense Jacobians,
O(n²) memory, O(n³) per factorization; a 1000-stage ladder did not finish in 9 minutes
at 10.5 GB), here each step is three sparse products accumulated in place and one solve
of the node count, O(n) for a ladder: each size's ``J_x`` is condensed onto the nodes
(:mod:`diracvi.solvers.condensed`: the parts' own unknowns eliminated by batched block
inverses, the equilibrated node system factored by SuperLU) and stepped on the augmented
state, as the fixed-step map does (``SparseAffineMap.one_step``). Factoring the whole
``J_x`` instead solved 5002 unknowns a step on the 1000-stage ladder, against 2002
(nnz(L + U) 22 002 against 8 011; see :mod:`diracvi.solvers.sparse_affine`).

**Step sizes on a grid, factored only when needed.** ``J_x`` depends on ``h``, so each
step size needs its own factorization. The controller's proposal is rounded *down* to
the grid ``2·hmax·2^{−k}`` (a try of ``H`` records two steps of ``H/2 ≤ hmax``): a try
needs the maps of two neighbouring levels, ``H`` and ``H/2``, and a run touches a handful
of levels, each factored by SuperLU once and kept in a small cache (:data:`CACHE_SIZE`
maps; a landing's dropped first, then the least recently used). Only a step that lands
on a breakpoint (a source corner, the run's end) has a size off the grid.

The step matrices of a linear circuit under the midpoint rule are ``A/h + B + C·h``
entry by entry (inertia over ``h``; resistance, coupling and constraint rows; stiffness
times ``h``), so :func:`~diracvi.solvers.sparse_affine.build` (probes of the model: the
costly part) runs four times — three grid sizes to fit ``A, B, C``, one to check the
fit to round-off — and every other size's matrices are a combination of those three,
``O(nnz)``. A model whose step is not of that form gets a build per size. So a run
makes 4 builds and at most ``4 + (levels visited + 1) + 2·(landing tries)``
factorizations (:class:`SparseRun` counts them), whatever its length; ngspice refactors
at every change of step. Rounding down costs tries against a continuous size: 1.1× the
compiled loop's on a 3-stage ladder, 1.4× on a pulse train (``benchmarks/README.md``).

**Offsets with ``h`` as data.** ``r₀(t; h)``, ``P₀(t; h)`` of the three steps of a try
come from one compiled program (the driven parts' own rows, or the whole residual at zero,
vmapped over ``(h, t)`` pairs): no program is compiled per step size, its arguments are
flattened once per run, and one call serves the next tries at the same size
(:mod:`.sparse_offsets`: the tries of a run mostly follow one another at one size).

**A second error control.** ``error="truncation"`` takes one step per try and judges
it by its local truncation error, read from the step and the last three nodes
(:mod:`.sparse_truncation`, :mod:`.truncation_error`): one solve a step where step
doubling takes three per two recorded steps, on the same maps, tests and tolerances.

**Verification.** ``build`` checks affinity (the Jacobians at two points agree and
reproduce the residual); the map's own check (one Newton correction ``J_x⁻¹ r`` of the
model's residual, below ``verify_rtol`` relative) is run on a sample of accepted steps
of every map used. A model that is not affine, not an interconnection, or has switches
is refused (:class:`~diracvi.solvers.sparse_affine.NotSparseAffine`); the caller then
takes the compiled loop.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from typing import NamedTuple

import numpy as np

from ..discretization.rules import get_rule
from ..errors import ModelError
from ..runtime.config import ensure_float64
from ..solvers.condensed import SingularStep, condense, own_unknowns
from ..solvers.sparse_affine import NotSparseAffine, build
from ..solvers.sparse_pattern import _structure, structural_pattern
from . import events
from .adaptive import (
    FAILED_SOLVE,
    OK,
    TOO_MANY,
    TOO_SMALL,
    AdaptiveRun,
    Controls,
    _inertia,
)
from .delay import incidents
from .sparse_lines import LineOffsets, Waves, line_breakpoints, line_hmax, need_doubling
from .sparse_offsets import _Offsets
from .sparse_truncation import march as truncation_march
from .step_error import DEFAULT_ERROR, ERRORS, SAFETY, estimate, growth_of

#: how many step maps (each an assembled, factored J_x for one step size) are kept
CACHE_SIZE = 8

#: names this path in ``AdaptiveRun.solver``
DESCRIBE = (
    "variable steps on the sparse affine map (condensed to the nodes, SuperLU, step sizes on "
    "a 2^-k grid)"
)

#: a sample of accepted steps is verified against the model's own residual: every this
#: many steps of a map (and the first), at most :data:`VERIFY_MAX` per map
VERIFY_EVERY = 256
VERIFY_MAX = 12
#: the samples are verified as they come, this many at a time (the steps one call of
#: the probe program checks)
VERIFY_BATCH = 3


class SparseRun(NamedTuple):
    """What :func:`adaptive_sparse` reports besides the :class:`AdaptiveRun`: ``builds``
    (maps assembled by probing the model), ``factorizations`` (sparse LU factorizations,
    the builds' included), ``levels`` (the grid levels ``k`` the tries used), ``fit``
    (whether the maps were combined from the basis builds)."""

    builds: int
    factorizations: int
    levels: tuple
    fit: bool
    #: tries whose size was off the grid (a step landing on a breakpoint or the end)
    landings: int = 0
    #: a run with transmission lines: ``(LineOffsets, Waves)`` — the lines (names,
    #: ``Z₀``, delays, port charges) and their recorded ``(t_centre, w)``
    #: (:mod:`.sparse_lines`); None without
    lines: tuple | None = None


class _Map:
    """One step size's map: ``found``, the
    :class:`~diracvi.solvers.sparse_affine.SparseAffineMap` at this ``h`` (its ``J_x``
    condensed onto the nodes and factored; its ``_check_steps`` verifies the steps)."""

    def __init__(self, found, grid):
        self.found, self.h, self.grid = found, found.h, grid
        self.n, self.size = found.n, found.size
        self.samples = []  # (z, y, t, shift) of accepted steps not yet verified
        self.accepted = 0  # steps of this map accepted so far
        self.sampled = 0  # of them, kept for the verification (verified or not)
        self.worst = 0.0  # the largest relative correction of the verified ones

    def check(self) -> float:
        """Verify the samples kept so far (then drop them): the largest relative Newton
        correction of this map's verified steps (see :func:`_verify`)."""
        if self.samples:
            z, y, t, shift = zip(*self.samples, strict=True)
            z, y, t = np.stack(z), np.stack(y), np.stack(t)
            # without lines the model's own residual is the step's (no shift)
            shift = None if shift[0] is None else np.stack(shift)
            self.worst = max(self.worst, self.found._check_steps(z, y, t, shift=shift))
            self.samples = []
        return self.worst

    def step(self, z, u):
        """``(z_next, y)`` of one step from ``z`` with the moving offsets ``u`` (the
        driven rows of ``r₀``, ``P₀``; see ``SparseAffineMap._augmented``)."""
        after, y = np.empty_like(z), np.empty(self.size)
        self.found.one_step(z, u, after, y)
        return after, y


def _mats(found):
    return (found.jz, found.jx, found.pz, found.px, found.r0, found.pm0)


def _largest(a) -> float:
    """``max |a_ij|`` of a sparse matrix or an array (0 if empty), without densifying."""
    if hasattr(a, "tocoo"):
        a = a.tocoo().data
    return float(np.max(np.abs(a), initial=0.0))


def _weights(sizes, h):
    """``λ(h)`` with ``M(h) = Σ_i λ_i(h) M(h_i)`` for every ``M(h) = A/h + B + C·h``."""
    x = np.asarray(sizes) / sizes[0]
    basis = np.stack([1.0 / x, np.ones(3), x], axis=1)  # rows: (1/x_i, 1, x_i)
    u = h / sizes[0]
    return np.linalg.solve(basis.T, np.array([1.0 / u, 1.0, u]))


class _Maps:
    """The cache of step maps, keyed by the step size.

    The step matrices of a linear circuit under the midpoint rule are ``A/h + B + C·h``
    entry by entry (inertia over ``h``; damping, coupling and constraint rows; stiffness
    times ``h``). So after :data:`FIT_SIZES` builds at grid sizes and one more that checks
    the fit, a map for any ``h`` is a combination of those three (``O(nnz)``, no probes)
    and one SuperLU factorization. If the check fails (a model whose step is not of that
    form), every size is built."""

    def __init__(self, system, rule, q0, p0, t0, detect_rtol, verify_rtol, top, lines=None):
        self.system, self.rule = system, rule
        self.lines = lines  # the transmission lines' rows (sparse_lines.LineOffsets)
        self.q0, self.p0, self.t0 = q0, p0, t0
        self.detect_rtol, self.verify_rtol = detect_rtol, verify_rtol
        self.pattern = structural_pattern(system, rule)
        offsets, mu_start, mu_sizes, *_ = _structure(system)
        self.groups = own_unknowns(offsets, mu_start, mu_sizes)  # the condensed blocks
        self.drivers = None  # the driven parts whose rows give every map's offsets
        self.cache: OrderedDict = OrderedDict()
        self.builds = self.factorizations = 0
        self.levels: set = set()
        self.worst = 0.0  # the verification of maps dropped from the cache (their samples)
        self.basis = None  # the three builds the others are combined from
        self.fit = None  # True / False once checked
        self.top = top

    def _build(self, h):
        self.builds += 1
        self.factorizations += 1
        return build(
            self.system, self.rule, "plus", float(h), self.q0, self.p0, self.t0,
            self.detect_rtol, self.verify_rtol, pattern=self.pattern,
        )  # fmt: skip

    def _try_fit(self) -> None:
        """Build the three basis sizes and one check size; decide ``self.fit``."""
        sizes = [self.top * 2.0**-k for k in FIT_SIZES]
        self.basis = (sizes, [self._build(h) for h in sizes])
        check_h = self.top * 2.0**-FIT_CHECK
        found = self._build(check_h)
        combined = self._combine(check_h)
        worst = 0.0
        for j, (got, want) in enumerate(zip(combined, _mats(found), strict=True)):
            if j >= 4 and found.driven:  # the offsets: what the drivers do not replace
                if found.drivers is None:
                    continue  # (every offset comes from the compiled program)
                rows = found.driver_rows if j == 4 else found.driver_coords
                got, want = np.delete(got, rows), np.delete(want, rows)
            worst = max(worst, _largest(got - want) / max(_largest(want), 1e-300))
        self.fit = worst <= FIT_RTOL
        for h, f in zip([*sizes, check_h], [*self.basis[1], found], strict=True):
            self._store(float(h), f, grid=True)

    def _combine(self, h):
        sizes, found = self.basis
        lam = _weights(sizes, h)
        out = []
        for parts in zip(*(_mats(f) for f in found), strict=True):
            total = lam[0] * parts[0]
            for w, m in zip(lam[1:], parts[1:], strict=True):
                total = total + w * m
            out.append(total)
        return out

    def _store(self, key, found, grid):
        if found.driven and (found.drivers is None) != (self.drivers is None):
            self._no_drivers(found)  # every map takes its offsets the same way
        if self.lines is not None:  # their offsets are set step by step (sparse_lines)
            found.line_rows, found.line_coords = self.lines.rows, self.lines.coords
            found._step = found._one = None
        entry = _Map(found, grid)
        self.cache[key] = entry
        while len(self.cache) > CACHE_SIZE:
            # off-grid maps (a landing's) go first, then the least recently used
            off = [k for k, v in self.cache.items() if not v.grid and k != key]
            drop = off[0] if off else next(iter(self.cache))
            # (verified as it goes: a dropped map is not kept for the end, 13 maps of
            # a 10⁴-stage ladder and their samples were a third of its run's memory)
            self.worst = max(self.worst, self.cache.pop(drop).check())
        return entry

    def _no_drivers(self, found) -> None:
        """Offsets of every row from the whole residual, for every map (one build's
        drivers did not reproduce its offsets, or the first ones are stored)."""
        if self.drivers is None and found.drivers is not None and not self.cache:
            self.drivers = found.drivers  # the first map: its drivers are the run's
            return
        self.drivers = None
        for f in [found, *(e.found for e in self.cache.values())]:
            f.drivers = f.driver_rows = f.driver_coords = None
            f._step = None

    def get(self, h: float, level: int | None) -> _Map:
        key = float(h)
        if level is not None:
            self.levels.add(level)
        if self.fit is None:
            self._try_fit()
        found = self.cache.get(key)
        if found is not None:
            self.cache.move_to_end(key)
            return found
        if not self.fit:
            return self._store(key, self._build(key), level is not None)
        mats = self._combine(key)
        try:
            lu = condense(mats[1].tocsc(), self.groups)
        except SingularStep as exc:
            raise NotSparseAffine(f"the step Jacobian at h = {key:g} is singular ({exc})") from None
        self.factorizations += 1
        found = self.basis[1][0].resized(key, mats, lu)
        return self._store(key, found, level is not None)

    def all(self):
        return list(self.cache.values())


#: a landing this close to a grid size (relative) takes the grid's map (:meth:`_Tries.plan`):
#: ``target − t`` is off by the round-off of ``t`` (≈ 1e-16 of it), and the step's
#: solution moves by ``SNAP`` of a step's change at most — far below any tolerance
SNAP = 1e-10

#: the grid levels built to fit ``A/h + B + C·h`` (see :class:`_Maps`), and the one that
#: checks the fit; the fit must reproduce its matrices to ``FIT_RTOL`` of their largest entry
FIT_SIZES = (0, 2, 4)
FIT_CHECK = 6
FIT_RTOL = 1e-12


class _Record:
    """Growing buffers of the recorded steps: nodes ``t``, sizes ``h``, states ``z`` (its
    halves are ``q`` and ``p``), multipliers ``μ``."""

    def __init__(self, capacity: int, n: int, m: int):
        self.n, self.k = n, 0
        self.t = np.empty(capacity + 1)
        self.h = np.empty(capacity)
        self.z = np.empty((capacity + 1, 2 * n))
        self.mu = np.empty((capacity, m))

    def start(self, t, z):
        self.t[0], self.z[0] = t, z

    def _grow(self):
        for name in ("t", "h", "z", "mu"):
            old = getattr(self, name)
            new = np.empty((2 * old.shape[0], *old.shape[1:]))
            new[: old.shape[0]] = old
            setattr(self, name, new)

    def add(self, t, h, z, mu):
        if self.k >= len(self.h):
            self._grow()
        k = self.k
        self.t[k + 1], self.h[k], self.z[k + 1], self.mu[k] = t, h, z, mu
        self.k = k + 1

    def arrays(self):
        """``(t, h, q, p, μ)``: views of the written rows (no copy of the states)."""
        k, n = self.k, self.n
        z = self.z[: k + 1]
        return self.t[: k + 1], self.h[:k], z[:, :n], z[:, n:], self.mu[:k]


def _level(h: float, top: float) -> tuple[float, int]:
    """``h`` rounded down to the grid ``top·2^{−k}`` (``k ≥ 0``): the size and ``k``."""
    k = max(0, math.ceil(math.log2(top / h) - 1e-12))
    return top * 2.0**-k, k


def _verify(maps: _Maps) -> float:
    """The largest relative Newton correction of the sampled steps (see the module doc)."""
    return max([maps.worst, *(entry.check() for entry in maps.all())])


class _Tries:
    """What the tries of a run share — the maps, the offsets, the tolerances — and the
    tries themselves: a doubled one (:meth:`doubled`) and a single step (:meth:`single`,
    :mod:`.sparse_truncation`), sized by :meth:`plan`."""

    def __init__(self, maps, offsets, n, tolerances, hmax, top, momenta=None, lines=None):
        self.maps, self.offsets, self.n = maps, offsets, n
        # the transmission lines: (LineOffsets, Waves), and the last try's pending waves
        self.lines = lines
        self.pending = None
        self.snap = lines is not None
        self.tolerances, self.hmax, self.top = tolerances, hmax, top
        self.landings = 0
        # (A(q)ᵀ as a sparse matrix, the inertia per coordinate): the nodal momenta's
        # error (step_error.node_momentum_error); None leaves them unjudged
        self.momenta = momenta

    def plan(self, h: float, rem: float, top: float):
        """``(size, level, lands)`` of a try proposed at ``h`` with ``rem`` left to the
        next breakpoint: rounded down to the grid ``top·2^{−k}``; the whole remainder
        if it is within the rounded size, half of it if within twice (no sliver left);
        ``level`` None off the grid (a landing, counted). Also the rounded size.

        With :attr:`snap` (a run with lines), a remainder within :data:`SNAP` of the
        grid size lands with the grid's map: the lines' breakpoints fall every delay,
        often whole multiples of the grid, and each landing's size, off the grid by the
        round-off of ``target − t``, was a map of its own (bug1370's 500 breakpoints
        0.1 ns apart: 1013 maps factored, 44 s of its 45 under the profiler)."""
        h0, k = _level(min(h, top), top)
        if self.snap and abs(rem - h0) <= SNAP * h0:
            return h0, k, True, h0
        if rem <= h0 * (1.0 + 1e-9):
            self.landings += 1
            return rem, None, True, h0
        if rem < 2.0 * h0:
            self.landings += 1
            return 0.5 * rem, None, False, h0
        return h0, k, False, h0

    def doubled(self, z, t, h_try, level, c_last, peaks):
        """One step of ``H = h_try`` and two of ``H/2`` from ``z`` at ``t``, judged by
        :func:`~.step_error.estimate`: ``(ok, estimate, fine map, z₁, y₁, z₂, y₂)``."""
        n, half = self.n, 0.5 * h_try
        coarse = self.maps.get(h_try, level)
        fine = self.maps.get(half, None if level is None else level + 1)
        u = _NO_OFFSETS if self.offsets is None else self.offsets(h_try, half, t)
        if self.lines is None:
            zc, yc = coarse.step(z, u[0])
            z1, y1 = fine.step(z, u[1])
            z2, y2 = fine.step(z1, u[2])
        else:
            zc, yc, z1, y1, z2, y2 = self._with_lines(coarse, fine, z, t, h_try, u)
        ok = bool(np.isfinite(z2).all() and np.isfinite(zc).all())
        momenta = None
        if self.momenta is not None:
            reaction, mass = self.momenta
            momenta = (zc[n:], z2[n:], reaction.dot, mass)
        with np.errstate(divide="ignore", invalid="ignore"):
            est = estimate(
                np, z[:n], (zc[:n], z1[:n], z2[:n]), (yc[n:], y1[n:], y2[n:]), c_last, h_try,
                peaks, self.tolerances, self.hmax, momenta=momenta,
            )  # fmt: skip
        ok = ok and math.isfinite(float(est.err))
        return ok, est, fine, z1, y1, z2, y2

    def _with_lines(self, coarse, fine, z, t, h_try, u):
        """The try's three steps with the lines' incident waves read from the recorded
        ones one delay before each step's centre (:mod:`.sparse_lines`), set as the
        lines' offsets; the two halves' outgoing waves kept in :attr:`pending` until the
        try is accepted (a rejected try's never enter the history)."""
        lines, waves = self.lines
        half = 0.5 * h_try
        centres = (t + half, t + 0.5 * half, t + half + 0.5 * half)
        incident = [waves.at(c - lines.delay)[:, ::-1] for c in centres]  # e₁ = w₂, e₂ = w₁
        out, shifts = [], []
        for j, (found, h) in enumerate(((coarse, h_try), (fine, half), (fine, half))):
            z_from = z if j < 2 else out[1][0]  # the second half from the first's end
            uj, shift = self._line_offsets(found, u[j], h, incident[j])
            out.append(found.step(z_from, uj))
            shifts.append(shift)
        (zc, yc), (z1, y1), (z2, y2) = out
        self.pending = (
            (centres[1], lines.waves(z, z1, half, incident[1])),
            (centres[2], lines.waves(z1, z2, half, incident[2])),
            shifts[1],
        )
        return zc, yc, z1, y1, z2, y2

    def _line_offsets(self, found, u, h, e):
        """``u`` with the lines' rows for incident ``e`` (the layout of
        ``SparseAffineMap._moving``), and the residual's shift from the model's (whose
        lines' ``e`` is 0) for the verification."""
        lines = self.lines[0]
        r, p, d_r, d_p = lines.rows_at(h, e)
        shift = np.zeros(found.size)
        shift[lines.rows] = d_r
        driven = found.found.driven
        if driven and found.found.drivers is None:  # every row moves: add the change
            u = u.copy()
            u[lines.rows] += d_r
            u[found.size + lines.coords] += d_p
            return u, shift
        k = found.found.driver_rows.size if driven else 0
        return np.concatenate([u[:k], r, u[k:], p]), shift

    def accept_lines(self, corner=None) -> None:
        """Record the accepted try's two halves' outgoing waves (see :meth:`_with_lines`);
        ``corner``: the try's end when it landed on a breakpoint, where the waves may
        have a corner: their value there is recorded too, extrapolated along the line
        through the two halves' centres (the same smooth piece: every piece between two
        breakpoints holds at least one try), so that no later read interpolates across
        the corner (:mod:`.sparse_lines`)."""
        if self.lines is None:
            return
        waves = self.lines[1]
        (t1, w1), (t2, w2), _ = self.pending
        first = waves.k == 1
        waves.add(t1, w1)
        waves.add(t2, w2)
        if first:  # the right limit at t₀, on the first try's piece (Waves.start)
            waves.start(w1 - (w2 - w1) * ((t1 - waves.t[0]) / (t2 - t1)))
        if corner is not None:
            waves.add(corner, w2 + (w2 - w1) * ((corner - t2) / (t2 - t1)))

    def single(self, z, t, h, level):
        """One step of ``h`` from ``z`` at ``t``: ``(map, z_next, y)``."""
        found = self.maps.get(h, level)
        u = _NO_OFFSETS[0] if self.offsets is None else self.offsets.single(h, t)
        return (found, *found.step(z, u))

    def sample(self, found, z, y, t, steps: int) -> None:
        """Keep an accepted step of ``found`` for the verification (module doc)."""
        seen = found.accepted
        if seen % VERIFY_EVERY == 0 and found.sampled < VERIFY_MAX:
            shift = None if self.pending is None else self.pending[2]
            found.samples.append((z.copy(), y.copy(), t, shift))
            found.sampled += 1
            if len(found.samples) == VERIFY_BATCH:  # (a large circuit's samples are MBs)
                found.check()
        found.accepted = seen + steps


_NO_OFFSETS = np.zeros((3, 0))


def adaptive_sparse(
    system,
    q0,
    p0,
    *,
    t0: float,
    t_stop: float,
    controls: Controls,
    breakpoints=(),
    max_tries: int = 1_000_000,
    detect_rtol: float = 1e-12,
    verify_rtol: float = 1e-11,
    record=None,
    error: str = DEFAULT_ERROR,
    waves0=None,
) -> tuple[AdaptiveRun, SparseRun]:
    """March a linear interconnection ``system`` (packed, see
    :meth:`~diracvi.model.interconnect.InterconnectedSystem._packed`) from ``(q0, p0)``
    at ``t0`` to ``t_stop`` under the (+) midpoint rule with error-controlled steps, as
    :func:`diracvi.driver.adaptive.adaptive` does, on sparse step maps (module doc).

    Raises :class:`~diracvi.solvers.sparse_affine.NotSparseAffine` when the path does not
    apply (not an interconnection, not affine, switches, a step that fails its
    verification). Returns the :class:`AdaptiveRun` and a :class:`SparseRun`.

    ``record``: what receives the recorded steps — ``record(capacity, n, m)`` returns an
    object with ``start(t, z)``, ``add(t, h, z, μ)`` (each recorded step's end node, size,
    end state ``z = (q, p)`` and multipliers; ``z`` is not reused by the loop, so it may
    be kept) and ``arrays()`` → ``(t, h, q, p, μ)``. Default: every step kept
    (:class:`_Record`, O(n·steps)); a caller that needs only sampled waveforms passes one
    that forms them while the run steps (:mod:`diracvi.spice._stream`: O(n) memory).

    ``error``: ``"doubling"`` (three solves a try, module doc) or ``"truncation"`` (one
    solve a step, its local truncation error from the recorded past:
    :mod:`.sparse_truncation`).

    ``waves0``: a circuit with lossless transmission lines, per line the outgoing waves
    ``(w₁, w₂)`` of its ports before ``t0`` (shape ``(lines, 2)``; zero if not given).
    Their waves are recorded at the accepted steps' centres and read one delay later
    (:mod:`.sparse_lines`), which needs ``controls.hmax`` no longer than half the
    shortest delay and step doubling; the lines' corners (each breakpoint and ``t0``
    plus every sum of delays) are added to ``breakpoints``. The run's waves are
    ``SparseRun.lines``.
    """
    ensure_float64()
    if error not in ERRORS:
        raise ModelError(f"error={error!r}: the error control is one of {ERRORS}.")
    if not t_stop > t0:
        raise ModelError(f"t_stop={t_stop!r} must be after t0={t0!r}.")
    try:
        switches = bool(events.relays(system))
    except ModelError:  # a packed system with switches (it cannot carry their states)
        switches = True
    if switches:
        raise NotSparseAffine("the circuit has switches (discrete states)")
    rule = get_rule("midpoint")
    n = system.n
    q = np.asarray(q0, dtype=np.float64).reshape(n).copy()
    p = np.asarray(p0, dtype=np.float64).reshape(n).copy()
    hmax, rtol = float(controls.hmax), float(controls.rtol)
    top = 2.0 * hmax  # a try of H records two steps of H/2 ≤ hmax
    lines = _lines_of(system, rule, error, hmax, waves0, float(t0))
    if lines is not None:
        breakpoints = line_breakpoints(breakpoints, lines[0].delay, float(t0), float(t_stop))
    maps = _Maps(
        system, rule, q, p, float(t0), detect_rtol, verify_rtol, top,
        None if lines is None else lines[0],
    )  # fmt: skip
    first = maps.get(*_level(min(controls.h_first, top), top))
    m = first.size - n
    atol_q = np.broadcast_to(np.asarray(controls.atol_q, np.float64), (n,))
    atol_v = np.broadcast_to(np.asarray(controls.atol_v, np.float64), (n,))
    atol_m = np.broadcast_to(np.asarray(controls.atol_m, np.float64), (m,))
    driven = bool(system.time_dependent)
    breaks = [float(b) for b in sorted(breakpoints) if t0 < b < t_stop]
    offsets = _Offsets(system, maps, rule) if driven else None
    tolerances = (SAFETY, rtol, atol_q, atol_v, atol_m)
    # the nodal momenta judged (Controls.inertia): their lag is the constraint impulse
    # Aᵀc (constant: the circuit is linear), the multiplier columns of the map's impulse
    # rows
    mass = _inertia(controls, n)
    momenta = None if mass is None else (first.found.imp[:, n:].tocsr(), mass)
    tries = _Tries(maps, offsets, n, tolerances, hmax, top, momenta, lines)
    # the recorded steps, written in place (a guess of the count, grown if exceeded;
    # np.empty's pages are committed only when written, so the guess costs nothing)
    capacity = 2 * math.ceil((t_stop - t0) / hmax) + 4 * len(breaks) + 16
    rec = (_Record if record is None else record)(capacity, n, m)
    z = np.concatenate([q, p])
    rec.start(float(t0), z)
    march = _doubling if error == "doubling" else truncation_march
    count, rejected, status = march(
        tries, rec, z, float(t0), float(t_stop), breaks, controls, max_tries, m
    )
    worst = _verify(maps)
    if not worst <= verify_rtol:
        raise NotSparseAffine(f"a step was off by {worst:.1e} relative (not affine)")
    run = AdaptiveRun(*rec.arrays(), count, rejected, status, None, DESCRIBE)
    return run, SparseRun(
        maps.builds, maps.factorizations, tuple(sorted(maps.levels)), bool(maps.fit),
        tries.landings, lines,
    )  # fmt: skip


def _lines_of(system, rule, error, hmax, waves0, t0):
    """``(LineOffsets, Waves)`` of a system with lossless lines, else None; refuses what
    the lines' history cannot carry (:mod:`.sparse_lines`)."""
    if not incidents(system):
        return None
    found = LineOffsets(system, rule)
    need_doubling(error)
    limit = line_hmax(found.delay)
    if hmax > limit * (1.0 + 1e-12):
        raise ModelError(
            f"controls.hmax={hmax:g} s: transmission lines {', '.join(found.names)} read "
            f"their waves one delay back, known only for steps up to half the shortest "
            f"delay. Fix: hmax ≤ {limit:g} s (a TMAX no longer than that)."
        )
    w0 = np.zeros((len(found), 2)) if waves0 is None else np.asarray(waves0, np.float64)
    if w0.shape != (len(found), 2):
        raise ModelError(f"waves0 of shape {w0.shape}: one (w1, w2) per line, ({len(found)}, 2).")
    return found, Waves(t0, w0, tol=1e-9 * float(np.min(found.delay)))


def _doubling(tries: _Tries, rec, z, t, t_stop, breaks, controls, max_tries, m):
    """Step doubling (module doc): ``(tries, rejected, status)``."""
    n, top, hmin = tries.n, tries.top, float(controls.hmin)
    h = min(float(controls.h_first), top)
    ib = 0
    c_last = np.zeros(m)  # the given p0 carries no lag: c_{−1} = 0
    peaks = (np.abs(z[:n]), np.zeros(n), np.zeros(m))
    if tries.momenta is not None:
        peaks = (*peaks, np.zeros(n))  # the nodal momenta's running peak
    count = rejected = 0
    status = OK
    while t < t_stop:
        if count >= max_tries:
            status = TOO_MANY
            break
        target = min(breaks[ib], t_stop) if ib < len(breaks) else t_stop
        h_try, level, land, h0 = tries.plan(h, target - t, top)
        if not (h_try > 0.0 and t + h_try > t):  # a try that cannot advance time
            status = TOO_SMALL  # (a breakpoint behind t, or h below t's resolution)
            break
        half = 0.5 * h_try
        ok, est, fine, z1, y1, z2, y2 = tries.doubled(z, t, h_try, level, c_last, peaks)
        count += 1
        err = float(est.err)
        accept = ok and err <= 1.0
        h_next = h_try * growth_of(err) if ok else 0.25 * h_try  # (growth, on a float)
        if accept and h_try < h0:  # a landing step says little about the next one
            h_next = max(h_next, h0)
        if accept:
            t_new = target if land else t + half + half
            tries.accept_lines(target if land else None)
            rec.add(t + half, half, z1, y1[n:])
            rec.add(t_new, half, z2, y2[n:])
            tries.sample(fine, z, y1, t, 2)
            t, z = t_new, z2
            c_last = est.c2
            peaks = (est.q_peak, est.v_peak, est.m_peak)
            if est.p_peak is not None:
                peaks = (*peaks, est.p_peak)
            if land and ib < len(breaks) and target == breaks[ib]:
                ib += 1
        else:
            rejected += 1
        h = min(h_next, top)
        if not accept and h_next < hmin:
            status = TOO_SMALL if ok else FAILED_SOLVE
            break
    return count, rejected, status
