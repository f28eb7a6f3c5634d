r"""The moving offsets of the sparse path's steps, computed ahead of the tries.

A linear circuit's step from ``z`` at ``t`` is ``J_x(h) y = −(r₀(t; h) + J_z(h) z)``
(:mod:`diracvi.solvers.sparse_affine`): the offsets ``r₀``, ``P₀`` (the driven parts'
rows, or every row) move with ``t`` and ``h``. They come from one compiled program
vmapped over ``(h, t)`` pairs (``h`` is data: no program per step size), and one call
serves the tries that follow at the same size (:class:`_Offsets`), for
:mod:`diracvi.driver.adaptive_sparse` and :mod:`diracvi.driver.sparse_truncation`.
"""

from __future__ import annotations

import numpy as np

from ..solvers.sparse_affine import OFFSETS_PAIRS, _offsets

#: tries whose offsets one call of the offsets program computes (see :class:`_Offsets`),
#: fewer when a try's offsets are many numbers (every row, for a circuit with many
#: sources): a call's output stays within :data:`AHEAD_NUMBERS`. Three pairs a try: the
#: call's shape is the one the map's build checks the drivers with (one program, 64 tries)
AHEAD = OFFSETS_PAIRS // 3
AHEAD_NUMBERS = 1 << 18


class _Offsets:
    """The moving offsets ``u`` (``SparseAffineMap._augmented``) of a try's steps — a
    doubled try's sizes ``(H, H/2, H/2)`` at times ``(t, t, t + H/2)``, or one step's
    (:meth:`single`; each call then serves three times the steps) — from the compiled program,
    whose arrays are gathered once (flattening the arguments at every try cost more than
    the program's run); each call passes only the ``(h, t)`` pairs.

    **Ahead of the tries.** A call computes the offsets of :data:`AHEAD` tries at once:
    this one, and the tries that follow if each is accepted at the same size (times
    ``t, t + H/2 + H/2, …``, the loop's own arithmetic, so the keys match bit for bit).
    A later try at one of those ``(H, t)`` reads its row; any other (a rejection, a new
    size, a landing) starts a new call. On the 1000-stage ladder 3445 of 3471 tries
    follow the one before: one call per 64 tries instead of one per try, whose dispatch
    (≈ 0.3–0.5 ms each) was a sixth of the loop's time. The values are the program's
    own, pair by pair (it is vmapped over the pairs)."""

    def __init__(self, system, maps, rule):
        self.system, self.maps, self.rule = system, maps, rule
        self.mode = self.call = None
        self.table: dict = {}  # (kind, H, t) → the try's offsets (one row a step)
        self.calls = 0

    def _args(self, use):
        return (None, self.maps.drivers, self.rule, "plus") if use else (
            self.system, None, self.rule, "plus")  # fmt: skip

    def __call__(self, h_try, half, t):
        """A doubled try's ``(3, width)`` offsets: steps ``(H, H/2, H/2)`` at
        ``(t, t, t + H/2)``; ahead, the tries at ``t + H/2 + H/2, …``."""
        return self._rows(
            ("doubled", h_try, t), (h_try, half, half), lambda s: (s, s, s + half),
            lambda s: s + half + half,
        )  # fmt: skip

    def single(self, h, t):
        """One step's ``(width,)`` offsets (:mod:`.sparse_truncation`): size ``h`` at
        ``t``; ahead, the steps at ``t + h, …``."""
        return self._rows(("single", h, t), (h,), lambda s: (s,), lambda s: s + h)[0]

    def _rows(self, key, sizes, times, advance):
        use = self.maps.drivers is not None  # (the drivers alone: a few small parts)
        if self.mode is use:
            hit = self.table.get(key)
            if hit is not None:
                return hit
        else:
            self.table = {}
        # one call is always 3·ahead pairs (a program per shape: no second compile)
        width = len(sizes)
        starts = [key[2]]  # this try's time and the next ones', each accepted at this size
        for _ in range(3 * self._ahead(use) // width - 1):
            starts.append(advance(starts[-1]))  # the loop's own arithmetic, bit for bit
        ahead = len(starts)
        hs = np.tile(sizes, ahead)
        ts = np.array([times(s) for s in starts]).ravel()
        if self.mode is not use:
            self._prepare(use, hs, ts)
        r, pm = self.call(hs, ts)
        self.calls += 1
        u = np.concatenate([np.asarray(r), np.asarray(pm)], axis=1).reshape(ahead, width, -1)
        self.table = {(key[0], key[1], s): u[j] for j, s in enumerate(starts)}
        return u[0]

    def _ahead(self, use) -> int:
        """Tries per call: :data:`AHEAD`, fewer if a try's offsets are many numbers."""
        if use:  # (a few small parts' rows)
            return AHEAD
        per_try = 3 * (2 * self.system.n + self.system.m)  # every row and coordinate
        return int(max(1, min(AHEAD, AHEAD_NUMBERS // per_try)))

    def _prepare(self, use, hs, ts) -> None:
        import equinox as eqx

        args = self._args(use)
        compiled, leaves = _offsets.program(*args, hs, ts)
        if compiled is None:
            self.call = lambda a, b: _offsets(*args, a, b)
        else:
            arrays = [leaf for leaf in leaves if eqx.is_array(leaf)][:-2]
            self.call = lambda a, b: compiled(*arrays, a, b)
        self.mode = use
