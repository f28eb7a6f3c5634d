"""Where the reading of an RLC ladder netlist goes, phase by phase, in CPU seconds (issue 30).

    PYTHONPATH=src python benchmarks/read_profile.py 10000

``spice.read`` of a ladder of N stages (:func:`diracvi.bench.ladders.ladder`: R, L, C per
stage, 3N + 1 elements), after a small ladder read first (imports and first-use costs
out of the way). Each phase is the CPU time of the functions named, measured by wrapping
them (nested phases are included in their parent); no run, so it needs little memory
(``benchmarks/ladder_profile.py`` times the run too).
"""

from __future__ import annotations

import os
import sys
import time


def main() -> None:
    os.environ["DIRACVI_CACHE_DIR"] = ""
    from diracvi import spice
    from diracvi.bench.ladders import ladder
    from diracvi.components import electrical, network
    from diracvi.model import interconnect
    from diracvi.spice import _parse

    spent: dict[str, float] = {}
    order: list[str] = []  # the phases as declared (nested ones after their parent)

    def timed(owner, attr, label):
        original = getattr(owner, attr)

        def wrapper(*a, **k):
            start = time.process_time()
            try:
                return original(*a, **k)
            finally:
                spent[label] = spent.get(label, 0.0) + time.process_time() - start

        setattr(owner, attr, wrapper)
        order.append(label)

    timed(_parse, "read_body", "elements read (parse, construction, Circuit.add)")
    timed(electrical, "_like", "  R, L, C construction")
    timed(network.Circuit, "add", "  Circuit.add")
    timed(_parse, "add_shunts", "GMIN islands")
    timed(network.Circuit, "build", "Circuit.build")
    timed(network, "interconnect", "  interconnect")
    timed(network.Circuit, "_check_topology", "  topology checks")
    timed(network, "_momenta", "  initial momenta")
    timed(interconnect.InterconnectedSystem, "_packed", "    packing alike parts")
    for n in (int(x) for x in sys.argv[1:] or ["10000"]):
        spice.read(ladder(10, steps=2000))
        spent.clear()
        text = ladder(n, steps=2000)
        start = time.process_time()
        spice.read(text)
        total = time.process_time() - start
        print(f"spice.read, {n} stages ({3 * n + 1} elements): {total:.3f} CPU s")
        for label in order:
            print(f"  {label:52s} {spent.get(label, 0.0):8.3f}")


if __name__ == "__main__":
    main()
