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

from _packed import assert_packed_step_equals_plain
from diracvi import spice
from diracvi.driver import events
from diracvi.model import stacked

# ngspice's examples/Monte_Carlo/MC_ring.sp cards, abridged (capMod 3, mobMod 1)
CARDS = """.model n1 nmos level=8 version=3.3.0 tnom=27.0 nch=2.498e+17 tox=9e-09 xj=1e-07
+ lint=9.36e-8 wint=1.47e-7 vth0=.6322 k1=.756 k2=-3.83e-2 k3=-2.612 dvt0=2.812
+ dvt1=0.462 dvt2=-9.17e-2 nlx=3.52291e-08 w0=1.163e-6 k3b=2.233 vsat=86301.58
+ ua=6.47e-9 ub=4.23e-18 uc=-4.706281e-11 rdsw=650 u0=388.3203 wr=1 a0=.3496967
+ ags=.1 b0=0.546 b1=1 keta=-3.605872e-02 a1=2.778747e-02 a2=.9 voff=-6.735529e-02
+ nfactor=1.139926 cit=1.622527e-04 cdsc=-2.147181e-05 eta0=1.0281729e-02
+ etab=-5.042203e-03 dsub=.31871233 pclm=1.114846 pdiblc1=2.45357e-03
+ pdiblc2=6.406289e-03 drout=.31871233 pscbe1=5000000 pscbe2=5e-09 pdiblcb=-.234
.model p1 pmos level=8 version=3.3.0 tnom=27.0 nch=3.533024e+17 tox=9e-09 xj=1e-07
+ lint=6.23e-8 wint=1.22e-7 vth0=-.6732829 k1=.8362093 k2=-8.606622e-02 k3=1.82
+ dvt0=1.903801 dvt1=.5333922 dvt2=-.1862677 nlx=1.28e-8 w0=2.1e-6 k3b=-0.24
+ vsat=103503.2 ua=1.39995e-09 ub=1.e-19 uc=-2.73e-11 rdsw=460 u0=138.7609
+ a0=.4716551 ags=0.12 keta=-1.871516e-03 a1=.3417965 a2=0.83 voff=-.074182
+ nfactor=1.54389 cit=-1.015667e-03 cdsc=8.937517e-04 eta0=6.024776e-02
+ etab=-4.64593e-03 dsub=.23222404 pclm=.989 pdiblc1=2.07418e-02 pdiblc2=1.33813e-3"""
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
