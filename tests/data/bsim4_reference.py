"""Makes ``bsim4_reference.json``, the ngspice 39 fixture ``tests/test_bsim4.py`` compares
BSIM4 with when ngspice is absent: ``cd tests && PYTHONPATH=../src:. python
data/bsim4_reference.py`` (ngspice on the PATH; a few seconds)."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import _ngspice as ng
import test_mosfet_level6 as level6
from _bsim4_cards import ro_card
from test_bsim3 import _charges_deck, _ngspice_charges

CURRENTS = [
    ("defaults 4.7 NMOS", "NMOS", "VERSION=4.7", "L=0.1u W=1u", -0.3),
    ("defaults 4.7 PMOS", "PMOS", "VERSION=4.7", "L=0.25u W=2u", 0.2),
    ("ng_ro_17_4 N1 (4.5.0)", "NMOS", ro_card("N1"), "L=0.1u W=5u AD=5p PD=6u AS=5p PS=6u", -0.3),
    ("ng_ro_17_4 P1 (4.5.0)", "PMOS", ro_card("P1"), "L=0.1u W=10u AD=5p PD=6u AS=5p PS=6u", -0.3),
]  # fmt: skip
#: ng_ro_17_4's cards with igcMod and igbMod 1: all four terminal currents
TUNNELLING = [
    ("ng_ro_17_4 N1 igc igb", "NMOS", "N1", 5),
    ("ng_ro_17_4 P1 igc igb", "PMOS", "P1", 10),
]
CHARGES = [
    ("n", "W=2u L=0.1u", ".model mm nmos (level=54 version=4.7)"),
    ("p", "W=2u L=0.35u", ".model mm pmos (level=54 version=4.5 xpart=0.5 ngate=5e19 k1=0.5 "
     "k2=0.01 acde=0.5 moin=10 noff=1.5 voffcv=0.05 clc=2e-7 cle=0.5)"),
]  # fmt: skip


def main():
    out = {"currents": [], "charges": []}
    for name, kind, card, instance, vb in CURRENTS:
        s = -1.0 if kind == "PMOS" else 1.0
        net = level6.sweep_deck(54).format(kind=kind, card=card, instance=instance, vb=s * vb)
        sweep = f"vd {-0.4 * s} {1.2 * s} {0.4 * s} vg {-0.3 * s} {1.2 * s} {0.3 * s}"
        data = ng.dc_sweep(net, sweep, ("v(g)", "v(d)", "v(b)", "i(vd)"))
        rows = [
            [float(data[p][k]) for p in ("v(g)", "v(d)", "v(b)")] for k in range(len(data["i(vd)"]))
        ]
        out["currents"].append({"name": name, "netlist": net, "v": rows,
                                "i_vd": [float(x) for x in data["i(vd)"]]})  # fmt: skip
    out["tunnelling"] = []
    for name, kind, card, w in TUNNELLING:
        s = -1.0 if kind == "PMOS" else 1.0
        net = level6.sweep_deck(54).format(
            kind=kind, card=ro_card(card, ("igcmod", "igbmod")),
            instance=f"L=0.1u W={w}u AD=5p PD=6u AS=5p PS=6u", vb=-0.3 * s)  # fmt: skip
        sweep = f"vd {-0.6 * s} {1.2 * s} {0.3 * s} vg {-1.0 * s} {1.2 * s} {0.2 * s}"
        probes = ("v(g)", "v(d)", "v(b)", "i(vd)", "i(vg)", "i(vb)")
        data = ng.dc_sweep(net, sweep, probes)
        n = len(data["i(vd)"])
        out["tunnelling"].append({
            "name": name, "netlist": net,
            "v": [[float(data[p][k]) for p in probes[:3]] for k in range(n)],
            **{p: [float(x) for x in data[p]] for p in probes[3:]},
        })  # fmt: skip
    for kind, instance, card in CHARGES:
        s = 1.0 if kind == "n" else -1.0
        grid = itertools.product([-0.5, 0.4, 1.2], [-0.5, 0.0, 0.6], [-0.5, 0.1])
        biases = [(s * g, s * d, s * b) for g, d, b in grid]
        q = _ngspice_charges(_charges_deck("mm", instance, biases, card), len(biases))
        out["charges"].append({"kind": kind, "instance": instance, "card": card,
                               "biases": biases, "q": q.tolist()})  # fmt: skip
    path = Path(__file__).with_name("bsim4_reference.json")
    path.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
