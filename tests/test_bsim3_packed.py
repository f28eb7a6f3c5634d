"""Alike BSIM3 devices are one kind of part: a chain of CMOS inverters of one card pair,
every stage of another W, L, AD/AS/PD/PS, and a Monte-Carlo variant of the NMOS card
(other VTH0, U0, TOX, LINT, WINT: what ngspice's ``MC_ring.sp`` alters), reads as two
groups of transistors whatever the number of stages — its devices' functions are read
once per kind, stacked and stepped with one ``vmap`` per kind — and the packed step
computes what the part-by-part one computes.

White-box: reads ``diracvi.driver.events``, ``diracvi.model.stacked``."""

from __future__ import annotations

import numpy as np
import pytest

from _bsim3_cards import CARDS
from _packed import assert_packed_step_equals_plain
from diracvi import spice
from diracvi.driver import events
from diracvi.model import stacked

VARIANT = CARDS.split(".model p1")[0].replace(".model n1", ".model n2")
for _old, _new in (("vth0=.6322", "vth0=.6511"), ("u0=388.3203", "u0=371.2"),
                   ("tox=9e-09", "tox=9.4e-09"), ("lint=9.36e-8 wint=1.47e-7",
                   "lint=9.9e-8 wint=1.38e-7")):  # fmt: skip
    VARIANT = VARIANT.replace(_old, _new)


def chain(n: int, stop: str = "2n") -> str:
    """``n`` BSIM3 inverters, stage k of its own sizes; odd stages' NMOS on the variant."""
    lines = [f"chain of {n} BSIM3 inverters", "vdd dd 0 3.3", "vin n0 0 pulse 0 3.3 0.1n 0.2n"]
    for k in range(n):
        w, ell, a = 1.0 + 0.5 * k, 0.35 + 0.05 * k, 3 + k
        card = "n2" if k % 2 else "n1"
        lines += [
            f"mn{k} n{k + 1} n{k} 0 0 {card} w={w}u l={ell}u as={a}p ad={a}p ps=4u pd=4u",
            f"mp{k} n{k + 1} n{k} dd dd p1 w={2 * w}u l=0.35u as={2 * a}p ad=7p ps=6u pd=6u",
        ]
    lines += [f"cl n{n} 0 0.05p", CARDS, VARIANT, f".tran 10p {stop}", ".end"]
    return "\n".join(lines) + "\n"


def transistor_groups(netlist) -> list[list[str]]:
    """The packed system's groups of transistors, by name."""
    packed = events.packed_unless_switched(netlist.system)
    assert packed.packed
    names = [s.name for s in netlist.system.subsystems]
    roles = {s.name: s.role for s in netlist.system.subsystems}
    groups = [[names[i] for i in m] for m in packed._packing.tables.members]
    return [g for g in groups if roles[g[0]] == "transistor"]


def test_alike_bsim3_devices_are_one_group_whatever_their_number_and_sizes():
    for n in (4, 9):
        netlist = spice.read(chain(n))
        groups = transistor_groups(netlist)
        # one group per polarity: sizes, junction areas and the card's variant aside
        assert sorted(groups) == [[f"mn{k}" for k in range(n)], [f"mp{k}" for k in range(n)]]
        keys = {stacked.structure_key(s) for s in netlist.system.subsystems}
        assert len(keys) == 5  # NMOS, PMOS, the two sources, the capacitor
    # what makes another kind: another structure (RSH: the variant's series resistors)
    netlist = spice.read(chain(4).replace("vth0=.6511", "vth0=.6511 rsh=5"))
    assert len(transistor_groups(netlist)) == 3


@pytest.mark.slow  # (two step programs of eight BSIM3 devices compiled: ~2 min of CPU)
def test_packed_bsim3_step_equals_part_by_part():
    # one variable step from the operating point across the input's edge, packed and
    # part by part: equal to round-off (the vmapped groups sum in another order)
    assert_packed_step_equals_plain(spice.read(chain(4)), 0.15e-9, (2e-12, 1e-11))


def test_a_zero_size_wall_of_grading_one_adds_no_charge():
    """A bottom wall with MJ = 1 (its charge divides by 1 − M) and AD = AS = 0: ngspice
    skips a wall of zero size, and so does the part — its charges are finite and equal
    those of the same device with MJ at its default (the wall carries nothing)."""
    base = "mj\nvd d 0 1\nvg g 0 1.2\nm1 d g 0 0 nb l=1u w=10u\n"
    card = ".model nb nmos level=8 version=3.3.0 {}\n.tran 1n 5n\n.end\n"
    parts = [
        next(p for p in spice.read(base + card.format(mj)).circuit.parts if p.name == "m1")
        for mj in ("mj=1", "")
    ]
    q = np.zeros(len(parts[0].coords))
    v = np.linspace(0.1, 0.9, len(parts[0].coords))
    one, default = (np.asarray(p.charge(q, v)) for p in parts)
    assert np.all(np.isfinite(one))
    np.testing.assert_array_equal(one, default)
