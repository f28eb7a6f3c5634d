"""Model binning (``nch.1``, ``nch.2`` with LMIN/LMAX/WMIN/WMAX; an ``M`` line naming
``nch`` takes the bin holding its L and W), by ngspice 39's ``INPgetModBin``: which bin
each line gets — at an edge two bins share too — checked against ngspice's own choice
(its operating point with BSIM3 cards that differ in VTH0 alone), and the lines ngspice
refuses (level-1 bins: it bins BSIM3/BSIM4/HiSIM cards only) refused, saying why."""

from __future__ import annotations

import subprocess
import tempfile
from pathlib import Path

import pytest

import _ngspice as ng
from diracvi import spice
from diracvi.spice._binning import in_range

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

BINS = """binning
vd d 0 1.5
vg g 0 1.2
m1 d g 0 0 {model} {size}
.model nch.1 nmos level=49 version=3.3.0 tox=4e-9 vth0=0.3 lmin=0.5u lmax=2u wmin=1u wmax=100u
.model nch.2 nmos level=49 version=3.3.0 tox=4e-9 vth0=0.6 lmin=2u lmax=10u wmin=1u wmax=100u
.tran 1n 10n
.end
"""


def chosen(net: str) -> str:
    """The bin diracvi builds m1 from: the one of ``nch.1``, ``nch.2`` the reader does not
    note as unused."""
    notes = spice.read(net).notes
    unused = {
        m for m in ("nch.1", "nch.2") if any(f".model {m} NMOS is not used" in n for n in notes)
    }
    (pick,) = {"nch.1", "nch.2"} - unused
    return pick


def test_the_range_rule_is_ngspices():
    assert in_range(1.5e-6, 1e-6, 2e-6)
    assert in_range(2e-6, 1e-6, 2e-6) and in_range(1e-6, 1e-6, 2e-6)  # both edges
    assert in_range(2e-6 + 0.9e-9, 1e-6, 2e-6)  # within is_equal's 1e-9 (metres)
    assert not in_range(2e-6 + 1.1e-9, 1e-6, 2e-6)


@pytest.mark.parametrize(
    ("size", "expected"),
    [("l=1u w=10u", "nch.1"), ("l=5u w=10u", "nch.2"), ("l=2u w=10u", "nch.1")],
)
def test_each_line_gets_its_bin_and_the_first_card_at_a_shared_edge(size, expected):
    assert chosen(BINS.format(model="nch", size=size)) == expected
    # at the shared edge the order of the cards decides: the one defined first
    swapped = BINS.format(model="nch", size=size).splitlines()
    swapped[4], swapped[5] = swapped[5], swapped[4]
    edge = size.startswith("l=2u")
    want = "nch.2" if edge else expected
    assert chosen("\n".join(swapped)) == want


@needs_ngspice
@pytest.mark.parametrize("size", ["l=1u w=10u", "l=5u w=10u", "l=2u w=10u"])
def test_ngspice_chooses_the_same_bin(size):
    """ngspice's drain current for the binned line equals its current for the line
    naming diracvi's bin (the bins differ in VTH0: 0.3 V against 0.6 V)."""
    current = {
        m: ng.operating_point(BINS.format(model=m, size=size))["i(vd)"]
        for m in ("nch", "nch.1", "nch.2")
    }
    assert abs(current["nch.1"] - current["nch.2"]) > 1e-2 * abs(current["nch.1"])
    mine = chosen(BINS.format(model="nch", size=size))
    assert current["nch"] == current[mine]
    # and the binned BSIM3 device itself carries ngspice's current
    got = spice.operating_point(BINS.format(model="nch", size=size))["i(vd)"]
    assert got == pytest.approx(current["nch"], rel=1e-9)


@pytest.mark.parametrize(
    ("size", "match"),
    [
        ("l=20u w=10u", r"L=2e-05, W=1e-05 lie in no bin of model 'nch' \(nch\.1: L 5e-07–2e-06"),
        ("l=1u w=0.5u", r"lie in no bin"),
        ("l=1u", r"chosen by the line's L= and W=.*give both"),
    ],
)
def test_a_line_no_bin_holds_is_refused_naming_the_ranges(size, match):
    with pytest.raises(spice.NetlistError, match=r"line 4: .*" + match):
        spice.read(BINS.format(model="nch", size=size))


@needs_ngspice
def test_level1_bins_are_refused_as_ngspice_refuses_them():
    net = BINS.replace("level=49 version=3.3.0 tox=4e-9 vth0", "level=1 vto").format(
        model="nch", size="l=1u w=10u"
    )
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "deck.cir").write_text(net)
        out = subprocess.run(
            ["ngspice", "-b", "deck.cir"], cwd=tmp, capture_output=True, text=True, timeout=60
        )
    assert "could not find a valid modelname" in out.stdout + out.stderr
    with pytest.raises(spice.NetlistError, match=r"ngspice 39 bins only BSIM3, BSIM4 and HiSIM"):
        spice.read(net)
