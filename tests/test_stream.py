"""A variable-step run's TSTEP grid formed while it steps (spice/_stream.py).

The streamed grid must be the whole-run sampler's (:class:`~diracvi.spice._resample.Sampler`
over every step centre) bit for bit: the same centres, the same three-point windows
within each interval between corners, the same weights — whatever the chunks the rows
arrive in. A run too large to keep reports the grid only and says so when asked for more.
"""

from __future__ import annotations

import numpy as np
import pytest

from diracvi import spice
from diracvi.bench.ladders import ladder
from diracvi.errors import ModelError
from diracvi.spice import _stream
from diracvi.spice._resample import Sampler


@pytest.mark.parametrize("chunk", [1, 3, 7, 64])
def test_streamed_sampling_is_the_whole_run_sampler_bit_for_bit(chunk):
    """Random steps with corners (some intervals of one or two steps) and an output grid
    finer and coarser than the steps in places: fed in chunks of any size, the result is
    exactly the whole-run sampler's."""
    rng = np.random.default_rng(7)
    h = rng.uniform(0.2, 1.0, 300) ** 3
    t = np.concatenate([[0.0], np.cumsum(h)])
    corners = np.sort(rng.choice(t[1:-1], 12, replace=False))
    # an interval of one step and one of two: corners on consecutive nodes
    k = int(np.searchsorted(t, corners[5]))
    corners = np.unique(np.concatenate([corners, t[k + 1 : k + 3]]))
    bounds = np.concatenate([[0.0], corners, [t[-1]]])
    times = np.unique(
        np.concatenate([np.linspace(0.0, t[-1], 97), corners, rng.uniform(0, t[-1], 50)])
    )
    values = rng.standard_normal((len(h), 5))
    want = Sampler(t, h, bounds)(values, times)
    stream = _stream.StreamSampler(bounds, times, 5)
    stream.start(0.0)
    for a in range(0, len(h), chunk):
        stream.feed(t[a + 1 : a + 1 + chunk], h[a : a + chunk], values[a : a + chunk])
    got = stream.finish()
    np.testing.assert_array_equal(got, want)


PULSED = ladder(6, steps=200).replace("SIN(0 1 1000.0)", "PULSE(0 1 20u 5u 5u 40u 100u)")


@pytest.mark.slow  # three runs of a 6-stage ladder, ~4 s each
def test_a_run_over_the_budget_streams_the_same_grid_and_keeps_no_states(monkeypatch):
    """The same deck kept whole and streamed only (the budget set to 0): the TSTEP grid
    is the same bit for bit; the streamed run keeps no states, no step-centred signals,
    and ``at`` says how to get them."""
    assert "PULSE" in PULSED
    whole = spice.run(PULSED)
    assert whole.trajectory.q is not None and whole.internal is not None
    monkeypatch.setattr(_stream, "KEEP_MAX", 0)
    lean = spice.run(PULSED)
    assert lean.trajectory.q is None and lean.internal is None
    np.testing.assert_array_equal(lean.time, whole.time)
    # the saved vectors (ngspice's default set: node voltages, source and inductor
    # currents), the same bit for bit; a resistor's current is not formed
    assert list(lean) == list(whole) and "i(R2)" in whole and "i(R2)" not in lean
    for key in whole:
        np.testing.assert_array_equal(lean[key], whole[key], err_msg=key)
    with pytest.raises(ModelError, match="internal=True"):
        lean.at([1e-5])
    kept = spice.run(PULSED, internal=True)  # asked for: kept whatever the budget
    assert kept.trajectory.q is not None
    np.testing.assert_array_equal(kept.at(whole.time)["v(n3)"], whole["v(n3)"])
