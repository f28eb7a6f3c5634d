"""Where a small netlist's variable-step run spends its time, beside ngspice's own count.

python benchmarks/small_nonlinear.py [--decks ng_rtlinv ng_schmitt …] [--warm-only]

Each deck runs in fresh processes — **cold** (an empty ``DIRACVI_CACHE_DIR``: nothing
compiled yet) and then **warm** (the cache the cold run filled) — and each process times its
phases in CPU seconds (user + system of the process, all its threads; on a shared machine
the wall clock moves with the others' load, the CPU time much less): importing diracvi,
reading the deck and building its system, the DC operating point, the variable-step march
(first call: loading or tracing, lowering and compiling its program, then stepping), the
march again in the same process (stepping only: the program is in memory), and resampling
onto the TSTEP grid. XLA compilations are counted per phase (``jax_log_compiles``), and
JAX's own event timings split the first march's CPU into tracing, lowering and XLA
compilation. The run's own counts: recorded steps, tries (each try is one step of ``H``
and two of ``H/2``), rejected tries, Newton iterations; µs per try is the second march's
CPU over its tries. Beside it ngspice ``-b`` on the same deck with ``.options acct``:
the child's CPU seconds (``os.wait4``), accepted and rejected timepoints and transient
Newton iterations.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _phases import child_source, table_head

HERE = Path(__file__).resolve().parent
NETLISTS = HERE.parent / "tests" / "data" / "netlists"
DECKS = ("ng_rtlinv", "ng_mos6_simpleinv", "ng_cntrl_sources", "ng_switches", "es_integrator")

CHILD = child_source(r"""
import json
split = jax_split()  # JAX's own event timings
netlist, settings, breaks = netlist_start(phases, sys.argv[1])
from diracvi import spice
from diracvi.spice import _run
mark = phases.mark
before = dict(split)
march = _run._march(netlist, settings, breaks)
mark("march")
split = {k: split[k] - before[k] for k in split}
again = _run._march(netlist, settings, breaks)
mark("march again")
spice.run(netlist)
mark("resample (+march)")
marks = {k: (c, n) for k, (_, c, n) in phases.marks.items()}  # CPU seconds, compilations
print(json.dumps({"marks": marks, "split": split, "steps": len(march.h),
                  "tries": int(again.tries), "rejected": int(again.rejected),
                  "newton": int(getattr(again, "iterations", 0)), "solver": march.solver}))
""")


def deck_path(name: str) -> Path:
    """The deck of a corpus name (its ``file`` in ``EXPECTED.toml``)."""
    import tomllib

    expected = tomllib.loads((NETLISTS / "EXPECTED.toml").read_text())
    if name not in expected:
        raise SystemExit(f"--decks {name}: not a corpus deck (see {NETLISTS / 'EXPECTED.toml'})")
    return NETLISTS / expected[name]["file"]


def child(deck: Path, env: dict, cwd: Path) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(deck)],
        env=env,
        cwd=cwd,
        capture_output=True,
        text=True,
    )
    if out.returncode != 0:
        raise SystemExit(f"{deck.name} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def ngspice(deck: Path, work: Path) -> dict:
    """ngspice -b on a copy of ``deck`` with ``.options acct`` after its title line (run
    beside the deck, so that its relative ``.include`` files are found): the child's CPU
    seconds and its transient counts."""
    lines = deck.read_text(errors="replace").splitlines()
    copy = work / f"acct-{deck.name}"
    copy.write_text("\n".join([lines[0], ".options acct", *lines[1:]]) + "\n")
    child = subprocess.Popen(
        ["ngspice", "-b", str(copy)], cwd=deck.parent, stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )  # fmt: skip
    text = child.stdout.read().decode(errors="replace")
    child.stdout.close()
    _, _, usage = os.wait4(child.pid, 0)

    def count(label):
        found = re.search(rf"{label}\s*=\s*(\d+)", text)
        return int(found.group(1)) if found else None

    return {
        "cpu": usage.ru_utime + usage.ru_stime,
        "accepted": count("Accepted timepoints"),
        "rejected": count("Rejected timepoints"),
        "newton": count("Transient iterations"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--decks", nargs="+", default=list(DECKS))
    parser.add_argument("--warm-only", action="store_true", help="skip the cold process")
    parser.add_argument("--json", type=Path, help="append each deck's numbers here")
    args = parser.parse_args()
    if shutil.which("ngspice") is None:
        raise SystemExit("ngspice is not on PATH: it is the baseline of this benchmark.")
    table_head("deck", "run", "import", "read", "op", "march (trace/lower/XLA)", "compiles",
               "again", "steps", "tries", "rejected", "Newton", "µs/try", "ngspice CPU",
               "ng steps/rej/Newton")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="diracvi-small-") as tmp:
        work = Path(tmp)
        for name in args.decks:
            deck = deck_path(name)
            cache = work / "cache"
            if not args.warm_only:
                shutil.rmtree(cache, ignore_errors=True)
            env = {**os.environ, "DIRACVI_CACHE_DIR": str(cache)}
            ng = ngspice(deck, work)
            for label in ("warm",) if args.warm_only else ("cold", "warm"):
                start = time.perf_counter()
                r = child(deck, env, work)
                wall = time.perf_counter() - start
                m, s = r["marks"], r["split"]
                compiles = sum(v[1] for v in m.values())
                print(
                    f"| {name} | {label} | {m['import'][0]:.2f} | {m['read'][0]:.2f} "
                    f"| {m['operating point'][0]:.2f} | {m['march'][0]:.2f} "
                    f"({s['trace']:.2f}/{s['lower']:.2f}/{s['compile']:.2f}) "
                    f"| {compiles} ({m['march'][1]} march) | {m['march again'][0]:.3f} "
                    f"| {r['steps']} | {r['tries']} | {r['rejected']} | {r['newton']} "
                    f"| {1e6 * m['march again'][0] / max(r['tries'], 1):.0f} "
                    f"| {ng['cpu']:.3f} | {ng['accepted']}/{ng['rejected']}/{ng['newton']} |",
                    flush=True,
                )
                if args.json:
                    with args.json.open("a") as f:
                        row = {"deck": name, "run": label, "wall": wall, **r, "ngspice": ng}
                        f.write(json.dumps(row) + "\n")
    print(f"load average at end: {os.getloadavg()[0]:.2f}")
    print("(CPU seconds per phase; 'again': the march a second time in the same process)")


if __name__ == "__main__":
    main()
