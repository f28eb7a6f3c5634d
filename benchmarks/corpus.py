"""The public-netlist corpus against ngspice: ``python benchmarks/corpus.py [options]``.

For every deck of ``tests/data/netlists/EXPECTED.toml``: run it through
``diracvi.spice.run(path)`` at its own settings, compare with the committed fine ngspice
reference (``tests/_corpus.py`` says how), time ngspice at the deck's own settings, and
print one table (deck, elements, what it needs beyond R C L K V I D, status, diracvi and
ngspice wall times) and a summary.

    --references        first regenerate every reference with ngspice 39 (reltol 1e-7,
                        TMAX = TSTEP/50 or the deck's reference_tmax_divisor; a few
                        minutes, one deck takes ~80 s)
    --only NAME         these decks only (repeatable)
    --markdown          the table as Markdown (docs/circuits.md)
    --write-expected    rewrite EXPECTED.toml's statuses from this run (keeps file/blob)
    --skip NAME         leave these decks out (repeatable)
    --rows FILE         append each deck's row to FILE as one JSON line when it is done

Times are wall-clock seconds of one call each, on whatever machine runs this: diracvi's
include reading, building, compiling and stepping (a first call in this process, with one
BLAS thread as the tests run; programs already in the on-disk cache, ``DIRACVI_CACHE_DIR``
or the user cache, are loaded rather than compiled), not the import of diracvi; ngspice's
include process start-up, at the deck's own tolerances and TMAX. On a shared machine wall
time grows with the others' load (at a load average of 12 on 2 cores a call's wall time is
several times its CPU time), so each deck's line on stderr and its ``--rows`` record also
give CPU seconds: diracvi's process CPU over the call (all its threads, compilation
included) and ngspice's child CPU. "ngspice's own error" is that ngspice run (at the
deck's own settings, linear between its points) against the same fine reference, by the
same measure as diracvi's.
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


def run_deck(name: str, entry: dict, *, references: bool) -> dict:
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
        result = spice.run(deck)
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
    return row


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
            "ngspice s", "ngspice's own error"]  # fmt: skip
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
    count = {s: sum(r["status"] == s for r in rows) for s in ("agrees", "disagrees", "refused")}
    ran = count["agrees"] + count["disagrees"]
    return (
        f"{len(rows)} decks (all run by ngspice 39): {ran} run through diracvi, "
        f"{count['agrees']} agree to {corpus.TOL:g} of peak, {count['disagrees']} disagree, "
        f"{count['refused']} refused"
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
        if r is None:
            for key in ("status", "match", "error", "slow"):
                if key in e:
                    value = e[key]
                    if isinstance(value, str):
                        value = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
                    elif isinstance(value, bool):
                        value = str(value).lower()
                    out.append(f"{key} = {value}")
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
        out.append("")
    corpus.EXPECTED.write_text("\n".join(out))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--references", action="store_true")
    parser.add_argument("--only", action="append", default=[])
    parser.add_argument("--markdown", action="store_true")
    parser.add_argument("--write-expected", action="store_true")
    parser.add_argument("--skip", action="append", default=[])
    parser.add_argument("--rows", type=Path, help="append each deck's row here as JSON")
    args = parser.parse_args(argv)
    expected = corpus.load_expected()
    names = [n for n in expected if (not args.only or n in args.only) and n not in args.skip]
    rows = []
    for name in names:
        rows.append(run_deck(name, expected[name], references=args.references))
        if args.rows:
            with args.rows.open("a") as f:
                f.write(json.dumps(rows[-1]) + "\n")
        print(
            f"{name}: {rows[-1]['status']} {reason(rows[-1])}; ngspice's own "
            f"{rows[-1]['ngspice_error']:.2g}; wall {rows[-1]['seconds']:.2f} s "
            f"(CPU {rows[-1]['cpu_seconds']:.2f}) against ngspice's "
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
