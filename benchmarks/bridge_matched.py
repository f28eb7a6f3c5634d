"""The full-wave bridge rectifier against ngspice at matched accuracy, in CPU seconds
(issue 30: "diode bridge rectifier ≤ 1× ngspice at matched accuracy").

    PYTHONPATH=src python benchmarks/bridge_matched.py            # both rows, min of 7
    PYTHONPATH=src python benchmarks/bridge_matched.py --repeats 3

The circuit is ``CIRCUITS["bridge"]`` of :mod:`diracvi.spice._ngspice` (4 diodes, 100 µF,
1 kΩ, a 10 V 50 Hz source on a 1 MΩ reference, 40 ms), measured as
``diracvi bench --only circuits`` measures it (:mod:`diracvi.bench.circuits`) but in CPU
seconds, which a loaded machine moves far less than wall seconds:

- the reference is ngspice at maximum step TSTOP/40000 and reltol 1e-7; an error is the
  max over t > 0 and the probes of ``|x − x_ref| / peak``;
- **variable**: ``spice.run(deck)`` as a user calls it (SPICE's variable steps at the
  deck's tolerances), its error at the run's own nodes; ngspice (trapezoidal, default
  tolerances) at maximum steps ``TSTEP·2^−j``, j = 0 … 7, the first at least as accurate
  timed;
- **fixed**: ``spice.run(deck, dt=h)`` at the circuit's test step; ngspice at ``h·2^j``,
  j = 3 … −3.

diracvi: a warm call's ``time.process_time()`` (min of the repeats; the first call, which
compiles, not counted), with the run's steps, tries and Newton iterations. ngspice: the
batch run's CPU (``RUSAGE_CHILDREN``), min of the repeats, minus an empty deck's (the
process's start-up and output). Run it beside another tree (``PYTHONPATH=…``) to compare
two versions: every row is measured in the same process.
"""

from __future__ import annotations

import argparse
import os
import resource
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from diracvi import spice
from diracvi.bench.circuits import EMPTY, _error
from diracvi.spice._ngspice import CIRCUITS, ngspice


def _cpu_children():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _ngspice_cpu(netlist, probes, tmax, repeats, options=".options"):
    best, out = float("inf"), None
    for _ in range(repeats):
        c0 = _cpu_children()
        out = ngspice(netlist, probes, tmax, options=options)
        best = min(best, _cpu_children() - c0)
    return best, out


def _dv_cpu(fn, repeats):
    fn()  # the first call compiles (or loads the stored program)
    best = float("inf")
    for _ in range(repeats):
        c0 = time.process_time()
        fn()
        best = min(best, time.process_time() - c0)
    return best


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    netlist, probes, h = CIRCUITS["bridge"]
    parsed = spice.read(netlist)
    ref_t, ref = ngspice(netlist, probes, tmax=parsed.stop / 40000)
    empty, _ = _ngspice_cpu(EMPTY, ("v(a)",), 1.0, args.repeats)
    rows = {
        "variable": (
            lambda: spice.run(parsed),
            lambda: spice.run(parsed, internal=True),
            [parsed.dt * 2.0**-j for j in range(8)],
        ),
        "fixed": (
            lambda: spice.run(parsed, dt=h),
            lambda: spice.run(parsed, dt=h),
            [h * 2.0**j for j in range(3, -4, -1)],
        ),
    }
    for name, (timed, measured, tmaxes) in rows.items():
        result = measured()
        err = _error(result.time, {p: result[p] for p in probes}, ref_t, ref, probes)
        cpu = _dv_cpu(timed, args.repeats)
        march = result.trajectory
        counts = (
            f"{len(march.h)} steps, {march.tries} tries, {march.iterations} Newton iterations"
            if name == "variable"
            else f"{len(result.time) - 1} steps"
        )
        for tmax in tmaxes:
            _, (ts, vs) = _ngspice_cpu(netlist, probes, tmax, 1)
            if _error(ts, vs, ref_t, ref, probes) <= err:
                ng_cpu, (ts, vs) = _ngspice_cpu(netlist, probes, tmax, args.repeats)
                ng_cpu = max(ng_cpu - empty, 1e-6)
                err_ng = _error(ts, vs, ref_t, ref, probes)
                print(
                    f"{name}: diracvi {cpu:.3f} CPU s (error {err:.2e}; {counts}) | "
                    f"ngspice {ng_cpu:.3f} CPU s (error {err_ng:.2e}, tmax {tmax:g}, "
                    f"{len(ts)} points; start-up {empty:.3f} s taken off) | "
                    f"ratio {cpu / ng_cpu:.2f}",
                    flush=True,
                )
                break
        else:
            print(f"{name}: diracvi {cpu:.3f} CPU s (error {err:.2e}); ngspice not as accurate")
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
