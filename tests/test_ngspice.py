"""Live ngspice: regenerate the reference waveforms and compare (skipped without ngspice).

The committed CSVs (``tests/data/ngspice``) are what ``tests/test_spice.py`` compares
diracvi with; here a fresh ngspice run must reproduce them, so a reference cannot go
stale or be edited by hand unnoticed.
"""

from __future__ import annotations

import numpy as np
import pytest

import _ngspice as ng

pytestmark = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")


@pytest.mark.parametrize(
    "name", ["rc", *(pytest.param(n, marks=pytest.mark.slow) for n in ng.CIRCUITS if n != "rc")]
)
def test_fresh_ngspice_run_reproduces_the_committed_reference(name):
    t, committed = ng.load(name)
    grid, fresh = ng.reference(name)
    np.testing.assert_allclose(grid, t, rtol=0, atol=1e-12 * t[-1])
    for probe, values in committed.items():
        peak = np.max(np.abs(values))
        assert np.max(np.abs(fresh[probe] - values)) <= 1e-7 * peak, probe


def test_ngspice_and_the_exact_rc_charge_agree():
    # guards the harness itself: ngspice's own run against 1 − e^{−t/RC} for t > 0 (its
    # t = 0 row under UIC is off by 1.2e-5: the first point is not a solved state)
    t, values = ng.reference("rc")
    assert np.max(np.abs(values["v(out)"] - (1.0 - np.exp(-t / 1e-3)))[1:]) < 1e-8
