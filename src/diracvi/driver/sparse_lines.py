r"""Lossless transmission lines on the sparse path's variable steps: the waves they read.

A line (:mod:`diracvi.components.tline`) is two resistive-like ports whose sources are
the other port's outgoing wave one delay earlier, ``e₁(t) = w₂(t − T_D)``,
``e₂(t) = w₁(t − T_D)`` with ``w = v + Z₀ i``. On the fixed step (:mod:`.delay`) the
waves sit on a regular grid of centres; here each accepted step's centre is wherever
the step control put it, so the history is a growing pair of host arrays
``(t_centre, w)`` (:class:`Waves`), appended once a try is accepted — a rejected try's
waves never enter it.

**What is recorded.** A midpoint step's port law is ``V = Z₀ Δq/h + e`` at its centre,
so an accepted step records per port ``w = 2 Z₀ Δq/h + e`` at ``t_k + h/2``: second
order in ``h``, as the step (its ``Δq/h`` is the current at the centre to ``O(h²)``).

**What is read: linear interpolation between the two recorded centres about
``t_c − T_D``.** On non-uniform centres a line through the two neighbours is exact
for a linear wave and off by at most ``Δ²/8 · max|w''|`` (``Δ`` the gap between the
two centres) for a smooth one — second order on any spacing, with no ratio of
neighbouring steps in the constant, where a parabola through three unequal gaps has
one. It is a convex combination of the two recorded values, so at a wave's corner (a
PULSE's edge, or its echo) it cannot overshoot; a parabola through three values
across a corner does (ngspice's ``traload.c`` takes the parabola). Before ``t₀`` the
wave is the initial one (``w₀``: from the operating point, or ``IC=`` under ``UIC``),
recorded as a point at ``t₀``.

**Corners are recorded too.** The centres about a corner lie on two different smooth
pieces, and a line between them starts the wave's change early, at the centre before
the corner: on ``TRANSLINE/transline`` the far port rose from 0.13 ns before its echo
(0.17 of the peak off ngspice). So where a try lands on a breakpoint — a corner, below
— the wave's value there is recorded as well, extrapolated along the line through
that try's two halves' centres: they lie on the piece that ends there (a try never
crosses a breakpoint, and each records two halves), and a linear extrapolation over a
quarter of the try is second order on a smooth piece and exact on a linear one. The
waves are continuous at a corner (a resistive port sees its sources' values, which
are), so one value serves both sides; no read then interpolates across a corner, and
that deck agrees to 1.9e-11 of its peak.

**Known before the step.** A read past the last recorded centre would be an
extrapolation. A doubled try of ``H`` from ``t`` reads at ``t + H/2`` (the coarse
step) and ``t + H/4``, ``t + 3H/4`` (the two halves, each ``≤ h_max``) less ``T_D``,
and the last recorded centre is ``t − h_last/2``: every read is known when
``3H/4 + h_last/2 ≤ T_D``, which ``h_max ≤ T_D/2`` guarantees (:func:`line_hmax`);
a read that would extrapolate raises instead (it cannot happen under that bound).

**Breakpoints** (:func:`line_breakpoints`). In a linear circuit the node values have
a corner only where what drives them has one: a source's corner, or the corner of a
line's incident wave — which is the other port's outgoing wave, corners and all, one
delay later. The corners are therefore the closure of the sources' corners (and of
``t₀``, where the run's driving starts) under ``t → t + T_D`` of every line, up to
TSTOP: ``k·T_D`` after each for a single line's reflections, and every sum of delays
for several. That set is known before the run, so it is landed exactly as the
sources' corners are (and the waveforms are resampled without interpolating across
one). ngspice finds the same corners from the waves themselves (``traacct.c``: a
breakpoint one delay after a recorded point where a port wave's slope changed by more
than ``REL·max(|slope|) + ABS``, both 1 by default, so in V/s — every visible corner of
a nanosecond edge): the closure here needs no threshold, and sets no breakpoint that
the circuit could not produce. It is bounded by :data:`MAX_BREAKPOINTS`.

**Offsets.** A line's ``e`` enters its own two rows of the step's residual and
momentum line affinely, with a coefficient that depends on ``h`` only (the rule's
quadrature of ``F = −(Z₀ q̇ + e)``): :class:`LineOffsets` evaluates those rows of
each line at ``e = 0`` and at the unit vectors, once per step size (one compiled
program, ``h`` as data), and a step's values are then a product on the host.

**Energy.** As on the fixed step (:mod:`diracvi.components.tline`), the work on a
port over a step is exactly ``h (a² − b²)/Z₀`` with ``a = Z₀ i + e/2`` the recorded
half-wave and ``b = e/2`` the incident one, so over a run ``Σ work = Σ h(a₁² + a₂²)/Z₀
− Σ h(b₁² + b₂²)/Z₀``. The incident energy is the recorded energy one delay earlier
when ``b`` is read from the recorded ``a`` without error; with interpolation each
incident value is off by the interpolation's error, ``O(Δ² w'')`` between corners
and exact where the wave is linear, so the balance closes to the interpolation's
error (``tests/test_tline.py`` measures it).
"""

from __future__ import annotations

import numpy as np

from ..errors import ModelError

#: the most breakpoints the lines' closure may add (beyond: refused, naming the fix)
MAX_BREAKPOINTS = 200_000


class Waves:
    """The recorded outgoing waves of every line's ports: centre times ``t`` (growing,
    strictly increasing) and values ``w`` of shape ``(lines, 2)`` per centre, the first
    at ``t₀``; before ``t₀``, the initial waves ``w₀``.

    At ``t₀`` itself the recorded value is the waves' right limit once the first try is
    accepted (:meth:`start`): under ``UIC`` the state at ``t₀`` need not be the one the
    ``IC=`` waves describe (a line released from its initial condition: ``w`` jumps
    from ``w₀`` at ``t₀``), and a read just after ``t₀ + T_D`` belongs to the waves
    after the jump."""

    def __init__(self, t0: float, w0, tol: float, capacity: int = 1024):
        w0 = np.asarray(w0, dtype=np.float64)
        self.tol = tol  # a read this far past the last centre is round-off, not a gap
        self.lines = w0.shape[0]
        self.t = np.empty(capacity)
        self.w = np.empty((capacity, self.lines, 2))
        self.t[0], self.w[0] = t0, w0
        self.before = w0.copy()
        self.k = 1

    def add(self, t: float, w) -> None:
        if not t > self.t[self.k - 1]:
            raise ModelError(
                f"a line's wave recorded at t = {t!r}, not after the last one at "
                f"{self.t[self.k - 1]!r} (the centres must increase)."
            )
        if self.k >= len(self.t):
            self.t = np.concatenate([self.t, np.empty_like(self.t)])
            self.w = np.concatenate([self.w, np.empty_like(self.w)])
        self.t[self.k], self.w[self.k] = t, w
        self.k += 1

    def start(self, w) -> None:
        """Set the value at ``t₀`` (the right limit there; see the class doc)."""
        self.w[0] = w

    @property
    def last(self) -> float:
        return float(self.t[self.k - 1])

    def at(self, s) -> np.ndarray:
        """The waves at times ``s`` (one per line, shape ``(lines,)``): ``(lines, 2)``,
        each line's two ports linearly interpolated between the recorded centres about
        its ``s`` (the initial wave at or before ``t₀``). Raises if an ``s`` is after the
        last recorded centre (that would be an extrapolation)."""
        s = np.asarray(s, dtype=np.float64)
        k = self.k
        t = self.t[:k]
        late = s > t[-1] + self.tol
        if np.any(late):
            j = int(np.argmax(late))
            raise ModelError(
                f"a line's wave read at t = {s[j]:.6g} s, after the last recorded step centre "
                f"({t[-1]:.6g} s): the step is longer than the line's delay allows. Fix: a "
                "TMAX no longer than half the shortest delay (line_hmax)."
            )
        right = np.clip(np.searchsorted(t, s, side="right"), 1, k - 1) if k > 1 else None
        out = np.empty((self.lines, 2))
        for j in range(self.lines):
            if s[j] < t[0]:
                out[j] = self.before[j]
                continue
            if k == 1:
                out[j] = self.w[0, j]
                continue
            r = int(right[j])
            t_a, t_b = t[r - 1], t[r]
            f = min(1.0, max(0.0, (s[j] - t_a) / (t_b - t_a)))
            out[j] = (1.0 - f) * self.w[r - 1, j] + f * self.w[r, j]
        return out

    def arrays(self):
        """``(t, w)``: the recorded centres (the initial point at ``t₀`` first)."""
        return self.t[: self.k].copy(), self.w[: self.k].copy()


def line_hmax(delays) -> float:
    """The longest recorded step for which every read of a doubled try is known (module
    doc): half the shortest delay."""
    return 0.5 * float(np.min(delays))


def line_breakpoints(corners, delays, t0: float, t_stop: float) -> np.ndarray:
    """The closure of ``{t₀} ∪ corners`` under ``t → t + T_D`` for every delay, within
    ``(t₀, t_stop)`` (module doc), points closer than ``10⁻⁹·(t_stop − t₀)`` merged."""
    span = t_stop - t0
    tol = 1e-9 * span
    steps = sorted({float(d) for d in delays})
    seeds = sorted({float(t0), *(float(c) for c in corners if t0 <= c < t_stop)})
    found: list[float] = []
    frontier = seeds
    seen = set()

    def key(x):
        return round((x - t0) / tol)

    for x in seeds:
        seen.add(key(x))
    while frontier:
        nxt = []
        for x in frontier:
            for d in steps:
                y = x + d
                if y >= t_stop - tol:
                    break
                kk = key(y)
                if kk in seen or kk - 1 in seen or kk + 1 in seen:
                    continue
                seen.add(kk)
                nxt.append(y)
        found.extend(nxt)
        if len(found) > MAX_BREAKPOINTS:
            raise ModelError(
                f"the lines' delays {steps} put more than {MAX_BREAKPOINTS} corners (every "
                f"sum of delays after each source corner) before TSTOP = {t_stop:g} s. Fix: "
                "a fixed step (dt=, --dt) no longer than the shortest delay."
            )
        frontier = nxt
    out = np.array(sorted(set(found) | {c for c in seeds if c > t0}), dtype=np.float64)
    return out


class LineOffsets:
    """The lines' rows of a step's offsets (the residual ``r₀`` and momentum line ``P₀``
    at the zero state) as functions of the step size ``h`` and the incident ``e``:
    ``r(h, e) = r(h, 0) + D_r(h) e``, ``P(h, e) = P(h, 0) + D_p(h) e``, the coefficients
    evaluated once per ``h`` from the lines' own parts (one compiled program).

    ``rows``: the lines' rows of the residual; ``coords``: their coordinates (the
    momentum rows); ``q_index`` ``(lines, 2)``: each port's branch charge; ``z0``,
    ``delay`` per line."""

    def __init__(self, system, rule):
        from ..solvers.sparse_pattern import _structure
        from .delay import incidents

        self.rule = rule
        offsets, mu_start, mu_sizes, *_ = _structure(system)
        packing = getattr(system, "_packing", None)
        if packing is None:
            groups = [[i] for i in range(len(system.subsystems))]
        else:
            groups = [[int(i) for i in m] for m in packing.tables.members]
        members, index = [], []
        for group in groups:
            if not incidents.leaves(system._member(group[0])):
                continue
            for i in group:
                members.append(system._member(i))
                index.append(i)
        self.members = tuple(members)
        rows, coords, q_index, z0, delay = [], [], [], [], []
        for sub, i in zip(members, index, strict=True):
            (inc,) = incidents.leaves(sub)
            own = np.arange(offsets[i], offsets[i + 1])
            coords.append(own)
            rows.append(np.concatenate([own, np.arange(mu_start[i], mu_start[i] + mu_sizes[i])]))
            q_index.append([own[sub.coords.index(c)] for c in inc.coordinates])
            z0.append(inc.z0)
            delay.append(inc.delay)
        self.rows = np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64)
        self.coords = np.concatenate(coords).astype(np.int64) if coords else np.zeros(0, np.int64)
        self.q_index = np.asarray(q_index, dtype=np.int64).reshape(-1, 2)
        self.z0 = np.asarray(z0, dtype=np.float64)
        self.delay = np.asarray(delay, dtype=np.float64)
        self.names = tuple(getattr(s, "name", "line") for s in members)
        self._cache: dict = {}
        self._program = None

    def __len__(self) -> int:
        return len(self.members)

    def _coefficients(self, h: float):
        hit = self._cache.get(h)
        if hit is not None:
            return hit
        if self._program is None:
            self._program = _coefficient_program(self.members, self.rule)
        r, p = self._program(np.float64(h))
        r, p = np.asarray(r), np.asarray(p)  # (1 + 2L, rows), (1 + 2L, coords)
        out = (r[0], (r[1:] - r[0]).T.copy(), p[0], (p[1:] - p[0]).T.copy())
        if len(self._cache) > 64:
            self._cache.pop(next(iter(self._cache)))
        self._cache[h] = out
        return out

    def rows_at(self, h: float, e) -> tuple[np.ndarray, np.ndarray]:
        """``(r, P)``: the lines' rows of the offsets of a step of ``h`` with incident
        ``e`` (shape ``(lines, 2)``), and their change from ``e = 0``."""
        r0, d_r, p0, d_p = self._coefficients(float(h))
        flat = np.asarray(e, dtype=np.float64).ravel()
        return r0 + d_r @ flat, p0 + d_p @ flat, d_r @ flat, d_p @ flat

    def waves(self, z_from, z_to, h: float, e) -> np.ndarray:
        """The outgoing waves ``w = 2 Z₀ Δq/h + e`` of a step ``z_from → z_to`` of size
        ``h`` with incident ``e``: ``(lines, 2)``."""
        i = (z_to[self.q_index] - z_from[self.q_index]) / h
        return 2.0 * self.z0[:, None] * i + e


def _coefficient_program(members, rule):
    """``h ↦ (r, P)``: the lines' own rows at the zero state with ``e = 0`` and with
    each unit ``e`` (``1 + 2·lines`` rows each), one compiled program."""
    import jax
    import jax.numpy as jnp

    from ..solvers.sparse_affine import _own_offsets
    from .delay import with_incident

    count = len(members)
    basis = jnp.concatenate([jnp.zeros((1, 2 * count)), jnp.eye(2 * count)])

    @jax.jit
    def run(h):
        def one(flat):
            e = flat.reshape(count, 2)
            pieces = [
                _own_offsets(with_incident(sub, e[j : j + 1]), rule, "plus", h, 0.0)
                for j, sub in enumerate(members)
            ]
            return (
                jnp.concatenate([r for r, _ in pieces]),
                jnp.concatenate([p for _, p in pieces]),
            )

        return jax.vmap(one)(basis)

    return run


def need_doubling(error: str) -> None:
    """Lines are carried by step doubling's loop only (:mod:`.adaptive_sparse`)."""
    if error != "doubling":
        raise ModelError(
            f"error={error!r}: a circuit with transmission lines is stepped with step "
            "doubling only (its waves are recorded from each accepted try's two halves). "
            "Fix: step_error='doubling' (the default)."
        )


__all__ = ["MAX_BREAKPOINTS", "LineOffsets", "Waves", "line_breakpoints", "line_hmax"]
