"""Alike transistors are traced once: a nonlinear circuit's variable-step loop and its
operating point step the *packed* interconnection (alike parts' parameters stacked,
each kind of part one ``vmap``), so their programs do not grow with the number of
transistors of one model, and they compute what the part-by-part system computes.

White-box: reads ``diracvi.driver.adaptive``, ``diracvi.driver.events``,
``diracvi.model.stacked``, ``diracvi.solvers.limiting``, ``diracvi.spice._operating_point``.
"""

import jax
import numpy as np
import pytest

from _jaxpr import count_equations
from _packed import assert_packed_step_equals_plain
from diracvi import spice
from diracvi.discretization.rules import get_rule
from diracvi.driver import adaptive, events
from diracvi.driver.tries import one_step
from diracvi.model import stacked
from diracvi.model.interconnect import InterconnectedSystem
from diracvi.solvers.limiting import junctions
from diracvi.solvers.newton import NewtonSolver
from diracvi.spice import _run as spice_run

CARDS = """.MODEL nch NMOS (LEVEL=1 VTO=1.0 KP=2e-5 TOX=6E-08 LAMBDA=0.02 GAMMA=0.37 PHI=0.65
+ CBD=0.1P CBS=0.1P PB=0.81 CGSO=2P CGBO=4P CGDO=2P IS=1E-14 RS=10 RD=10)
.MODEL pch PMOS (LEVEL=1 VTO=-1.0 KP=1e-5 TOX=6E-08 LAMBDA=0.02 GAMMA=0.37 PHI=0.65
+ CBD=0.1P CBS=0.1P PB=0.81 CGSO=2P CGBO=4P CGDO=2P IS=1E-14 RS=10 RD=10)"""


def inverters(n: int, stop: str = "2u") -> str:
    """A chain of ``n`` CMOS inverters (level 1 with TOX: Meyer's capacitances, RS/RD:
    internal nodes), each stage of another width, a current source loading the end."""
    lines = [f"chain of {n} inverters", "VDD vdd 0 5", "VIN in 0 PULSE(0 5 0.2u 10n 10n 1u 2u)"]
    lines.append("RIN in n0 1k")
    for k in range(n):
        w = 10 + 3 * k
        lines += [
            f"MN{k} n{k + 1} n{k} 0 0 nch W={w}u L=2u",
            f"MP{k} n{k + 1} n{k} vdd vdd pch W={2 * w}u L=2u",
            f"C{k} n{k + 1} 0 0.05p",
        ]
    lines += [f"IL n{n} 0 1u", CARDS, f".tran 10n {stop}", ".end"]
    return "\n".join(lines) + "\n"


def step_size(system, q, p) -> int:
    """Equations of one variable step's program (Newton with limiting, as the loop's)."""
    rule, solver, mu = get_rule("midpoint"), NewtonSolver(reuse_jacobian=True), np.zeros(system.m)
    jaxpr = jax.make_jaxpr(lambda q, p: one_step(system, rule, solver, 1e-9, 0.0, q, p, q, mu))
    return count_equations(jaxpr(q, p).jaxpr)


def term_sizes(system, q) -> tuple[int, ...]:
    """Equations of the terms a step is built from: ``L``, ``F``, ``A(q, t)``."""
    v = np.ones_like(q)
    return tuple(
        count_equations(jax.make_jaxpr(fn)(q, v).jaxpr)
        for fn in (
            lambda q, v: system.lagrangian(q, v, 0.0),
            lambda q, v: system.force(q, v, 0.0),
            lambda q, v: system.constraint_forms(q, 0.0),
        )
    )


@pytest.mark.slow  # (reading two chains and tracing their terms: ~20 s of CPU)
def test_alike_transistors_share_one_program_of_each_term(monkeypatch):
    # index tables (not a slice per run of alike parts): the layout's size is fixed too
    monkeypatch.setattr(stacked, "MAX_RUNS", 0)
    sizes, groups = {}, {}
    for n in (2, 6):
        netlist = spice.read(inverters(n))
        packed = events.packed_unless_switched(netlist.system)
        assert packed.packed
        groups[n] = len(packed._packing.tables.members)
        sizes[n] = term_sizes(packed, netlist.q0)
        # the junctions Newton limits, read group by group from the stacks: the same
        # indices and rows as the part-by-part system lists them
        a, b = junctions(netlist.system), junctions(packed)
        assert np.array_equal(a[0], b[0])
        assert np.array_equal(np.asarray(a[1]), np.asarray(b[1]))
        assert len(a[0]) == 4 * n  # two bulk junctions per transistor
    # NMOS, PMOS, capacitor, the two sources, the input resistor, the load: whatever n
    assert groups[2] == groups[6]
    assert sizes[2] == sizes[6]


@pytest.mark.slow
def test_alike_transistors_share_one_step_program(monkeypatch):
    # the whole step — Newton, its Jacobian, the junctions' limiting — as the
    # variable-step loop traces it (~20 s of tracing for six inverters)
    monkeypatch.setattr(stacked, "MAX_RUNS", 0)
    sizes = {}
    for n in (2, 6):
        netlist = spice.read(inverters(n))
        sizes[n] = step_size(events.packed_unless_switched(netlist.system), netlist.q0, netlist.p0)
    assert sizes[2] == sizes[6]


@pytest.mark.slow  # (~10 s of CPU)
def test_packed_circuit_rows_are_the_part_by_part_rows():
    # the operating point reads A(q, t) and b(q, t) of the whole circuit: the packed
    # system's (its blocks scattered group by group) equal the part-by-part ones exactly
    netlist = spice.read(inverters(3))
    plain, packed = netlist.system, InterconnectedSystem._packed(netlist.system)
    q = np.random.default_rng(3).standard_normal(plain.n)
    for t in (0.0, 0.7e-6):
        assert np.array_equal(plain.constraint_forms(q, t), packed.constraint_forms(q, t))
        assert np.array_equal(plain.one_forms(q, t), packed.one_forms(q, t))
        b_plain, b_packed = plain.constraint_offset(q, t), packed.constraint_offset(q, t)
        assert b_plain is not None  # the current source's row is affine
        assert np.array_equal(b_plain, b_packed)


@pytest.mark.slow
def test_packed_step_equals_part_by_part():
    # one variable step (Newton with the junctions limited) from the operating point,
    # across the input's rising edge, packed and part by part: equal to round-off (the
    # vmapped groups sum in another order). A whole variable-step run is not compared
    # bitwise: round-off moves an accept/reject decision, and the runs then differ at
    # the level of the step control's tolerance.
    assert_packed_step_equals_plain(spice.read(inverters(2)), 0.2e-6, (1e-9, 4e-9))


@pytest.mark.slow
def test_packed_variable_steps_equal_part_by_part(monkeypatch):
    # the whole run — operating point and variable steps — packed and part by part
    deck = inverters(2, stop="0.6u")
    monkeypatch.setattr(spice_run, "PACKED_MARCH", True)
    packed = spice.run(deck)
    monkeypatch.setattr(spice_run, "PACKED_MARCH", False)
    plain = spice.run(deck)
    # not step for step: the next step's size is read from an error estimate, a
    # difference of nearly equal states, and the two Newtons (dense part by part, packed
    # by the stacked parts) stop at different iterates inside their tolerance, so the
    # sizes drift apart (the 0.6 µs run's last steps end at 5.628516e-07 against
    # 5.628562e-07 s) as two runs of the step control do. Measured 2026-11-30: 493 packed
    # against 483 part by part under the tests' compile options, 491 against 487 under the
    # default ones — the compile options alone, which change only round-off, move the
    # part-by-part count by 4. A wrong error estimate moves it by far more (a factor 2 in
    # a second-order estimate: 2^(1/3), 26 %), hence 5 %. The waveforms on the TSTEP grid
    # agree far inside its RELTOL = 1e-3 (7.2e-5 of the peak at the worst node)
    assert len(packed.trajectory.t) == pytest.approx(len(plain.trajectory.t), rel=0.05)
    for key in plain:
        a, b = np.asarray(plain[key]), np.asarray(packed[key])
        assert np.max(np.abs(a - b)) <= 1e-4 * max(1.0, np.max(np.abs(a))), key


class _Traced(Exception):
    """Raised by the stand-in for the loop's program once its jaxpr is counted."""


@pytest.mark.slow  # (two chains read, each loop traced with its probes: ~30 s of CPU)
def test_alike_transistors_share_one_loop_program(monkeypatch):
    # the whole variable-step loop (tries, error estimate, the junctions' end check, the
    # gap check, recording), not only its step: the same size for 2 and 3 inverters (both
    # under bordered.MIN_SIZE unknowns, so both dense Newton), so its compilation does
    # not grow with the number of alike transistors
    monkeypatch.setattr(stacked, "MAX_RUNS", 0)
    sizes = {}

    def count(system, rule, solver, capacity, x):
        jaxpr = jax.make_jaxpr(lambda x: adaptive._march(system, rule, solver, capacity, x))(x)
        sizes[system.n] = count_equations(jaxpr.jaxpr)
        raise _Traced

    monkeypatch.setattr(adaptive, "_program", count)
    for n in (2, 3):
        netlist = spice.read(inverters(n))
        system = events.packed_unless_switched(netlist.system)
        assert system.packed
        zero = np.zeros(system.n)
        ctl = adaptive.Controls(1e-3, 1e-14, 1e-6, np.full(system.m, 1e-6), 1e-8, 1e-16, 1e-9)
        with pytest.raises(_Traced):
            adaptive.adaptive(system, zero, zero, t0=0.0, t_stop=1e-6, controls=ctl)
    assert len(sizes) == 2
    assert len(set(sizes.values())) == 1, sizes
