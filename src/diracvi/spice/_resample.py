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
corners) a signal is smooth, so it is sampled at other times by quadratic interpolation
through the three nearest step centres *of the same interval* — never across a corner;
at the ends of an interval (and of the run, half a step beyond the last centre) the
same quadratic extrapolates, which keeps second order (a linear one would not).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np


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


class Sampler:
    """Quadratic interpolation of step-centred values within the intervals between
    consecutive ``bounds`` (the run's start, its breakpoints, its end).

    ``t``: the run's nodes (N+1), ``h``: its steps (N).
    """

    def __init__(self, t: np.ndarray, h: np.ndarray, bounds: np.ndarray):
        self.centres = t[:-1] + 0.5 * h
        self.bounds = np.asarray(bounds, dtype=np.float64)
        # the interval of each step (by its centre), and each interval's first step
        self.interval = np.clip(np.searchsorted(self.bounds, self.centres) - 1, 0, None)
        count = len(self.bounds) - 1
        self.first = np.searchsorted(self.interval, np.arange(count + 1))

    def weights(self, query: np.ndarray):
        """``(index (Q, 3), weights (Q, 3))``: each query's three step centres and their
        Lagrange weights. A query on a bound belongs to the interval before it (the run's
        start to the first interval)."""
        query = np.asarray(query, dtype=np.float64)
        count = len(self.bounds) - 1
        interval = np.clip(np.searchsorted(self.bounds, query, side="left") - 1, 0, count - 1)
        lo, hi = self.first[interval], self.first[interval + 1]
        size = hi - lo
        # windows in the interval's steps: up to 3, the nearest around the query
        at = np.searchsorted(self.centres, query)
        start = np.clip(at - 1, lo, np.maximum(hi - 3, lo))
        index = np.minimum(start[:, None] + np.arange(3)[None, :], (hi - 1)[:, None])
        x = self.centres[index]
        w = np.empty_like(x)
        for j in range(3):
            others = [i for i in range(3) if i != j]
            num = np.ones_like(query)
            den = np.ones_like(query)
            for i in others:
                num = num * (query - x[:, i])
                den = den * (x[:, j] - x[:, i])
            w[:, j] = num / np.where(den == 0.0, 1.0, den)
        # intervals of one or two steps: constant or linear
        one = size == 1
        w[one] = [1.0, 0.0, 0.0]
        two = size == 2
        if np.any(two):
            x0, x1 = x[two, 0], x[two, 1]
            s = (query[two] - x0) / (x1 - x0)
            w[two] = np.column_stack([1.0 - s, s, np.zeros_like(s)])
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
        for j in (1, 2):  # accumulated: no (Q, 3, S) intermediate
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
