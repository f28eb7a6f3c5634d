"""Where a ladder's variable-step run spends its memory and time, phase by phase (issue 30:
memory O(N)).

    PYTHONPATH=src python benchmarks/ladder_memory.py 1000 3000
    PYTHONPATH=src python benchmarks/ladder_memory.py --probes 10000

For each ladder of N stages (:func:`diracvi.bench.ladders.ladder`, 2000 steps of 1 µs;
``--probes``: a ``.save`` of the probes of :mod:`diracvi.bench.ladder_scaling`, so the
output is three vectors, not every node), one ``spice.read`` and one ``spice.run`` of the
netlist in this process (without ``--dt``: SPICE's variable steps, the sparse maps of
:mod:`diracvi.driver.adaptive_sparse` for a linear circuit). A thread samples the
process's resident memory every 20 ms; each phase (the functions named, wrapped) is
printed with its CPU seconds, the resident memory at its start and its peak, and the
growth it left (summed over its calls). Phases: ``read`` (``spice.read``), ``packing``
(the alike parts' stacks), ``sparse maps`` (each probed and assembled step map),
``march`` (the whole variable-step loop, the maps included), ``output`` (after the march:
the waveforms on the TSTEP grid). One run per process: the resident memory of one never
returns to the OS before the next.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


class _Sampler(threading.Thread):
    """The resident memory every ``period`` seconds, as ``(wall time, MB)``."""

    def __init__(self, period: float = 0.02):
        super().__init__(daemon=True)
        self.period, self.samples, self.done = period, [], threading.Event()

    def run(self) -> None:
        while not self.done.is_set():
            self.samples.append((time.perf_counter(), _rss_mb()))
            time.sleep(self.period)

    def peak(self, a: float, b: float) -> float:
        inside = [mb for t, mb in self.samples if a <= t <= b]
        return max(inside, default=_rss_mb())


def main(stages: int, probes: bool) -> None:
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    from diracvi import spice
    from diracvi.bench import ladder_scaling as bench
    from diracvi.bench.ladders import ladder
    from diracvi.driver import adaptive_sparse
    from diracvi.model import interconnect
    from diracvi.spice import _run

    spans: dict[str, list] = {}  # phase -> [(wall start, wall end, cpu, rss before, after)]

    def timed(owner, attr, label):
        original = getattr(owner, attr)

        def wrapper(*a, **k):
            t, c, before = time.perf_counter(), time.process_time(), _rss_mb()
            try:
                return original(*a, **k)
            finally:
                span = (t, time.perf_counter(), time.process_time() - c, before, _rss_mb())
                spans.setdefault(label, []).append(span)

        setattr(owner, attr, wrapper)

    timed(interconnect.InterconnectedSystem, "_packed", "packing")
    timed(adaptive_sparse, "build", "sparse maps")
    timed(_run, "adaptive_sparse", "march")
    text = ladder(stages)
    if probes:
        body, _, tail = text.rpartition(".end")
        text = body + f".save {' '.join(bench.PROBES)}\n.end" + tail
    sampler = _Sampler()
    sampler.start()
    base = _rss_mb()
    t, c = time.perf_counter(), time.process_time()
    netlist = spice.read(text)
    spans["read"] = [(t, time.perf_counter(), time.process_time() - c, base, _rss_mb())]
    t0, c0 = time.perf_counter(), time.process_time()
    result = spice.run(netlist)
    end, cpu = time.perf_counter(), time.process_time() - c0
    march_end = spans["march"][-1][1]
    march_cpu = sum(s[2] for s in spans["march"])
    after = spans["march"][-1][4]
    spans["output"] = [(march_end, end, cpu - march_cpu, after, _rss_mb())]
    sampler.done.set()
    sampler.join()
    saved = len(result.names) if hasattr(result, "names") else len(list(result))
    print(
        f"{stages} stages ({3 * stages + 1} elements, {saved} saved vectors): resident "
        f"memory {base:.0f} MB after the imports"
    )
    print(f"  {'phase':12s} {'calls':>5s} {'CPU s':>8s} {'RSS at start':>13s} {'peak':>8s} "
          f"{'left':>8s}")  # fmt: skip
    for label in ("read", "packing", "sparse maps", "march", "output"):
        rows = spans.get(label, [])
        if not rows:
            continue
        peak = max(max(sampler.peak(a, b), after) for a, b, _, _, after in rows)
        print(
            f"  {label:12s} {len(rows):5d} {sum(r[2] for r in rows):8.2f} "
            f"{rows[0][3]:10.0f} MB {peak:5.0f} MB {sum(r[4] - r[3] for r in rows):+6.0f} MB"
        )
    print(f"  spice.run total: CPU {cpu:.2f} s, wall {end - t0:.2f} s; peak RSS "
          f"{max(mb for _, mb in sampler.samples):.0f} MB")  # fmt: skip


if __name__ == "__main__":
    flags = {a for a in sys.argv[1:] if a.startswith("--")}
    if flags - {"--probes"}:
        raise SystemExit(f"unknown options {sorted(flags - {'--probes'})}: --probes")
    sizes = [int(a) for a in sys.argv[1:] if not a.startswith("--")] or [1000]
    if len(sizes) == 1:
        main(sizes[0], "--probes" in flags)
    else:  # one process per ladder (see the docstring)
        for n in sizes:
            subprocess.run([sys.executable, __file__, str(n), *sorted(flags)], check=True)
