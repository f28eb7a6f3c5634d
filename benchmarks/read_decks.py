"""CPU seconds of ``spice.read`` on public decks and on synthetic decks of 10³–10⁴ elements
(issue 30: reading linear in the element count).

    PYTHONPATH=src python benchmarks/read_decks.py [deck.cir ...] [--ladder N] [--chain N]
        [--inverters N] [--sized N]

Each deck is read in a fresh process (``DIRACVI_CACHE_DIR=""``) after a small ladder
(imports and first-use costs out of the way), from the deck's own directory (its
``.include`` files). ``--ladder N``: :func:`diracvi.bench.ladders.ladder` of N stages
(3N + 1 elements, no subcircuit); ``--chain N``: the same RLC stage as a ``.subckt``
instantiated N times in a chain (3N elements behind N ``X`` lines); ``--inverters N``: N
CMOS inverters (level 1, bulk junction and overlap capacitances, a load capacitor) of one
``.subckt`` in a chain (3N elements; the cards' ``COX`` is not a level-1 parameter, so
ngspice and diracvi ignore it with a note: without ``TOX`` there are no Meyer
capacitances). Every inverter's transistors are alike: the reader builds each of the two
parts once (``spice/_cards.py: built``); ``--sized N``: the same with each instance of its
own width (``params: w``), so every transistor is built.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

_CHILD = r"""
import json, os, sys, time
from pathlib import Path
from diracvi import spice
from diracvi.bench.ladders import ladder
kind, arg = sys.argv[1], sys.argv[2]
spice.read(ladder(3, steps=20))
if kind == "deck":
    os.chdir(Path(arg).parent)
    source = Path(arg)
elif kind == "ladder":
    source = ladder(int(arg), steps=2000)
elif kind in ("inverters", "sized"):
    n = int(arg)
    sized = kind == "sized"  # each instance its own width: no two transistors alike
    lines = ["CMOS inverter chain", ".subckt inv in out vdd" + " params: w=1u" * sized,
             "M1 out in vdd vdd p1 W={2*w} L=1u" if sized else "M1 out in vdd vdd p1 W=2u L=1u",
             "M2 out in 0 0 n1 W={w} L=1u" if sized else "M2 out in 0 0 n1 W=1u L=1u",
             "C1 out 0 10f", ".ends inv",
             ".model n1 nmos level=1 vto=0.7 kp=1e-4 cbd=1f cgso=1e-10 cox=1e-3",
             ".model p1 pmos level=1 vto=-0.7 kp=5e-5 cbd=1f cgso=1e-10 cox=1e-3",
             "VDD vdd 0 3.3", "VIN n0 0 PULSE(0 3.3 1n 1n 1n 10n 20n)"]
    width = (lambda k: f" w={1 + k * 1e-4:.6g}u") if sized else (lambda k: "")
    lines += [f"X{k} n{k - 1} n{k} vdd inv{width(k)}" for k in range(1, n + 1)]
    source = "\n".join([*lines, ".tran 0.1n 40n", ".end", ""])
else:
    n = int(arg)
    lines = ["RLC chain of subcircuits", ".subckt stage a b", "R1 a m 10", "L1 m b 1m",
             "C1 b 0 1u", ".ends stage", "V1 n0 0 SIN(0 1 1k)"]
    lines += [f"X{k} n{k - 1} n{k} stage" for k in range(1, n + 1)]
    source = "\n".join([*lines, ".tran 1u 2m uic", ".end", ""])
start = time.process_time()
spice.read(source)
print(json.dumps({"read": time.process_time() - start}))
"""


def measure(kind: str, arg: str) -> float:
    env = os.environ | {"DIRACVI_CACHE_DIR": "", "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-c", _CHILD, kind, arg], env=env, capture_output=True, text=True
    )
    if out.returncode:
        return float("nan")
    return json.loads(out.stdout.strip().splitlines()[-1])["read"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("decks", nargs="*", help="netlists to read (each in a fresh process)")
    for kind, what in (("ladder", "an RLC ladder of N stages"),
                       ("chain", "N RLC .subckt stages in a chain"),
                       ("inverters", "N level-1 CMOS inverter .subckt instances"),
                       ("sized", "the same, each instance of its own width")):  # fmt: skip
        parser.add_argument(f"--{kind}", type=int, action="append", default=[], metavar="N",
                            help=what)  # fmt: skip
    args = parser.parse_args()
    jobs = [("deck", os.path.abspath(d)) for d in args.decks]
    for kind in ("ladder", "chain", "inverters", "sized"):
        jobs += [(kind, str(n)) for n in getattr(args, kind)]
    with open("/proc/loadavg") as f:
        print(f"load average at start: {f.read().split()[0]}")
    for kind, arg in jobs:
        label = arg if kind == "deck" else f"{kind} {arg}"
        print(f"{measure(kind, arg):9.3f} CPU s  {label}", flush=True)


if __name__ == "__main__":
    main()
