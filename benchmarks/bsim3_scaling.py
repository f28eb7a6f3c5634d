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

# ngspice's examples/Monte_Carlo/MC_ring.sp cards, abridged (its binning-free core)
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
