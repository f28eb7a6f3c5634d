"""Are the corpus's references converged? ``python benchmarks/reference_audit.py [options]``.

Each committed reference (``tests/data/netlists/reference/<deck>.csv.gz``) is ngspice 39
at the deck's own ``.tran`` with ``reltol = 1e-7`` and ``TMAX = TSTEP/d``, ``d`` = 50 or
the deck's ``reference_tmax_divisor`` (``tests/_corpus.py``). This runs ngspice the same
way (the same wrapper deck, ``_corpus.wrapper``) with ``TMAX`` ``--factor`` times smaller
(``d' = factor · d``; default 10) at the same ``reltol`` (or ``--reltol``), and measures
the committed reference against that finer run by the corpus's own measure
(``_corpus.compare_ngspice``: over the reference's points from TSTART on, the finer run
linear between its own points, each signal's error divided by its peak over the
reference's points, worst signal reported). The finer run's own points do not fall on the
reference's, so that measure holds the linear interpolant's error of the finer run too:
O(h'^2 |f''|) at its spacing h', which on a diode's knee at 50 Hz (es_clipper, h' = 20 µs)
is 6.6e-4 of peak where the reference itself is within 6.4e-6 (``--factor 100``). The
column "PCHIP" is the same comparison with the finer run sampled by its monotone cubic
(scipy's ``PchipInterpolator``, no overshoot at a corner), whose error on smooth stretches
is a power of h' higher; where the two columns differ, the interpolant, not the
reference, is what was measured. So the error of the reference against its
``factor``-times finer run is read as the reference's own error; above 1e-4 of peak it is
a tenth of the corpus's 1e-3 tolerance, and the deck is a candidate for a finer reference.

Each ngspice run gets a CPU limit of ``--cpu`` seconds (default 120; ``RLIMIT_CPU`` in
the child, so load does not count) and is recorded as a timeout past it. The CPU column
is the child's user + system seconds. The deck's own ``.tran`` TMAX, when smaller than
``TSTEP/d``, bounds both runs (``_corpus.wrapper``), so the refinement is then less than
``factor``: the column ``refined`` gives the ratio of the two runs' TMAX actually used.

    python benchmarks/reference_audit.py                  # every deck, agreeing ones first
    python benchmarks/reference_audit.py --only xy_rlc    # repeatable; --skip NAME too
    options: --factor 10  --reltol 1e-7  --cpu 120  --markdown  --rows FILE (JSON lines)
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import numpy as np  # noqa: E402
from scipy.interpolate import PchipInterpolator  # noqa: E402

import _corpus as corpus  # noqa: E402  (after the path set-up above)

CANDIDATE = 1e-4  # a tenth of corpus.TOL


def tmax_used(tran: corpus.Tran, divisor: float) -> float:
    """The TMAX ``_corpus.wrapper`` gives a fine run at ``divisor``."""
    tmax = tran.step / divisor
    return min(tmax, tran.tmax) if tran.tmax else tmax


def run_limited(deck: Path, divisor: float, reltol: float, cpu: float):
    """ngspice on ``deck`` as ``_corpus.run_ngspice(fine=True)`` runs it, under a CPU limit:
    ``(names, data, cpu_seconds)``, or ``(None, None, cpu_seconds)`` past the limit."""
    text = deck.read_text(errors="replace")
    tran = corpus.find_tran(text)

    def limit():
        resource.setrlimit(resource.RLIMIT_CPU, (int(cpu), int(cpu) + 5))

    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "out.raw"
        cir = Path(tmp) / "wrapper.cir"
        cir.write_text(corpus.wrapper(text, tran, raw, fine=True, divisor=divisor, reltol=reltol))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        proc = subprocess.run(
            [shutil.which("ngspice") or "/usr/bin/ngspice", "-b", str(cir)],
            cwd=deck.parent,  # its relative .include files
            capture_output=True,
            text=True,
            preexec_fn=limit,
        )
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        used = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
        # past the CPU limit ngspice is killed (SIGXCPU, then SIGKILL) before its `write`;
        # a crash after it is not a timeout: on some Xyce line decks (xy_tra_bug1284_baseline)
        # ngspice 39 goes on past the wrapper's `write` and dies (SIGSEGV), the raw file
        # complete (its last point at TSTOP), as it is when a reference is made
        killed = proc.returncode in (-signal.SIGXCPU, -signal.SIGKILL)
        if killed or not raw.exists():
            return None, None, used
        names, data = corpus.read_raw(raw, corpus.kept)  # what a reference keeps
    return names, data, used


def audit(name: str, entry: dict, factor: float, reltol: float, cpu: float) -> dict:
    deck = corpus.DATA / entry["file"]
    tran = corpus.find_tran(deck.read_text(errors="replace"))
    divisor = corpus.reference_divisor(deck)
    row = {
        "deck": name,
        "status": entry.get("status"),
        "divisor": divisor,
        "audit_divisor": divisor * factor,
        "refined": tmax_used(tran, divisor) / tmax_used(tran, divisor * factor),
    }
    t, ref = corpus.load_reference(name)
    names, data, row["cpu"] = run_limited(deck, divisor * factor, reltol, cpu)
    if names is None:
        row["error"], row["worst"] = None, "timeout"
        return row
    row["points"] = len(data)
    worst, errors, missing = corpus.compare_ngspice(names, data, t, ref)
    row["error"] = worst
    row["worst"] = max(errors, key=errors.get) if errors else ""
    row["missing"] = missing
    row["error_pchip"] = pchip_error(names, data, t, ref)
    return row


def pchip_error(names: list[str], data: np.ndarray, t: np.ndarray, ref) -> float:
    """``_corpus.compare_ngspice``'s worst error with the run sampled by its PCHIP
    interpolant instead of linearly (a repeated time point, a breakpoint written twice,
    keeps its later value)."""
    times = data[:, 0]
    keep = np.append(np.diff(times) > 0, True)
    inside = t >= times[0]
    t = t[inside]
    ref = {k: v[inside] for k, v in ref.items()}
    have = {n: PchipInterpolator(times[keep], data[keep, j])(t) for j, n in enumerate(names) if j}
    return corpus.compare_sampled(have, (times[0], times[-1]), t, ref)[0]


def line(row: dict, markdown: bool) -> str:
    err = "timeout" if row["error"] is None else f"{row['error']:.2g}"
    cells = [
        row["deck"],
        str(row["status"]),
        f"{row['divisor']:g}",
        f"{row['audit_divisor']:g}"
        + (
            ""
            if row["refined"] > 0.99 * row["audit_divisor"] / row["divisor"]
            else f" (TMAX only {row['refined']:.3g}x smaller)"
        ),
        err,
        "" if row["error"] is None else f"{row['error_pchip']:.2g}",
        row["worst"],
        f"{row['cpu']:.1f}",
    ]
    return "| " + " | ".join(cells) + " |" if markdown else "  ".join(cells)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", action="append", default=[])
    parser.add_argument("--skip", action="append", default=[])
    parser.add_argument("--factor", type=float, default=10.0)
    parser.add_argument("--reltol", type=float, default=corpus.RELTOL)
    parser.add_argument("--cpu", type=float, default=120.0)
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--rows", type=Path, help="append each deck's row here as JSON")
    args = parser.parse_args(argv)
    expected = corpus.load_expected()
    names = [n for n in expected if (not args.only or n in args.only) and n not in args.skip]
    names.sort(key=lambda n: expected[n].get("status") != "agrees")  # stable: agreeing first
    header = ["deck", "status", "ref. divisor", "audit divisor", "ref. vs audit", "PCHIP",
              "worst signal", "ngspice CPU s"]  # fmt: skip
    print("| " + " | ".join(header) + " |" if args.markdown else "  ".join(header))
    if args.markdown:
        print("|" + "---|" * len(header))
    rows = []
    for name in names:
        if not (corpus.REFERENCES / f"{name}.csv.gz").is_file():
            continue
        rows.append(audit(name, expected[name], args.factor, args.reltol, args.cpu))
        if args.rows:
            with args.rows.open("a") as f:
                f.write(json.dumps(rows[-1]) + "\n")
        print(line(rows[-1], args.markdown), flush=True)
    # a candidate: over CANDIDATE by both samplings of the finer run (or no finer run)
    over = [r for r in rows if r["error"] is None or min(r["error"], r["error_pchip"]) > CANDIDATE]
    print(f"\n{len(rows)} decks audited (load {os.getloadavg()[0]:.1f}); over {CANDIDATE:g} of "
          f"peak or timed out: " + (", ".join(r["deck"] for r in over) or "none"))  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
