"""Card names ngspice 39 does not have: it ignores them with a warning ("unrecognized
parameter (xj) - ignored"), so a public deck it runs may carry them (``tests/mos6/
mos6inv.cir``'s level-6 cards set ``XJ``). diracvi ignores them too, with a note, and its
operating point is ngspice's; a name ngspice's table has and diracvi does not read stays
refused by name (the level tests)."""

from __future__ import annotations

import pytest

import _ngspice as ng
from diracvi import spice

needs_ngspice = pytest.mark.skipif(not ng.available(), reason="ngspice is not installed")

MOS = (
    "names\nvd d 0 3\nvg g 0 2\nm1 d g 0 0 mm L=2u W=10u\n.model mm NMOS ({card})\n"
    ".tran 1n 10n\n.end\n"
)
JFET = "names\nvd d 0 3\nvg g 0 -0.5\nj1 d g 0 jm\n.model jm NJF ({card})\n.tran 1n 10n\n.end\n"
CASES = [
    # (deck, card, the names ngspice 39's table for it lacks)
    (MOS, "VTO=0.7 KP=1e-4 LAMBDA=0.02 XJ=0.2u FOO=1", ("XJ", "FOO")),
    (MOS, "LEVEL=2 VTO=0.7 KP=5e-5 TOX=2e-8 UTRA=0.3", ("UTRA",)),
    (MOS, "LEVEL=3 VTO=0.7 KP=5e-5 TOX=2e-8 THETA=0.05 LAMBDA=0.02 UCRIT=1e4", ("LAMBDA", "UCRIT")),
    (MOS, "LEVEL=6 VTO=0.7 KV=2 NV=1 KC=1e-4 NC=1 LAMBDA=0.01 XJ=0.2u KP=2e-5", ("XJ", "KP")),
    (JFET, "VTO=-2 BETA=1e-4 LAMBDA=0.01 N=2", ("N",)),
]


@needs_ngspice
@pytest.mark.parametrize(("deck", "card", "foreign"), CASES)
def test_names_ngspice_ignores_are_noted_and_the_current_is_ngspices(deck, card, foreign):
    net = deck.format(card=card)
    notes = " ".join(spice.read(net).notes)
    for name in foreign:
        assert f"{name} ignored (not a parameter of ngspice 39's" in notes, name
    ref = ng.operating_point(net)["i(vd)"]
    assert abs(ref) > 1e-6  # the channel conducts: the comparison says something
    assert spice.run(net)["i(vd)"][-1] == pytest.approx(ref, rel=1e-8)
