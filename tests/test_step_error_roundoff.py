"""A current law whose terms cancel: the step control does not judge its round-off.

``ng_memristor``'s law ``β y − ½β(|y + V_t| − |y − V_t|)`` (``β`` = 2e12) is exactly 0
for ``|y| < V_t`` and computes to values up to ~5e-4 A of either sign there. Judged as a
branch current against ``abstol + reltol·peak``, that scatter (it does not fall with the
step) rejected every try, and Newton's residual test never saw the terms (the law's
Jacobian cancels to 0): the run stopped on its tries budget at a fraction of a ns.
``diracvi.driver.roundoff`` holds the currents' tolerance at the laws' round-off bound
(``diracvi.runtime.roundoff``) and Newton counts the law's terms
(``StepEquations.force_sizes``). Both circuits below stopped on the budget before
(t = 1.3e-10 s of 1e-8).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from diracvi import spice
from diracvi.driver.roundoff import floors
from diracvi.runtime.config import ensure_float64
from diracvi.runtime.roundoff import with_bound
from diracvi.spice._expr import compile_expression

ensure_float64()

BETA, VT, TSTOP, OMEGA = 2e12, 1.6, 1e-8, 2.0 * np.pi * 1e8
LAW = "2e12*v(1) - 1e12*(abs(v(1)+1.6) - abs(v(1)-1.6))"


def _deck(amplitude: float, ic: float) -> str:
    return f"""a current law whose terms cancel below its threshold
V1 1 0 DC 0 SIN(0 {amplitude} 100MEG)
R1 1 0 1k
B1 0 x I = {LAW}
C1 x 0 1 IC={ic}
.tran 0.1n 10n uic
.end
"""


def _largest_bound(amplitude: float) -> float:
    """The law's round-off bound, largest over ``|y| ≤ amplitude``."""
    law = compile_expression(LAW, {})
    ys = jnp.linspace(-amplitude, amplitude, 4001)
    bound = jax.vmap(lambda y: with_bound(law.fn, y[None], jnp.zeros(0), 0.0, jnp.zeros(0))[1])
    return float(jnp.max(bound(ys)))


def test_a_law_that_is_round_off_alone_runs_at_tmax():
    # below the threshold throughout: the current is exactly 0 and the capacitor holds
    # its IC, to the integral of the law's round-off (closed form)
    result = spice.run(_deck(1.0, 5.0))
    bound = _largest_bound(1.0)  # ~1.0e-3 A (measured)
    assert 1e-4 < bound < 1e-2
    v = np.asarray(result["v(x)"])
    assert np.max(np.abs(v - 5.0)) <= TSTOP * bound  # measured 1.5e-13 V (of 1e-11)
    # the reported current is the law's round-off: within the bound (a step's current
    # from its charges, the output from four step centres: twice it)
    assert np.max(np.abs(result["i(B1)"])) <= 2.0 * bound  # measured 3.5e-4 A
    # and nothing holds the steps below TMAX: the control reads no error in it
    h = np.diff(np.asarray(result.trajectory.t))
    assert np.max(h) >= 0.99 * 1e-10


def _charged(t):
    """``∫₀ᵗ β (y − clip(y, ±V_t)) ds`` for ``y = 2 sin(ωs)`` (the capacitor's rise)."""
    a = 2.0
    t1 = np.arcsin(VT / a) / OMEGA
    lo, hi = (t1, np.pi / OMEGA - t1), (np.pi / OMEGA + t1, 2.0 * np.pi / OMEGA - t1)

    def over(start, end, sign):
        e = np.clip(t, start, end)
        return (a * np.cos(OMEGA * start) - a * np.cos(OMEGA * e)) / OMEGA - sign * VT * (e - start)

    return BETA * (over(*lo, 1.0) + over(*hi, -1.0))


def test_a_law_crossing_its_threshold_against_the_closed_form():
    # a memristor's programming: 2 V crosses 1.6 V both ways, the 1 F capacitor charged
    # by 1084 V and back (its IC 7000 V, as ng_memristor's Cx)
    result = spice.run(_deck(2.0, 7000.0))
    t = np.asarray(result.time)
    rise = _charged(t)
    peak = np.max(np.abs(rise))
    assert 1000.0 < peak < 1100.0
    off = np.max(np.abs(np.asarray(result["v(x)"]) - 7000.0 - rise)) / peak
    assert off <= 1e-3, off  # measured 8.3e-5 (338 steps)


def test_the_floor_only_ever_raises_a_tolerance():
    # max(atol, 2N/3): below the absolute tolerances nothing changes, bit for bit (every
    # circuit whose laws round below abstol steps as before); above, only the judged
    # coordinates (the branch charges) take it
    atol_q, atol_v = jnp.array([1e-14, 1e-6, 1e-14]), jnp.array([1e-12, 1e-6, 1e-12])
    judged = jnp.array([True, False, True])
    for floor in (0.0, 1e-16, 1.4e-12):
        q, v = floors(atol_q, atol_v, judged, floor, 1e-9)
        assert np.array_equal(q, atol_q) and np.array_equal(v, atol_v)
    q, v = floors(atol_q, atol_v, judged, 3e-4, 1e-9)
    np.testing.assert_allclose(v, [2e-4, 1e-6, 2e-4], rtol=1e-15)
    np.testing.assert_allclose(q, [2e-13, 1e-6, 2e-13], rtol=1e-15)
