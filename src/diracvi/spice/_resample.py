r"""Waveforms of a variable-step run: step-centred values, resampled on any times.

Under the midpoint rule the quantities a circuit reports belong to the *steps*, not to
the nodes ``t_k``:

* a branch current is the step velocity ``i_{k+½} = (q_{k+1} − q_k)/h_k``;
* a node potential comes from the KCL multipliers. The (+) equations put a step's whole
  constraint impulse on the momentum line of its first node, and half of each step's
  impulse ``c_k ≈ −h_k φ(t_{k+½})`` belongs to each of its ends, so the multiplier of
  step ``k`` is ``μ_k = ½c_{k−1} + ½c_k``, with ``c_{−1} = 0`` (the given ``p₀`` carries
  no lag). Hence ``c_k = 2μ_k − c_{k−1}`` and ``φ_{k+½} = −c_k/h_k``: exact at the
  step's centre to the rule's order, whatever ``h_{k−1}/h_k``. (The node average
  ``−μ_k / ((h_{k−1}+h_k)/2)`` of a fixed-step run is off by ``|Δφ'|·h/4`` where the
  steps change size or a source has a corner.)

Both are second order at the step centres ``t_{k+½}``. Between two breakpoints (source
corners) a signal is smooth, so it is sampled at other times from the four nearest step
centres *of the same interval* — never across a corner; at the ends of an interval (and
of the run, half a step beyond the last centre) the same weights extrapolate, which keeps
second order (a linear extrapolation would not). The weights are exact for quadratics and
blind to the midpoint rule's period-2 alternation ``A(−1)^k/h_k`` (a stiff mode, ``R(z) →
−1``, excited at a corner of a device law), which a quadratic through three centres passes
on — and extrapolated half a step, multiplies by 3.5 (:mod:`._smooth`). The step-centred
values themselves, the states, KCL and the power balance are untouched: only what is
read between the centres (and at them: the weights at a centre are ``(−1, 3, 5, 1)/8``)
is the alternation-free value. An interval of three steps is read by the quadratic
through them, of two by the line, of one by the constant.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ._smooth import alternation_free


def step_potentials(mu: np.ndarray, h: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``φ_{k+½} = −c_k/h_k`` per multiplier column, from ``c_k = 2μ_k − c_{k−1}``
    (written into ``out`` when given: a view of a larger array of signals)."""
    c = np.empty_like(mu) if out is None else out
    prev = np.zeros(mu.shape[1:])
    for k in range(mu.shape[0]):  # a recurrence: sequential by nature
        np.multiply(mu[k], 2.0, out=c[k])
        c[k] -= prev
        prev = c[k]
    c /= -h.reshape(-1, *([1] * (mu.ndim - 1)))
    return c


#: a query this close after a bound (relative) is on it: the same corner computed by
#: another program (ngspice's ``td + tr + pw``) can differ from this run's by an ulp,
#: and a waveform that jumps there (a capacitor's current at a PULSE corner) would be
#: read on the wrong side of its jump
ON_BOUND = 1e-12


def interval_of(bounds: np.ndarray, query: np.ndarray) -> np.ndarray:
    """The interval ``[b_i, b_{i+1}]`` of each query, a query on a bound (up to
    :data:`ON_BOUND`) in the one before it, the run's start in the first."""
    snapped = query - ON_BOUND * np.abs(query)
    return np.clip(np.searchsorted(bounds, snapped, side="left") - 1, 0, len(bounds) - 2)


class Sampler:
    """Quadratic interpolation of step-centred values within the intervals between
    consecutive ``bounds`` (the run's start, its breakpoints, its end).

    ``t``: the run's nodes (N+1), ``h``: its steps (N).
    """

    def __init__(self, t: np.ndarray, h: np.ndarray, bounds: np.ndarray):
        self.centres = t[:-1] + 0.5 * h
        self.h = np.asarray(h, dtype=np.float64)
        self.bounds = np.asarray(bounds, dtype=np.float64)
        # the interval of each step (by its centre), and each interval's first step
        self.interval = np.clip(np.searchsorted(self.bounds, self.centres) - 1, 0, None)
        count = len(self.bounds) - 1
        self.first = np.searchsorted(self.interval, np.arange(count + 1))

    def weights(self, query: np.ndarray):
        """``(index (Q, 4), weights (Q, 4))``: each query's four step centres and their
        weights. A query on a bound (up to round-off, :func:`interval_of`) belongs to the
        interval before it (the run's start to the first interval). An interval of four
        steps or more: the four nearest centres around the query, weights exact for
        quadratics that take out the midpoint rule's period-2 alternation
        (:mod:`._smooth`); of three, the quadratic through them; of two, the line; of
        one, the constant (the unused columns weigh 0)."""
        query = np.asarray(query, dtype=np.float64)
        interval = interval_of(self.bounds, query)
        lo, hi = self.first[interval], self.first[interval + 1]
        size = hi - lo
        # windows in the interval's steps: up to 4, the nearest around the query
        at = np.searchsorted(self.centres, query)
        start = np.clip(at - 2, lo, np.maximum(hi - 4, lo))
        index = np.minimum(start[:, None] + np.arange(4)[None, :], (hi - 1)[:, None])
        x = self.centres[index]
        w = np.zeros_like(x)
        four = size >= 4
        if np.any(four):
            w[four] = alternation_free(x[four], self.h[index[four]], query[four])
        three = size == 3
        if np.any(three):
            x3, q3 = x[three, :3], query[three]
            for j in range(3):
                num = np.ones_like(q3)
                den = np.ones_like(q3)
                for i in range(3):
                    if i != j:
                        num = num * (q3 - x3[:, i])
                        den = den * (x3[:, j] - x3[:, i])
                w[three, j] = num / den
        w[size == 1, 0] = 1.0
        two = size == 2
        if np.any(two):
            x0, x1 = x[two, 0], x[two, 1]
            s = (query[two] - x0) / (x1 - x0)
            w[two, 0], w[two, 1] = 1.0 - s, s
        return index, w

    def __call__(self, values: np.ndarray, query: np.ndarray) -> np.ndarray:
        """Step-centred ``values`` (N, …) sampled at ``query``: one set of weights for
        every column of ``values`` (a run's signals are sampled as one (N, S) array;
        per signal, the weights cost more than the sampling)."""
        return self.apply(values, *self.weights(query))

    @staticmethod
    def apply(values: np.ndarray, index: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``values`` sampled with the :meth:`weights` ``(index, w)`` of some times."""
        extra = (slice(None),) + (None,) * (np.ndim(values) - 1)
        out = w[:, 0][extra] * values[index[:, 0]]
        for j in range(1, index.shape[1]):  # accumulated: no (Q, 3, S) intermediate
            out += w[:, j][extra] * values[index[:, j]]
        return out


#: signals are sampled this many columns at a time
COLUMNS = 512


class Signals:
    """A run's step-centred signals as one ``(N, S)`` array (``values``) with their
    ``names`` (one column each): sampled at any times by one :class:`Sampler` call."""

    def __init__(self, names, values: np.ndarray):
        self.names = list(names)
        self.values = values

    def sample(self, sampler: Sampler, times: np.ndarray) -> dict[str, np.ndarray]:
        """``{name: waveform at times}`` (columns of one ``(Q, S)`` array)."""
        index, w = sampler.weights(np.asarray(times, dtype=np.float64))
        block = np.empty((len(index), self.values.shape[1]))
        for a in range(0, block.shape[1], COLUMNS):  # (small temporaries: see _run)
            block[:, a : a + COLUMNS] = sampler.apply(self.values[:, a : a + COLUMNS], index, w)
        return {name: block[:, j] for j, name in enumerate(self.names)}

    def __getitem__(self, name: str) -> np.ndarray:
        return self.values[:, self.names.index(name)]


class Sampled(Mapping):
    """``{name: waveform}`` at ``times``, computed at the first access (a run's waveforms
    at its own nodes are as large as its signals, and seldom asked for); ``pin`` maps
    the computed dict once (the start values, see :mod:`._run`)."""

    def __init__(self, signals: Signals, sampler: Sampler, times, pin=None):
        self._args = (signals, sampler, times, pin)
        self._waves = None

    def _all(self) -> dict:
        if self._waves is None:
            signals, sampler, times, pin = self._args
            waves = signals.sample(sampler, times)
            self._waves = waves if pin is None else pin(waves)
        return self._waves

    def __getitem__(self, key):
        return self._all()[key]

    def __iter__(self):
        return iter(self._args[0].names)

    def __len__(self) -> int:
        return len(self._args[0].names)
