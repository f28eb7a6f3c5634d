"""A netlist read afresh finds its compiled programs again (issue 30).

A user reruns a deck after editing a value, and the corpus reads every deck anew: the
variable-step loop (:mod:`diracvi.driver.adaptive`) must then not be traced again. Its
programs are looked up by the model's structure — the PyTree structure with its static
fields — and, in the disk store, by the key printed from it; so two reads of one deck
must give the same structure, a deck that differs in values only as well, and the key
must be printable (no opaque callable in it).
"""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np
import pytest

from diracvi import spice
from diracvi.driver import adaptive as _adaptive
from diracvi.runtime.fingerprint import canonical

HALFWAVE = Path(__file__).parent / "data" / "netlists" / "es_halfwave"

SQUARE_RC = """Square wave into an RC
V1 in 0 PULSE(0 5 0 1u 1u 0.5m 1m)
R1 in out 1k
C1 out 0 0.1u
.tran 10u 3m uic
.end
"""


def _halfwave(amplitude: str = "20", load: str = "1k") -> str:
    deck = (HALFWAVE / "Halfwave_Rectifier.cir.out").read_text()
    deck = deck.replace(".include D.lib", (HALFWAVE / "D.lib").read_text())
    return deck.replace("sine(0 20 50", f"sine(0 {amplitude} 50").replace("1k", load)


def test_two_reads_of_a_deck_with_a_diode_are_one_structure_with_a_printable_key():
    """The diode's junction charge has a custom derivative rule; JAX wraps the rule anew
    at every trace, and that wrapper's identity used to be part of the Lagrangian's
    program key: each read made a new program, so a new structure and a retrace."""
    first, second = (spice.read(_halfwave()).system for _ in range(2))
    assert jax.tree.structure(first) == jax.tree.structure(second)
    diode_l = first.subsystems[0]._lagrangian.rest
    assert diode_l is second.subsystems[0]._lagrangian.rest  # one interned program
    assert "_depletion_coenergy_jvp" in diode_l.key and not diode_l.keep
    canonical(first)  # no opaque callable: the disk store can key it (raises if not)


def test_values_are_data_in_the_structure():
    """Other values of a source, a resistor or a diode parameter leave the structure as
    it is (they are array leaves, arguments of the compiled programs); another kind of
    source does not."""
    base = jax.tree.structure(spice.read(_halfwave()).system)
    for deck in (
        _halfwave(amplitude="15"),
        _halfwave(load="2.2k"),
        _halfwave().replace("is=2.495E-09", "is=3E-09"),
    ):
        assert jax.tree.structure(spice.read(deck).system) == base
    pulses = [SQUARE_RC, SQUARE_RC.replace("PULSE(0 5 0 1u 1u 0.5m", "PULSE(1 3 0 2u 1u 0.4m")]
    one, two = (spice.read(deck).system for deck in pulses)
    assert jax.tree.structure(one) == jax.tree.structure(two)
    source = {p.name: p for p in two.subsystems}["V1"]
    (wave,) = source.waveforms
    assert float(wave.v1) == 1.0 and float(wave.rise) == 2e-6  # the values themselves
    dc = spice.read(SQUARE_RC.replace("PULSE(0 5 0 1u 1u 0.5m 1m)", "DC 5")).system
    assert jax.tree.structure(dc) != jax.tree.structure(one)


def test_a_deck_read_again_or_with_other_values_is_not_traced_again():
    first = spice.run(SQUARE_RC)
    traces = _adaptive.TRACES["count"]
    again = spice.run(SQUARE_RC)
    edited = spice.run(
        SQUARE_RC.replace("PULSE(0 5", "PULSE(0 2.5").replace("R1 in out 1k", "R1 in out 2k")
    )
    assert _adaptive.TRACES["count"] == traces
    np.testing.assert_array_equal(again["v(out)"], first["v(out)"])
    # the new values were used: a square wave of amplitude A and half-period T/2 through
    # an RC of time constant τ peaks, periodically, at A / (1 + e^{−T/(2τ)})
    for run, amplitude, tau in ((first, 5.0, 1e-4), (edited, 2.5, 2e-4)):
        peak = amplitude / (1.0 + np.exp(-0.5e-3 / tau))
        np.testing.assert_allclose(run["v(out)"].max(), peak, rtol=5e-3)


@pytest.mark.slow
def test_the_halfwave_rectifier_read_again_or_edited_runs_without_tracing():
    """The brief's case: es_halfwave read afresh in one process (4.6 s of a 7.2 s call
    was the retrace)."""
    first = spice.run(_halfwave())
    traces = _adaptive.TRACES["count"]
    again = spice.run(_halfwave())
    edited = spice.run(_halfwave(amplitude="15", load="2k"))
    assert _adaptive.TRACES["count"] == traces
    np.testing.assert_array_equal(again["v(out)"], first["v(out)"])
    # a rectified peak (at the run's own points: the deck's 10 ms output grid falls on
    # the 50 Hz sine's zeros): the amplitude less one diode drop at ~7 mA
    drop = 15.0 - edited.internal["v(out)"].max()
    assert 0.4 < drop < 1.2, drop
