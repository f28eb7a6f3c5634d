"""The operating point's aids for MOSFET circuits: the bulk junctions limited as ngspice's
``mos1load``/``mos2load`` limit them (``pnjlim`` with the device's polarity, started
reverse-biased at −1 V), ngspice's dynamic gmin stepping, and the singularity test on a
scaled Jacobian (a MOSFET's Meyer rows are 10¹² times its others).

The whole path against ngspice is the corpus deck ``ng_mosamp`` (27 level-2 transistors,
whose operating point plain Newton does not find, in ngspice either:
``tests/test_corpus.py``, slow).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from _ngspice import available
from _ngspice import operating_point as ngspice_op
from diracvi import components as cp
from diracvi.components._junction import THERMAL_VOLTAGE
from diracvi.errors import ModelError
from diracvi.solvers.limiting import junctions, limit_junction, limit_rows
from diracvi.spice import operating_point, read
from diracvi.spice._operating_point import _gmin_stepping, _singular
from diracvi.spice._operating_point import operating_point as point_of


@pytest.mark.parametrize("kind, sign", [("nmos", 1.0), ("pmos", -1.0)])
def test_mosfet_declares_its_bulk_junctions_with_ngspice_values(kind, sign):
    """``V_BS``, ``V_BD`` are limited with ``V_T`` and ``V_crit = V_T ln(V_T/(√2 I_S))``
    (``I_S`` times ``M``), the polarity ``type`` and the start −1 V (``MODEINITJCT``)."""
    part = cp.MOSFET(kind, vto=sign * 0.7, kp=2e-5, is_=1e-15, m=2.0, name="m1")
    index, rows = junctions(part)
    assert [part.coords[j] for j in index] == ["wbs", "wbd"]
    vcrit = THERMAL_VOLTAGE * np.log(THERMAL_VOLTAGE / (np.sqrt(2.0) * 2e-15))
    expected = [THERMAL_VOLTAGE, vcrit, np.inf, sign, -1.0]
    np.testing.assert_allclose(np.asarray(rows), [expected, expected], rtol=1e-15)


def test_a_pmos_junction_is_limited_as_its_forward_voltage():
    """A polarity −1 junction moves as the mirrored +1 junction: ``pnjlim`` acts on the
    forward voltage ``s·v``; three-column rows (diodes) keep polarity +1."""
    v_new, v_old = np.array([-5.0, 4.0, -0.61]), np.array([-0.6, 1.0, -0.6])
    row = [THERMAL_VOLTAGE, 0.6, np.inf, -1.0, -1.0]
    got = limit_rows(v_new, v_old, np.array([row] * 3), xp=np)
    plain = limit_junction(-v_new, -v_old, THERMAL_VOLTAGE, 0.6, np.inf, xp=np)
    np.testing.assert_array_equal(got, -plain)
    assert got[0] > -5.0  # the forward jump (−5 V is 5 V forward for s = −1) is limited
    assert got[1] == 1.0 + 1.0 + 1.0 or got[1] < 4.0  # reverse: not beyond 2·V_old + 1


def test_dynamic_gmin_stepping_retreats_and_reaches_zero():
    """A solve converges only when ``G`` is at least a third of the last converged one:
    the first step (10⁻³ from 10⁻²) fails, and ngspice's rule retreats to a smaller factor,
    lets it grow while steps pass, and ends at 10⁻¹² S, then 0, from the last point."""
    tried = []

    def solve(x, source, gmin):
        tried.append(gmin)
        last = 1e-2 if x is None else x
        ok = gmin == 0.0 or gmin >= last / 3.0
        return (gmin if ok and gmin > 0.0 else x), ok

    x, ok = _gmin_stepping(solve, None)
    assert ok and x == 1e-12
    assert tried[0] == 1e-3 and tried[-2:] == [1e-12, 0.0]
    passed = [g for g, nxt in itertools.pairwise(tried) if nxt < g or nxt == 0.0]
    assert all(b >= a / 3.0 for a, b in itertools.pairwise(passed))
    assert len(tried) < 200


def test_singularity_is_judged_on_the_scaled_matrix():
    """Rows 10¹² times the others (Meyer's ``y/τ``) do not make a regular matrix singular;
    a node with no DC path does."""
    rng = np.random.default_rng(1)
    a = rng.standard_normal((6, 6)) + 6.0 * np.eye(6)
    a[:2] *= 1e12
    a[:, 3] *= 1e-11
    assert np.linalg.matrix_rank(a) < 6  # the unscaled test's verdict
    assert not _singular(a)
    a[:, 4] = 0.0
    assert _singular(a)


DIVIDER_MOS = """NMOS load pulled by a PMOS, both cut off or on: ngspice's .op
VDD dd 0 5
VG g 0 2.5
R1 dd d 10k
M1 d g 0 0 nch w=10u l=2u
M2 d g dd dd pch w=20u l=2u
.model nch nmos level=1 vto=0.8 kp=5e-5 lambda=0.02 gamma=0.4 phi=0.7 is=1e-14
.model pch pmos level=1 vto=-0.8 kp=2e-5 lambda=0.02 gamma=0.4 phi=0.7 is=1e-14
.tran 1n 10n
.end
"""


@pytest.mark.slow  # ~20 s: a MOSFET circuit's operating point compiles
@pytest.mark.skipif(not available(), reason="ngspice is not installed")
def test_cmos_stage_operating_point_by_each_method_is_ngspices():
    """The stage's point by Newton and by gmin stepping forced alone is ngspice's ``.op``
    (node voltages and the supply current to 1e-9 relative): the limiting, the seeds and
    the stepping change the path, not the point."""
    netlist = read(DIVIDER_MOS)
    reference = ngspice_op(DIVIDER_MOS)
    for method in ("newton", "gmin stepping"):
        point = point_of(netlist.assembly, methods=(method,))
        assert point.method == method
        for key in ("v(d)", "i(vdd)"):
            assert point[key] == pytest.approx(reference[key], rel=1e-9, abs=1e-15), key


def test_a_voltage_source_shorted_by_an_inductor_is_reported_singular():
    """A loop of a voltage source and an inductor has no DC solution: the scaled test
    still calls it singular, and the message says what to fix."""
    netlist = "Shorted source\nV1 a 0 DC 1\nL1 a 0 1m\nR1 a 0 1k\n.tran 1u 10u\n.end\n"
    with pytest.raises(ModelError, match=r"its equations are singular.*a loop of inductors"):
        operating_point(netlist)


def test_out_of_memory_in_the_dense_analysis_is_a_clear_error(monkeypatch):
    """XLA refusing the dense Jacobian's memory (a held-out deck of 17 472 coordinates,
    Xyce's ``sram.cir``, asked 61 GB) is reported as the operating point's limit, with
    its size and the fix (UIC), not as a runtime traceback."""
    import jax

    from diracvi.spice import _operating_point as op_module

    def exhausted(*args, **kwargs):
        raise jax.errors.JaxRuntimeError("RESOURCE_EXHAUSTED: Out of memory allocating 6e10 bytes.")

    monkeypatch.setattr(op_module, "_linearized", exhausted)
    deck = read("rc\nV1 1 0 DC 1\nR1 1 2 1k\nC1 2 0 1u\n.tran 1u 1m\n.end\n")
    with pytest.raises(ModelError, match=r"out of memory.*dense Jacobian.*UIC") as info:
        operating_point(deck)
    import re

    assert re.search(
        r"\(\d+ × \d+, [\d.]+ GB .* \d+ coordinates and \d+ constraints", str(info.value)
    )
