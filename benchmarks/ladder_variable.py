"""RLC ladders run as a circuit engineer runs them: ``diracvi run ladder.cir`` without
``--dt`` (SPICE's variable steps; a linear circuit takes the sparse maps of
:mod:`diracvi.driver.adaptive_sparse`), beside ``ngspice -b`` (issues 30, 28).

    PYTHONPATH=src python benchmarks/ladder_variable.py 100 1000 10000

For each ladder of N stages (:func:`diracvi.bench.ladders.ladder`): ngspice's wall and CPU
seconds and peak RSS; ``diracvi run`` with the disk cache cold, then warm (a fresh
``DIRACVI_CACHE_DIR``, then the same again): wall and CPU seconds and peak RSS; then an
in-process ``spice.run`` and its max error / peak against ngspice over the probes of
:mod:`diracvi.bench.ladder_scaling` on the TSTEP grid, and the path that ran. CPU seconds
are the figure to compare on a loaded machine.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from diracvi.bench import ladder_scaling as bench
from diracvi.bench.ladders import ladder


def main(sizes: list[int]) -> None:
    for stages in sizes:
        text = ladder(stages)
        with tempfile.TemporaryDirectory() as name:
            tmp = Path(name)
            path = tmp / f"ladder{stages}.cir"
            path.write_text(text)
            wall, mb, t_ref, ref = bench._ngspice(text, tmp)
            print(f"{stages} stages: ngspice -b wall {wall:.2f} s, CPU "
                  f"{bench._NGSPICE_CPU[0]:.2f} s, RSS {mb:.0f} MB", flush=True)  # fmt: skip
            cache, cpu = tmp / "cache", []
            for label in ("cold", "warm"):
                wall, mb = bench._diracvi_run(path, None, cache, tmp, cpu=cpu)
                print(f"{stages} stages: diracvi run (no --dt), cache {label}: wall {wall:.1f} "
                      f"s, CPU {cpu[-1]:.1f} s, RSS {mb:.0f} MB", flush=True)  # fmt: skip
            t, c = time.perf_counter(), time.process_time()
            err, solver = bench._variable_agreement(text, t_ref, ref)
            print(f"{stages} stages: in-process spice.run wall {time.perf_counter() - t:.1f} s, "
                  f"CPU {time.process_time() - c:.1f} s; max error / peak vs ngspice "
                  f"{err:.2e}; path: {solver}", flush=True)  # fmt: skip


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [100, 1000])
