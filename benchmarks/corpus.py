"""The public-netlist corpus against ngspice: ``python benchmarks/corpus.py [options]``.

For every deck of ``tests/data/netlists/EXPECTED.toml``: run it through
``diracvi.spice.run(path)`` at its own settings, compare with the committed fine ngspice
reference (``tests/_corpus.py`` says how), time ngspice at the deck's own settings, and
print one table (deck, elements, what it needs beyond R C L K V I D, status, diracvi and
ngspice wall times, ngspice's own error at the deck's settings, diracvi's tightened
error) and a summary.

    --references        first regenerate every reference with ngspice 39 (reltol 1e-7,
                        TMAX = TSTEP/50 or the deck's reference_tmax_divisor; the
                        median of runs at the deck's reference_reltols if it has them;
                        a few minutes, one deck takes ~80 s)
    --only NAME         these decks only (repeatable)
    --markdown          the table as Markdown (docs/circuits.md)
    --write-expected    rewrite EXPECTED.toml's statuses from this run (keeps file/blob)
    --skip NAME         leave these decks out (repeatable)
    --rows FILE         append each deck's row to FILE as one JSON line when it is done
    --no-tightened      skip the tightened runs (EXPECTED's ``tightened`` settings)
    --step-error KIND   the sparse path's error control, ``doubling`` or ``truncation``
                        (``spice.run``'s ``step_error``; default: its own)

Times are wall-clock seconds of one call each, on whatever machine runs this: diracvi's
include reading, building, compiling and stepping (a first call in this process, with one
BLAS thread as the tests run; programs already in the on-disk cache, ``DIRACVI_CACHE_DIR``
or the user cache, are loaded rather than compiled), not the import of diracvi; ngspice's
include process start-up, at the deck's own tolerances and TMAX. On a shared machine wall
time grows with the others' load (at a load average of 12 on 2 cores a call's wall time is
several times its CPU time), so each deck's line on stderr and its ``--rows`` record also
give CPU seconds: diracvi's process CPU over the call (all its threads, compilation
included) and ngspice's child CPU. "ngspice at the deck's settings" is that ngspice run
(at the deck's own ``.tran`` and ``.options``, linear between its points) against the
same fine reference, by the same measure as diracvi's: where it is above 1e-3, agreement
to 1e-3 at the deck's own settings is more than ngspice itself does. For such a deck
``EXPECTED.toml``'s ``tightened`` gives settings (``reltol``, ``tmax``, … as
``spice.run`` takes them, the deck unedited) under which diracvi is run again against
the same reference: the column "tightened".
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import resource
import sys
import time
from pathlib import Path

# One BLAS thread, as the test suite runs (tests/conftest.py): the compiled loop's Newton
# factors a small dense Jacobian per iteration, and OpenBLAS's threads spin while they
# wait, so on a loaded machine each factorization takes tens of milliseconds instead of
# half of one (measured: a 158x158 LU 63 ms CPU with the default threads against 0.53 ms
# with one; ng_switch_osc's first 0.2 ns, 39 tries, 9.7 s against 0.31 s CPU). Set
# before NumPy is imported, which is when OpenBLAS reads it.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "src"))  # this checkout's diracvi, as the tests import it

import _corpus as corpus  # noqa: E402  (after the path set-up above)

SLOW_SECONDS = 10.0


def run_deck(
    name: str, entry: dict, *, references: bool, tightened: bool = True, step_error=None
) -> dict:
    deck = corpus.DATA / entry["file"]
    row = {"deck": name, "elements": corpus.elements(deck), "needs": corpus.needs(deck)}
    if references:
        grid, signals, seconds = corpus.reference_from_run(deck)
        corpus.write_reference(corpus.REFERENCES / f"{name}.csv.gz", grid, signals)
        row["fine_seconds"] = seconds
    t, ref = corpus.load_reference(name)
    from diracvi import spice

    t0, c0 = time.perf_counter(), time.process_time()
    try:
        result = spice.run(deck, step_error=step_error)
    except Exception as exc:  # every failure is a row of the table
        row["seconds"] = time.perf_counter() - t0
        row["cpu_seconds"] = time.process_time() - c0
        row["status"] = "refused"
        row["message"] = f"{type(exc).__name__}: {exc}"
    else:
        row["seconds"] = time.perf_counter() - t0
        row["cpu_seconds"] = time.process_time() - c0
        worst, _, missing = corpus.compare(result, t, ref)
        row["error"], row["missing"] = worst, missing
        row["solver"] = result.trajectory.solver
        row["steps"] = len(result.trajectory.h) if hasattr(result.trajectory, "h") else None
        row["status"] = "agrees" if worst <= corpus.TOL and not missing else "disagrees"
    try:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        names, data, row["ngspice_seconds"] = corpus.run_ngspice(deck, fine=False)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        row["ngspice_cpu_seconds"] = (after.ru_utime + after.ru_stime) - (
            before.ru_utime + before.ru_stime
        )
        row["ngspice_error"] = corpus.compare_ngspice(names, data, t, ref)[0]
    except Exception:
        row["ngspice_seconds"] = row["ngspice_error"] = row["ngspice_cpu_seconds"] = math.nan
    if tightened and "tightened" in entry:
        row.update(run_tightened(deck, entry["tightened"], t, ref, step_error))
    return row


def run_tightened(deck: Path, tight: dict, t, ref, step_error=None) -> dict:
    """diracvi on ``deck`` at EXPECTED's ``tightened`` settings, against the reference."""
    from diracvi import spice
    from diracvi.spice._tran import OVERRIDES

    settings = {k: v for k, v in tight.items() if k in OVERRIDES}
    out: dict = {"tightened_settings": settings}
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        result = spice.run(deck, step_error=step_error, **settings)
    except Exception as exc:
        out["tightened_error"] = math.inf
        out["tightened_message"] = f"{type(exc).__name__}: {exc}"
    else:
        worst, _, missing = corpus.compare(result, t, ref)
        out["tightened_error"] = math.inf if missing else worst
        out["tightened_steps"] = len(result.trajectory.h)
    out["tightened_seconds"] = time.perf_counter() - t0
    out["tightened_cpu_seconds"] = time.process_time() - c0
    return out


def tightened_cell(row: dict) -> str:
    """The table's "tightened" cell: the error and the settings, or "—"."""
    if "tightened_error" not in row:
        return "—"
    given = ", ".join(f"{k} {v:g}" for k, v in row["tightened_settings"].items())
    return f"{row['tightened_error']:.2g} ({given})"


def reason(row: dict) -> str:
    if row["status"] == "refused":
        # the first line naming a netlist line (a reader may list several problems)
        lines = [x.strip() for x in row["message"].splitlines() if x.strip()]
        first = next((x for x in lines if re.search(r"\bline \d+", x)), lines[0])
        first = re.sub(r"^\w+(Error|Exception): ", "", first)  # the class name is not the point
        return first.split(" (supported")[0].split(" (only")[0]
    if row["status"] == "disagrees":
        text = f"max error {row['error']:.2g} of peak"
        if row["missing"]:
            text += f"; missing {', '.join(row['missing'][:4])}"
        return text
    return f"max error {row['error']:.2g} of peak"


def table(rows: list[dict], markdown: bool) -> str:
    head = ["deck", "elements", "needs beyond R C L K V I D", "status", "detail", "diracvi s",
            "ngspice s", "ngspice at the deck's settings", "diracvi tightened"]  # fmt: skip
    body = [
        [
            r["deck"],
            r["elements"],
            ", ".join(r["needs"]) or "—",
            r["status"],
            reason(r).replace("|", "\\|").replace("[", "\\[").replace("]", "\\]")
            if markdown
            else reason(r),
            f"{r['seconds']:.2f}",
            f"{r['ngspice_seconds']:.2f}",
            f"{r['ngspice_error']:.2g}",
            tightened_cell(r),
        ]
        for r in rows
    ]
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(f"`{c}`" if j == 0 else c for j, c in enumerate(b)) + " |"
                  for b in body]  # fmt: skip
        return "\n".join(lines)
    widths = [max(len(str(x)) for x in col) for col in zip(head, *body, strict=True)]
    widths = [min(w, 70) for w in widths]
    fmt = "  ".join(f"{{:{w}.{w}}}" for w in widths)
    return "\n".join(fmt.format(*map(str, line)) for line in [head, *body])


def summary(rows: list[dict]) -> str:
    """The counts: diracvi at the decks' own settings; how many decks ngspice itself
    misses at their own settings (above TOL against the fine reference), and of those
    how many diracvi agrees on as written and how many more once tightened."""
    count = {s: sum(r["status"] == s for r in rows) for s in ("agrees", "disagrees", "refused")}
    ran = count["agrees"] + count["disagrees"]
    tol = corpus.TOL
    loose = [r for r in rows if not r["ngspice_error"] <= tol]  # NaN: ngspice failed
    as_written = sum(r["status"] == "agrees" for r in loose)
    others = [r for r in loose if r["status"] != "agrees"]
    tried = [r for r in others if "tightened_error" in r]
    converged = sum(r["tightened_error"] <= tol for r in tried)
    return (
        f"{len(rows)} decks (all run by ngspice 39): {ran} run through diracvi, "
        f"{count['agrees']} agree to {tol:g} of peak at the deck's own settings, "
        f"{count['disagrees']} disagree, {count['refused']} refused. ngspice itself, at the "
        f"deck's own settings, is off the fine reference by more than {tol:g} of peak on "
        f"{len(loose)}; of those, diracvi agrees on {as_written} as written, and of the "
        f"{len(others)} it does not, agrees when tightened (EXPECTED's `tightened`, the deck "
        f"unedited) on {converged} of the {len(tried)} run so"
    )


def tally(rows: list[dict]) -> str:
    """How many decks use each feature beyond today's reader (the table's survey)."""
    count: dict[str, list[str]] = {}
    for r in rows:
        for item in r["needs"]:
            count.setdefault(item, []).append(r["deck"])
    lines = ["decks needing each feature (a deck usually needs several):"]
    for item, decks in sorted(count.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        lines.append(f"  {len(decks):3d}  {item}")
    return "\n".join(lines)


def write_expected(rows: list[dict], expected: dict) -> None:
    """Rewrite EXPECTED.toml: the statuses of ``rows``, every other deck as it was."""
    done = {r["deck"]: r for r in rows}
    out = [
        "# What diracvi does with each corpus deck today (tests/test_corpus.py checks it).",
        "# status: agrees | disagrees (runs, off by more than 1e-3 of a peak) | refused",
        "# (then `match` must be in the error message). Regenerate the statuses with",
        "#     python benchmarks/corpus.py --write-expected",
        "# and update them by hand when support lands (the test says which).",
        "",
    ]
    for name, e in expected.items():
        out.append(f"[{name}]")
        out.append(f'file = "{e["file"]}"')
        out.append(f'blob = "{e["blob"]}"')
        r = done.get(name)
        own = r["ngspice_error"] if r is not None else e.get("ngspice_own")
        if own is not None and not math.isnan(own):
            out.append(f"ngspice_own = {own:.3g}")
        if r is None:
            for key in ("status", "match", "error", "slow"):
                if key in e:
                    value = e[key]
                    if isinstance(value, str):
                        value = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
                    elif isinstance(value, bool):
                        value = str(value).lower()
                    out.append(f"{key} = {value}")
            out.extend(_kept(e))
            out.append("")
            continue
        out.append(f'status = "{r["status"]}"')
        if r["status"] == "refused":
            match = reason(r).replace("\\", "\\\\").replace('"', '\\"')
            out.append(f'match = "{match}"')
        elif r["status"] == "disagrees":
            out.append(f"error = {r['error']:.3g}")
        if r["seconds"] > SLOW_SECONDS:
            out.append("slow = true")
        out.extend(_kept(e, r))
        out.append("")
    corpus.EXPECTED.write_text("\n".join(out))


def _kept(entry: dict, row: dict | None = None) -> list[str]:
    """What a rewrite keeps of a deck's entry besides its status: the reference's
    ``reference_tmax_divisor``, ``reference_reltols``, ``reference_options``,
    ``reference_random`` and ``tightened = { … }`` (its error re-measured when ``row`` ran it)."""
    out = []
    if "reference_tmax_divisor" in entry:
        out.append(f"reference_tmax_divisor = {entry['reference_tmax_divisor']!r}")
    if "reference_reltols" in entry:
        out.append(f"reference_reltols = {[float(r) for r in entry['reference_reltols']]!r}")
    if "reference_options" in entry:
        out.append(f'reference_options = "{entry["reference_options"]}"')
    if entry.get("reference_random"):
        out.append("reference_random = true")
    if "tightened" in entry:
        tight = dict(entry["tightened"])
        if row is not None and "tightened_error" in row:
            tight["error"] = float(f"{row['tightened_error']:.3g}")
        out.append("tightened = { " + ", ".join(f"{k} = {v!r}" for k, v in tight.items()) + " }")
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--references", action="store_true")
    parser.add_argument("--only", action="append", default=[])
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--write-expected", action="store_true")
    parser.add_argument("--skip", action="append", default=[])
    parser.add_argument("--rows", type=Path, help="append each deck's row here as JSON")
    parser.add_argument("--no-tightened", action="store_true")
    parser.add_argument("--step-error", choices=("doubling", "truncation"), default=None)
    args = parser.parse_args(argv)
    expected = corpus.load_expected()
    names = [n for n in expected if (not args.only or n in args.only) and n not in args.skip]
    rows = []
    for name in names:
        rows.append(
            run_deck(
                name,
                expected[name],
                references=args.references,
                tightened=not args.no_tightened,
                step_error=args.step_error,
            )
        )
        if args.rows:
            with args.rows.open("a") as f:
                f.write(json.dumps(rows[-1]) + "\n")
        print(
            f"{name}: {rows[-1]['status']} {reason(rows[-1])}; ngspice at the deck's "
            f"settings {rows[-1]['ngspice_error']:.2g}; tightened {tightened_cell(rows[-1])}; "
            f"wall {rows[-1]['seconds']:.2f} s "
            f"(CPU {rows[-1]['cpu_seconds']:.2f}, {rows[-1].get('steps')} steps) against ngspice's "
            f"{rows[-1]['ngspice_seconds']:.2f} s (CPU {rows[-1]['ngspice_cpu_seconds']:.3f})",
            file=sys.stderr,
            flush=True,
        )
    print(table(rows, args.markdown))
    print()
    print(summary(rows))
    print()
    print(tally(rows))
    if args.write_expected:
        write_expected(rows, expected)
    return 0


if __name__ == "__main__":
    sys.exit(main())
