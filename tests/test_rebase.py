"""Growing coordinates stepped from zero in each variable step's gauge
(``diracvi.driver.rebase``; docs/circuits.md, "Time steps")."""

from __future__ import annotations

import numpy as np
import pytest

from diracvi import spice
from diracvi.driver.rebase import rebase_map

MIXED = """charges, fluxes, a capacitor and a ddt position
V1 p 0 15
E1 m 0 p 0 1
R1 m 0 1k
C1 m 0 1n
L1 m x 1m
R2 x 0 1
B1 y 0 V=ddt(v(p))
R3 y 0 1k
.tran 1u 1m
.end
"""


def test_the_rebased_coordinates_are_those_the_lagrangian_reads_only_linearly():
    """Branch charges of sources, resistors and the inductor (cyclic: ``a = 0``) and the
    sensing fluxes (``L = w ṡ``: ``a = e_s``) are rebased; the capacitor's charge (its
    energy is quadratic in it) and the ``ddt`` position (held by a quadratic term) are
    not; ``G`` holds exactly the ``∂²L/∂ṡ∂w = 1`` of each sensing pair."""
    net = spice.read(MIXED)
    coords = list(net.system.coords)
    mask, gauge = rebase_map(net.system, net.q0)
    rebased = {c for c, k in zip(coords, mask, strict=True) if k}
    assert rebased == set(coords) - {"C1.q", "B1.y0"}
    pairs = {(coords[i], coords[j]): gauge[i, j] for i, j in np.argwhere(gauge != 0.0)}
    assert pairs == {("E1.s", "E1.w"): 1.0, ("B1.s0", "B1.w0"): 1.0}


def test_the_probes_are_traced_once_per_structure_not_at_every_run(monkeypatch):
    """``rebase_map`` and ``algebraic_mask`` run at the start of every variable-step run;
    their derivatives are one kept program per system's structure (``_probes``), so a
    second run of a deck — or another deck of the same structure — traces nothing
    (traced at every call they cost ~0.3 CPU s a run of the bridge rectifier, more than
    its steps). The traced function body runs only while tracing: count it."""
    from diracvi.driver import algebraic, rebase

    traced = {"rebase": 0, "algebraic": 0}
    for module, name in ((rebase, "rebase"), (algebraic, "algebraic")):
        original = module._probe

        def counting(*args, original=original, name=name):
            traced[name] += 1
            return original(*args)

        monkeypatch.setattr(module, "_probe", counting)
    net = spice.read(MIXED)
    q, p = np.asarray(net.q0, float), np.zeros(net.system.n)
    first = rebase_map(net.system, q), algebraic.algebraic_mask(net.system, q, p)
    after_first = dict(traced)
    again = spice.read(MIXED)  # a new system object of the same structure
    second = rebase_map(again.system, q, 0.5), algebraic.algebraic_mask(again.system, q, p, 0.5)
    assert traced == after_first
    np.testing.assert_array_equal(first[0][0], second[0][0])
    np.testing.assert_array_equal(first[0][1], second[0][1])
    np.testing.assert_array_equal(first[1], second[1])


@pytest.mark.slow  # a variable-step simulation (~10 s with its compilation)
def test_a_node_at_zero_sensed_across_a_growing_flux_stays_near_round_off():
    """``v(z) = v(p) − v(m)`` with ``m`` a copy of the 15 V rail is 0 V in exact
    arithmetic; the sensing fluxes grow as ``15 V · t``, and a 10 ns edge at 0.9 ms
    takes the steps to under a nanosecond (0.54 ns measured 2026-11-29, session 25; 44 ps
    before the step control sized tries for the gap checks ahead). Stepped from zero
    (``spice.run``'s default), ``|v(z)| ≤ 2e-8`` V (3.3e-9 measured); with the fluxes
    carried whole (``adaptive(rebase=False)``), their ulps over the edge's steps gave
    1.2e-7 V (6.3e-7 on the 44 ps steps)."""
    text = """a node at 0 V in exact arithmetic, sensed across a 15 V rail, and a fast edge
V1 p 0 15
E1 m 0 p 0 1
R1 m 0 1k
E2 z 0 p m 1
R2 z 0 1k
V3 in 0 PULSE(0 5 0.9m 10n)
R3 in o 1k
C3 o 0 10p
.tran 1u 1m
.end
"""
    result = spice.run(text, internal=True)
    assert np.min(result.trajectory.h) < 1e-9  # the edge's steps were taken (≤ 1/10 of it)
    assert np.max(np.abs(result["v(z)"])) <= 2e-8
