r"""A variable-step run's signals, formed step by step, and sampled while the run steps.

Each recorded step ``k`` of size ``h_k`` gives the circuit's signals at its centre
(:mod:`._resample`):

    φ_{k+½} = −c_k/h_k  with  c_k = 2μ_k − c_{k−1}  (c_{−1} = 0)    (node potentials),
    i_{k+½} = (q_{k+1} − q_k)/h_k                                       (branch currents),

plus XSPICE's MMF nodes, sums of winding currents (:mod:`._magnetic`). Both need only the
step before: :class:`Layout` forms them from a whole run's records (:func:`step_signals`)
or one step at a time (:class:`StreamRecord`).

**Why stream.** A run that keeps every state holds ``(2n + m)·steps`` numbers and its
signals ``S·steps`` more: 1.2 GB for a 1000-stage ladder, 45 GB projected at 10⁵ stages.
The TSTEP grid's values need only the four step centres around each output time
(:class:`~._resample.Sampler`), so :class:`StreamSampler` fills the grid chunk by chunk
from the rows as they come and keeps only the last few: O(S) working memory beside the
output. It calls the same :class:`~._resample.Sampler` on the same centres, so the grid
is the one the whole-run sampler gives, bit for bit (``tests/test_stream.py``).

:class:`StreamRecord` is the recorder :func:`~diracvi.driver.adaptive_sparse.adaptive_sparse`
calls: it streams the grid of the saved vectors (``.save``, else ngspice's default set:
node voltages, source and inductor currents — what ngspice itself keeps) always, and
keeps the whole run too — states, multipliers and
step-centred signals, for ``result.at(times)``, ``result.internal`` and
``result.trajectory.q`` — when asked (``internal=True``) or while they stay under
:data:`KEEP_MAX` numbers (every small deck: nothing changes for them).
"""

from __future__ import annotations

import numpy as np

from ._magnetic import potentials
from ._resample import COLUMNS, Sampler, Signals, interval_of, step_potentials
from ._save import differences

#: a run's records and signals are kept (besides the streamed grid) up to this many
#: numbers (128 MB: a 100-stage ladder's 6940 steps fit, a 1000-stage one's do not);
#: beyond, only the grid is (unless ``internal=True``)
KEEP_MAX = 2**24

#: rows gathered before the grid is filled from them (a few MB for a large circuit)
CHUNK = 128

#: signals are formed this many columns at a time (whole gathers of a run's records
#: were temporaries as large as the signals themselves)
SIGNAL_COLUMNS = 512


class Layout:
    """Where each signal comes from: the KCL rows of the node potentials (``rows``, into
    ``μ``), the coordinates of the branch currents (``cols``, into ``q``), the names
    (``v(<node>)`` then ``i(<element>)``), and the MMF nodes added from the currents."""

    def __init__(self, netlist):
        assembly = netlist.assembly
        # (dicts of positions: list.index per node was quadratic in the circuit's size)
        row_of = {name: j for j, name in enumerate(netlist.system.constraint_names)}
        self.rows = np.array(
            [row_of[assembly.kcl_rows[node]] for node in assembly.nodes], dtype=np.int64
        )
        index = {c: j for j, c in enumerate(netlist.system.coords)}
        self.display = netlist.display  # ngspice's names of parts in subcircuit instances
        currents = list(assembly.currents.items())
        self.cols = np.array([index[coord] for _, coord in currents], dtype=np.int64)
        names = [f"v({node})" for node in assembly.nodes]
        names += [f"i({self.display.get(label, label)})" for label, _ in currents]
        self.base = names
        self.table = netlist.potentials
        self.vd = getattr(netlist, "differences", {})  # .probe vd(…) (spice/_save.py)
        self.extra = []
        if self.table or self.vd:
            base = {n: np.zeros(1) for n in names}
            more = differences(potentials(dict(base), self.table, self.display), self.vd)
            self.extra = [n for n in more if n not in base]  # (they add to their dict)
        self.names = names + self.extra

    def with_extra(self, values: np.ndarray) -> np.ndarray:
        """``values`` (K, base signals) with the MMF nodes' and the ``.probe`` voltage
        differences' columns appended."""
        if not self.extra:
            return values
        base = {n: values[:, j] for j, n in enumerate(self.base)}
        more = differences(potentials(dict(base), self.table, self.display), self.vd)
        return np.column_stack([values, *(more[n] for n in self.extra)])


def step_signals(netlist, march) -> Signals:
    """``v(<node>)`` and ``i(<element>)`` at the step centres of a whole run."""
    lay = Layout(netlist)
    values = np.empty((len(march.h), len(lay.base)))
    count = len(lay.rows)
    for a in range(0, count, SIGNAL_COLUMNS):  # (a few columns at a time: see above)
        b = min(a + SIGNAL_COLUMNS, count)
        step_potentials(march.mu[:, lay.rows[a:b]], march.h, out=values[:, a:b])
    for a in range(0, len(lay.cols), SIGNAL_COLUMNS):
        part = lay.cols[a : a + SIGNAL_COLUMNS]
        out = values[:, count + a : count + a + SIGNAL_COLUMNS]
        np.subtract(march.q[1:, part], march.q[:-1, part], out=out)
        out /= march.h[:, None]
    return Signals(lay.names, lay.with_extra(values))


class StreamSampler:
    """The resampling of :class:`~._resample.Sampler` onto sorted ``times``,
    fed step rows in order (:meth:`feed`), finished by :meth:`finish`.

    An output time ``τ`` in interval ``[b_i, b_{i+1}]`` is sampled from the four step
    centres around it within that interval; it is *settled* — its centres and weights
    final — once its interval has closed (a later step lies beyond ``b_{i+1}``) or four
    centres of its interval lie at or after the second before ``τ``. Settled times are
    sampled by a :class:`~._resample.Sampler` over the kept rows; rows before the second
    one preceding the first unsettled time are dropped (at least the last four are
    kept: the end of an interval extrapolates from its last four)."""

    def __init__(self, bounds, times, width: int):
        self.bounds = np.asarray(bounds, dtype=np.float64)
        self.times = np.asarray(times, dtype=np.float64)
        self.out = np.empty((len(self.times), width))
        self.done = 0  # output times sampled so far
        self.t = None  # the kept rows' nodes (rows + 1), sizes and values
        self.h = np.empty(0)
        # the kept values live in one buffer reused from feed to feed (a fresh array of
        # a chunk's rows at every feed was MBs of new pages a chunk on a large circuit:
        # a tenth of a 1000-stage ladder's loop); ``values`` is a view of its first rows
        self._buffer = np.empty((0, width))
        self.values = self._buffer

    def start(self, t0: float) -> None:
        self.t = np.array([t0])

    def feed(self, t_next, h, values) -> None:
        """Rows of consecutive steps: their end nodes, sizes and signal values."""
        self.t = np.concatenate([self.t, t_next])
        self.h = np.concatenate([self.h, h])
        have, more = len(self.values), len(values)
        if have + more > len(self._buffer):
            grown = np.empty((2 * (have + more), self._buffer.shape[1]))
            grown[:have] = self.values
            self._buffer = grown
        self._buffer[have : have + more] = values
        self.values = self._buffer[: have + more]
        self._flush(final=False)

    def finish(self) -> np.ndarray:
        """The output (times × signals), every time sampled."""
        if len(self.h):
            self._flush(final=True)
        return self.out

    def _flush(self, final: bool) -> None:
        pending = self.times[self.done :]
        if not len(pending) or not len(self.h):
            return
        sampler = Sampler(self.t, self.h, self.bounds)
        n = len(self.h)
        at = np.searchsorted(sampler.centres, pending)
        if final:
            ready = len(pending)
        else:
            count = len(self.bounds) - 1
            interval = interval_of(self.bounds, pending)
            last = sampler.interval[-1]
            lo = sampler.first[np.minimum(interval, count)]
            closed = interval < last
            within = (interval == last) & (np.maximum(at - 2, lo) + 4 <= n)
            settled = closed | within
            ready = int(np.argmin(settled)) if not np.all(settled) else len(pending)
        if ready:
            index, w = sampler.weights(pending[:ready])
            block = self.out[self.done : self.done + ready]
            for a in range(0, block.shape[1], COLUMNS):
                block[:, a : a + COLUMNS] = sampler.apply(self.values[:, a : a + COLUMNS], index, w)
            self.done += ready
        if final or self.done == len(self.times):
            return
        keep = max(0, min(int(at[ready]) - 2, n - 4))
        if keep:
            self.t, self.h = self.t[keep:], self.h[keep:]
            rest = len(self.values) - keep  # (a few rows: moved to the buffer's front)
            self._buffer[:rest] = self._buffer[keep : keep + rest].copy()
            self.values = self._buffer[:rest]


class StreamRecord:
    """The recorder of a sparse variable-step run (see the module doc): each step's
    signals formed as it is recorded and streamed onto ``grid``; the whole run kept too
    while it fits :data:`KEEP_MAX` numbers, or always with ``keep=True``.

    Call with ``(capacity, n, m)`` as :func:`~diracvi.driver.adaptive_sparse.adaptive_sparse`
    does (:meth:`__call__`); afterwards :attr:`grid_values` holds the grid's values of
    the saved vectors (:attr:`names`) and :attr:`kept` says whether the records are
    whole (then every signal can be formed from them, as for a small circuit)."""

    def __init__(
        self, netlist, bounds, grid, keep=False, keep_max: int | None = None, least: int = 0
    ):
        self.layout = Layout(netlist)
        self.bounds, self.grid = bounds, grid
        # the grid is formed for the saved vectors only (.save, else ngspice's default
        # set: node voltages, source and inductor currents), as ngspice keeps its plot
        saved = {key for _, key in netlist.vectors} or set(self.layout.names)
        self.select = np.array(
            [j for j, name in enumerate(self.layout.names) if name in saved], dtype=np.int64
        )
        self.names = [self.layout.names[j] for j in self.select]
        lay, nodes = self.layout, len(self.layout.rows)
        if lay.extra:  # the MMF nodes are sums of currents: every signal is formed
            self.rows_of, self.cols_of = lay.rows, lay.cols
            self.pick = self.select
        else:  # the saved ones only (ngspice's default set leaves out C and R currents)
            self.rows_of = lay.rows[self.select[self.select < nodes]]
            self.cols_of = lay.cols[self.select[self.select >= nodes] - nodes]
            self.pick = None
        self.keep, self.keep_max = keep, KEEP_MAX if keep_max is None else keep_max
        self.kept = True
        # ``least``: steps the run records at the fewest (span / TMAX: no step is longer).
        # A run that cannot fit is never kept: writing its first rows into buffers of
        # ~KEEP_MAX numbers and dropping them cost 0.2 s of page faults on the
        # 1000-stage ladder
        self.least = least
        self.grid_values = None

    def __call__(self, capacity: int, n: int, m: int):
        from ..driver.adaptive_sparse import _Record

        self.n = n
        self.per_step = 2 * n + m + len(self.layout.names)
        self.kept = self.keep or self.least * self.per_step <= self.keep_max
        self.full = _Record(capacity, n, m) if self.kept else None
        self.sampler = StreamSampler(self.bounds, self.grid, len(self.select))
        width = len(self.rows_of) + len(self.cols_of)
        self.rows_t, self.rows_h = np.empty(CHUNK), np.empty(CHUNK)
        self.rows = np.empty((CHUNK, width))
        self.count = 0  # rows in the chunk
        self.steps = 0
        self.t_nodes = [None]  # every node and size (O(steps)): the run's own times
        self.h_all = []
        return self

    def start(self, t, z) -> None:
        if self.kept:
            self.full.start(t, z)
        self.sampler.start(t)
        self.t_nodes[0] = t
        self.c_prev = np.zeros(len(self.rows_of))
        self.q_prev = np.asarray(z[: self.n])[self.cols_of]

    def add(self, t, h, z, mu) -> None:
        row = self.rows[self.count]
        nodes = len(self.rows_of)
        c = row[:nodes]
        np.multiply(mu[self.rows_of], 2.0, out=c)  # (the arithmetic of step_potentials)
        c -= self.c_prev
        self.c_prev = c.copy()
        c /= -h
        q = z[: self.n][self.cols_of]
        np.subtract(q, self.q_prev, out=row[nodes:])
        row[nodes:] /= h
        self.q_prev = q
        self.rows_t[self.count], self.rows_h[self.count] = t, h
        self.t_nodes.append(t)
        self.h_all.append(h)
        self.count += 1
        self.steps += 1
        if self.kept:
            if self.keep or self.steps * self.per_step <= self.keep_max:
                self.full.add(t, h, z, mu)
            else:
                self.kept, self.full = False, None  # over the budget: the grid only
        if self.count == CHUNK:
            self._pass()

    def _pass(self) -> None:
        k = self.count
        values = self.rows[:k]  # (the sampler copies the rows it keeps)
        if self.pick is not None:
            values = self.layout.with_extra(values)[:, self.pick]
        self.sampler.feed(self.rows_t[:k].copy(), self.rows_h[:k].copy(), values)
        self.count = 0

    def arrays(self):
        """``(t, h, q, p, μ)``; ``q, p, μ`` are ``None`` when the records were not kept."""
        if self.count:
            self._pass()
        self.grid_values = self.sampler.finish()
        if self.kept:
            return self.full.arrays()
        return np.asarray(self.t_nodes), np.asarray(self.h_all), None, None, None
