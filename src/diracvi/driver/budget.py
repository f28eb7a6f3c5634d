r"""A variable-step run's budget of tries, judged by the run's own pace.

A run that cannot meet its tolerance often does not fail outright: its error estimate
stalls just below the tolerance at a tiny step (a ringing junction, a law's round-off
judged as error) and it creeps on, every try accepted, for hours. A budget of tries
stops it with a message. A fixed count must guess what paces a run — SPICE's ``TMAX``
(``spice/_run.tries_budget``: 10 per TMAX), a source's period — and a run paced by
something else, such as the switching events of a ring oscillator, runs out of it while
it makes steady progress (``ng_switch_osc``: 15 436 ordinary tries where 10 510 were
given, 26 284 steps to its end).

So the count is judged by the run's pace. Past ``base`` tries (``N ≥ base``) the run goes
on while, at the pace of its last :data:`WINDOW` · ``base`` tries,

.. math:: N + (t_\text{stop} - t)\,\frac{\Delta N}{\Delta t} \le L \cdot \text{base},
   \qquad L = \text{LIMIT},

and stops at ``N ≥ L·base`` whatever its pace. A stuck run's recent ``Δt`` is a few
tiny steps (``ng_memristor``, before its law's round-off was left unjudged, crept at
5e-15 s a step with 1e-8 s to go: 2·10⁶ more tries, 120 times its count), so it stops at
``base`` as it did under the plain count; a run making steady progress that needs up to ``L`` times
its guess finishes. The run is seen only where the compiled loop returns to the host
(each chunk of :func:`~.adaptive.buffer_size` steps), so ``ΔN`` spans at least a chunk.
"""

from __future__ import annotations

import math

#: how far past its base a run that keeps its pace may go: ``ng_switch_osc`` needs 1.47
#: times its base (15 436 of 10 510); a stuck run projects 10⁴ times or more
LIMIT = 4.0

#: the pace is judged from the last check at least ``WINDOW · base`` ordinary tries back:
#: long enough to span several switching events of an oscillator (``ng_switch_osc``: 2 628
#: tries; at 62.4 ns, checks a chunk apart, it reached back to 37.0 ns, five periods),
#: short enough that a run which was fast and then got stuck is judged by where it is stuck
WINDOW = 0.25


class TriesBudget:
    """``base`` ordinary tries, extended by the run's pace (module doc) when ``paced``;
    :meth:`spent` is asked at each return of the loop to the host."""

    def __init__(self, base: int, *, paced: bool = True):
        if base < 0:
            raise ValueError(f"base={base!r}: a budget of tries is a count >= 0.")
        self.base = int(base)
        self.paced = paced
        self._seen: list[tuple[int, float]] = []  # (tries, t) at each check
        self.projected = math.inf  # the last projection judged (for the message)

    @classmethod
    def of(cls, budget, t0: float) -> TriesBudget:
        """A fresh budget from ``budget``: a :class:`TriesBudget` (its settings, no history)
        or a plain count (not paced: the run stops at that many tries)."""
        if isinstance(budget, TriesBudget):
            made = cls(budget.base, paced=budget.paced)
        else:
            made = cls(int(budget), paced=False)
        made._seen.append((0, float(t0)))
        return made

    def spent(self, t: float, tries: int, t_stop: float) -> bool:
        """Whether a run at ``t`` after ``tries`` ordinary tries stops (module doc)."""
        self._seen.append((int(tries), float(t)))
        if tries < self.base:
            return False
        if not self.paced or tries >= LIMIT * self.base:
            return True
        # the latest check at least WINDOW·base tries back (else the run's start)
        reach = tries - WINDOW * self.base
        then_tries, then_t = self._seen[0]
        for n, at in reversed(self._seen[:-1]):
            if n <= reach:
                then_tries, then_t = n, at
                break
        advanced = t - then_t
        if not advanced > 0.0:
            self.projected = math.inf
            return True
        self.projected = tries + (t_stop - t) * (tries - then_tries) / advanced
        return self.projected > LIMIT * self.base
