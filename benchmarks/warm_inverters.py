"""CPU seconds of repeated ``spice.run`` calls on N sized level-1 CMOS inverters (5 ns).

    PYTHONPATH=src taskset -c 1 python benchmarks/warm_inverters.py [N] [--calls 4] [--netlist]

The deck is ``benchmarks/read_decks.py --sized N``'s (each instance its own width, so
every transistor is a distinct part) with ``.tran 0.1n 5n`` (51 points): the first call
compiles or loads its programs, the later ones are warm. Each call reads the text again
(and solves the new netlist's operating point); ``--netlist`` reads it once and passes the
``Netlist``. To compare two trees, run this alternately with ``PYTHONPATH=<tree>/src``.
"""

from __future__ import annotations

import argparse
import time

from diracvi import spice


def deck(n: int) -> str:
    lines = ["CMOS inverter chain", ".subckt inv in out vdd params: w=1u",
             "M1 out in vdd vdd p1 W={2*w} L=1u", "M2 out in 0 0 n1 W={w} L=1u",
             "C1 out 0 10f", ".ends inv",
             ".model n1 nmos level=1 vto=0.7 kp=1e-4 cbd=1f cgso=1e-10 cox=1e-3",
             ".model p1 pmos level=1 vto=-0.7 kp=5e-5 cbd=1f cgso=1e-10 cox=1e-3",
             "VDD vdd 0 3.3", "VIN n0 0 PULSE(0 3.3 1n 1n 1n 10n 20n)"]  # fmt: skip
    lines += [f"X{k} n{k - 1} n{k} vdd inv w={1 + k * 1e-4:.6g}u" for k in range(1, n + 1)]
    return "\n".join([*lines, ".tran 0.1n 5n", ".end", ""])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=10, help="inverters (default 10)")
    parser.add_argument("--calls", type=int, default=4)
    parser.add_argument("--netlist", action="store_true", help="read once, run the Netlist")
    args = parser.parse_args()
    source = deck(args.n)
    if args.netlist:
        source = spice.read(source)
    with open("/proc/loadavg") as f:
        print(f"load average at start: {f.read().split()[0]}")
    times = []
    for _ in range(args.calls):
        start = time.process_time()
        spice.run(source)
        times.append(time.process_time() - start)
    warm = f", min of the warm ones {min(times[1:]):.2f}" if len(times) > 1 else ""
    print("CPU s per call: " + ", ".join(f"{t:.2f}" for t in times) + warm)


if __name__ == "__main__":
    main()
