"""A BSIM3 inverter chain's read and first run against its number of stages.

python benchmarks/bsim3_scaling.py [--stages 2 8 32] [--run]

Each chain (``N`` CMOS inverters on ngspice's ``examples/Monte_Carlo/MC_ring.sp`` card
pair, abridged: BSIM3v3.3, capMod 3; stage k of its own W, L and junction areas, a 0.05 pF
load, a 0.2 ns input edge, 2 ns of transient) is read in a fresh process with the program
store and JAX's cache off (``DIRACVI_CACHE_DIR=""``), one BLAS thread. Printed per chain:
``spice.read``'s CPU seconds, the transistors, the *groups* they fall into when the
circuit is packed (``model/stacked.py``: one ``vmap`` per group, traced once), and with
``--run`` the first and a second ``spice.run``'s CPU seconds and the number of XLA
compilations of the first (``jax_log_compiles``). A part traced per device shows as one
group per transistor and a read growing by the part's trace (~0.2 s CPU) per device.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

sys.path.insert(0, str(ROOT / "tests"))
from _bsim3_cards import CARDS  # noqa: E402  (MC_ring.sp's cards, as the tests use them)


def chain(n: int) -> str:
    """``n`` BSIM3 inverters, stage k of its own sizes."""
    lines = [f"chain of {n} BSIM3 inverters", "vdd dd 0 3.3", "vin n0 0 pulse 0 3.3 0.1n 0.2n"]
    for k in range(n):
        w, ell, a = 1.0 + 0.25 * (k % 8), 0.35 + 0.05 * (k % 5), 3 + k % 4
        lines += [
            f"mn{k} n{k + 1} n{k} 0 0 n1 w={w}u l={ell}u as={a}p ad={a}p ps=4u pd=4u",
            f"mp{k} n{k + 1} n{k} dd dd p1 w={2 * w}u l=0.35u as={2 * a}p ad=7p ps=6u pd=6u",
        ]
    lines += [f"cl n{n} 0 0.05p", CARDS, ".tran 10p 2n", ".end"]
    return "\n".join(lines) + "\n"


CHILD = r"""
import json, logging, sys, time
import jax
from diracvi import spice
from diracvi.driver import events

compiles = []


class Count(logging.Handler):
    def emit(self, record):
        if "Finished XLA compilation" in record.getMessage():
            compiles.append(1)


for name in ("jax._src.dispatch", "jax._src.interpreters.pxla"):
    logging.getLogger(name).addHandler(Count())
jax.config.update("jax_log_compiles", True)
path, run = sys.argv[1], sys.argv[2] == "1"
t = time.process_time()
netlist = spice.read(path)
out = {"read": time.process_time() - t}
subs = netlist.system.subsystems
packed = events.packed_unless_switched(netlist.system)
if getattr(packed, "packed", False):
    groups = packed._packing.tables.members
else:  # (fewer parts than packing needs: each its own program)
    groups = [[i] for i in range(len(subs))]
out["transistors"] = sum(s.role == "transistor" for s in subs)
out["groups"] = sum(subs[int(g[0])].role == "transistor" for g in groups)
if run:
    for key in ("first", "second"):
        before, t = len(compiles), time.process_time()
        spice.run(netlist)
        out[key], out[key + "_compiles"] = time.process_time() - t, len(compiles) - before
print(json.dumps(out))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stages", type=int, nargs="+", default=[2, 8, 32])
    parser.add_argument("--run", action="store_true", help="also time two spice.run calls")
    args = parser.parse_args()
    env = os.environ | {"DIRACVI_CACHE_DIR": "", "OPENBLAS_NUM_THREADS": "1"}
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    print("stages transistors groups read_s first_s compiles second_s (CPU seconds)")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.stages:
            deck = Path(tmp) / f"chain{n}.cir"
            deck.write_text(chain(n))
            done = subprocess.run(
                [sys.executable, "-c", CHILD, str(deck), "1" if args.run else "0"],
                env=env, capture_output=True, text=True, check=True,
            )  # fmt: skip
            row = json.loads(done.stdout.strip().splitlines()[-1])
            line = f"{n:6d} {row['transistors']:11d} {row['groups']:6d} {row['read']:6.2f}"
            if "first" in row:
                line += f" {row['first']:7.2f} {row['first_compiles']:8d} {row['second']:8.2f}"
            print(line, flush=True)


if __name__ == "__main__":
    main()
