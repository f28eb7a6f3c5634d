"""The public-netlist corpus: decks, their fine ngspice references, and the comparison.

``tests/data/netlists/`` holds public SPICE decks written by others, unedited (sources in
``SOURCES.md``), and ``reference/<deck>.csv.gz``: ngspice 39 at the deck's own ``.tran``
but with ``reltol=1e-7`` and ``TMAX = TSTEP/50``, at ngspice's *own* time points from
TSTART on (the values it computed, none interpolated), thinned to every m-th point with
m the smallest that keeps at most ``MAX_POINTS`` (the last point always kept), plus each
kept signal's min and max over those times, where its peak is (at most 2 points a signal
more): see :func:`thin`. The points are at most ``TSTEP/50`` apart before thinning, so a
deck's waveform is resolved even when its TSTEP grid is not (the eSim 50 Hz decks print every
10 ms, which meets their sines only at the zero crossings), and they include ngspice's
breakpoints; times are written to 17 digits (references written before that change hold
10), values to 10. ``python benchmarks/corpus.py --references`` rewrites them.
A deck's ``reference_reltols`` in ``EXPECTED.toml`` makes its reference the median of
fine runs at those ``reltol`` (:func:`reference_from_run`).
``EXPECTED.toml`` says what diracvi does with each deck today; a deck's
``reference_tmax_divisor`` there replaces the 50 (ngspice's first step is a tenth of
TMAX, taken by backward Euler: across ``xy_minductors``'s 1 µs L/R start at 0.2 µs it
left the reference 0.018 of peak off its closed form, 3.3e-4 at TSTEP/500), and its
``reference_options`` adds ngspice ``.options`` to the fine run (:func:`reference_options`).

Names: ngspice's raw file calls a node voltage ``v(n)`` and a branch current ``i(name)``,
as diracvi does; they are matched case-insensitively. Kept are the node voltages and the
currents of voltage sources and inductors (:func:`kept`). An element inside a subcircuit,
which ngspice 39 calls ``<letter>.<instance>.<name>`` (``i(v.x1.vm)``), is also looked up
as ``i(<instance>.<name>)``.

Agreement: for each reference signal ``s``, ``max_k |diracvi(t_k) − s(t_k)| ≤ TOL · max(max_k
|s(t_k)|, floor)`` over the reference's points ``t_k`` (the peak too is taken over them;
they hold the fine run's own peak of each signal, so it is the signal's real peak and the
point where it occurs is compared: a burst in ngspice's own run is a point diracvi is
judged at, not only a larger peak),
with diracvi's waveform sampled at ``t_k`` by its own interpolant (``Result.at``: quadratic
through its step centres between corners, as it fills the TSTEP grid). The floor is
SPICE's default absolute resolution of the signal's kind — ``VNTOL`` = 1 µV for a node
voltage, ``ABSTOL`` = 1 pA for a current — so that a signal which is zero to within
what any SPICE resolves (a node ngspice reports at 8.9e-16 V and diracvi at exactly 0)
is not judged relative to its own round-off; a signal whose peak is above the floor is
judged exactly as before.
"""

from __future__ import annotations

import ast
import gzip
import io
import re
import shutil
import subprocess
import tempfile
import time
import tomllib
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

DATA = Path(__file__).parent / "data" / "netlists"
REFERENCES = DATA / "reference"
EXPECTED = DATA / "EXPECTED.toml"
TOL = 1e-3
VNTOL = 1e-6  # SPICE's default absolute tolerance of node voltages (V) ...
ABSTOL = 1e-12  # ... and of branch currents (A): the floor of a signal's "peak"
MAX_POINTS = 2001  # the every-m-th points; thin() adds at most 2 a signal (its min, max)
RELTOL = 1e-7
TMAX_DIVISOR = 50


# ------------------------------------------------------------------ the deck's .tran


@dataclass(frozen=True)
class Tran:
    """A transient request: ``tran TSTEP TSTOP [TSTART [TMAX]] [UIC]``."""

    step: float
    stop: float
    start: float = 0.0
    tmax: float | None = None
    uic: bool = False


def thin(t: np.ndarray, start: float = 0.0, signals=()) -> np.ndarray:
    """Indices of the kept reference points: those at or after ``start``, every m-th
    with the smallest m leaving at most ``MAX_POINTS`` (the last one always kept), and,
    for each array ``s`` of ``signals`` (values at every ``t``), the points of its min and
    max over the same span, where its peak ``max |s|`` is: every-m-th points alone keep
    ``xy_sandler1``'s ``i(v.x4.vofst)`` at 4.0 pA of its 61 pA, and a burst between them
    would be neither judged nor counted in the peak. A reference so holds at most
    ``MAX_POINTS + 2 · len(signals)`` points; a point already kept is not repeated."""
    first = int(np.searchsorted(t, start * (1 - 1e-12) if start > 0 else start))
    n = len(t) - first
    every = max(1, int(np.ceil((n - 1) / (MAX_POINTS - 1))))
    k = np.arange(first, len(t), every)
    if k[-1] != len(t) - 1:
        k = np.append(k, len(t) - 1)
    extremes = [
        first + int(f(np.asarray(s)[first:])) for s in signals for f in (np.argmin, np.argmax)
    ]
    return np.union1d(k, np.asarray(extremes, dtype=k.dtype))


_SCALE = {"t": 1e12, "g": 1e9, "meg": 1e6, "k": 1e3, "mil": 25.4e-6, "m": 1e-3, "u": 1e-6,
          "µ": 1e-6, "n": 1e-9, "p": 1e-12, "f": 1e-15}  # fmt: skip
_NUMBER = re.compile(r"^([+-]?(?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?)(meg|mil|[tgkmuµnpf])?", re.I)


def spice_number(token: str) -> float:
    """A SPICE number with its scale suffix (letters after it ignored): ``2ns`` → 2e-9."""
    m = _NUMBER.match(token.strip())
    if not m:
        raise ValueError(f"not a SPICE number: {token!r}")
    return float(m.group(1)) * _SCALE.get((m.group(2) or "").lower(), 1.0)


def logical_lines(text: str) -> list[str]:
    """The deck's lines after the title, continuations joined, comments dropped."""
    lines: list[str] = []
    for raw in text.splitlines()[1:]:
        body = re.split(r";| \$ |\t\$ ", raw, maxsplit=1)[0].strip()
        if not body or body.startswith("*"):
            continue
        if body.startswith("+") and lines:
            lines[-1] += " " + body[1:].strip()
        else:
            lines.append(body)
    return lines


def find_tran(text: str) -> Tran:
    """The deck's ``.tran`` line, else the first ``tran`` command in its ``.control`` block,
    its ``$&name`` and ``$name`` written as ngspice 39 writes them (:func:`control_words`)."""
    control = False
    found = None
    commands: list[str] = []
    for line in logical_lines(text):
        low = line.lower()
        if low.startswith(".control"):
            control = True
            continue
        if low.startswith(".endc"):
            control = False
            continue
        words = low.replace(",", " ").split()
        if not control and words[0] == ".tran":
            return _tran(words[1:])
        if control and found is None:
            if words[0] == "tran":
                found = line
            else:
                commands.append(line)
    if found is None:
        raise ValueError("the deck has no .tran and no tran command in .control")
    if "$" in found:
        found = control_words(text, commands, found)
    return _tran(found.lower().replace(",", " ").split()[1:])


#: ngspice's control commands after which a new plot is current (a let made in the plot
#: before is not seen from it; one made before any, in the const plot, is)
_NEW_PLOT = set("op ac dc noise tf sens pz disto pss sp run linearize load fft spec".split())


def control_words(text: str, commands: list[str], tran: str) -> str:
    """The ``tran`` command with its variables substituted as ngspice 39 does
    (``cp_variablesubst``): ``$&name`` a vector — a ``.csparam`` (over the deck's
    top-level ``.param`` values) or a ``let`` before the tran (over the vectors before it,
    in the const plot or the current one) — written ``%G``; ``$name`` a ``set`` variable, a
    number written ``%d`` when whole, else ``%G``, a quoted value as written. A value this
    reading cannot give (a vector of a run, a ``let`` in an ``if`` block) is a ValueError:
    the corpus makes no reference of what it cannot read. Independent of diracvi's reader
    (``spice/_control.py``), which ``tests/test_control_vars.py`` holds to ngspice."""
    params: dict[str, float] = {}
    vectors: dict[tuple[int, str], float] = {}
    depth = 0
    for line in logical_lines(text):
        word = line.split()[0].lower()
        depth += (word == ".subckt") - (word == ".ends")
        if depth or word not in (".param", ".csparam"):
            continue
        for name, expr in re.findall(r"(\w+)\s*=\s*(\{[^}]*\}|'[^']*'|\S+)", line[len(word) :]):
            value = _number_expr(expr.strip("{}'"), params)
            if word == ".param":
                params[name.lower()] = value
            else:
                vectors[(0, name.lower())] = value
    plot, plots, block, sets = 0, 0, 0, {}
    for command in commands:
        word = command.split()[0].lower()
        block += (word in ("if", "while", "repeat", "dowhile", "foreach")) - (word == "end")
        if word in _NEW_PLOT:
            plots += 1
            plot = plots
        elif word == "setplot":
            raise ValueError(f"{command!r} before the tran: the plot of a let is not followed")
        elif word == "let" and not block and "=" in command:
            name, expr = (x.strip() for x in command[3:].split("=", 1))
            seen = {n: v for (p, n), v in vectors.items() if p == 0}
            seen.update({n: v for (p, n), v in vectors.items() if p == plot and plot})
            try:
                vectors[(plot, name.lower())] = _number_expr(expr, seen)
            except ValueError:
                vectors.pop((plot, name.lower()), None)  # no value: refused if used
        elif word == "set":
            for name, value in re.findall(r'(\w+)\s*=\s*("[^"]*"|\S+)', command[3:]):
                if value.startswith('"'):
                    sets[name.lower()] = value.strip('"')
                else:
                    x = spice_number(value)
                    sets[name.lower()] = str(int(x)) if x == int(x) else f"{x:G}"

    def one(m: re.Match) -> str:
        name = m.group(2).lower()
        if m.group(1):
            value = vectors.get((plot, name), vectors.get((0, name)))
            if value is None:
                raise ValueError(f"{tran!r}: $&{name} has no value before the run")
            return f"{value:G}"
        if name not in sets:
            raise ValueError(f"{tran!r}: ${name} is not set before the tran")
        return sets[name]

    return re.sub(r"\$(&?)(\w+)", one, tran)


_SAFE = {"sqrt": np.sqrt, "exp": np.exp, "log": np.log, "abs": abs, "pi": np.pi}


def _number_expr(expr: str, names: dict[str, float]) -> float:
    """An arithmetic expression of SPICE numbers (``2n``), ``names`` and a few functions
    (a ValueError for anything else)."""
    scaled = re.sub(
        r"(?<![\w.])((?:\d+\.?\d*|\.\d+)(?:e[+-]?\d+)?)(meg|mil|[tgkmuµnpf])?[a-z]*",
        lambda m: repr(spice_number(m.group(0))),
        expr.strip(),
        flags=re.I,
    ).replace("^", "**")

    def walk(node):
        if isinstance(node, ast.Expression):
            return walk(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, int | float):
            return float(node.value)
        if isinstance(node, ast.Name) and node.id.lower() in {**_SAFE, **names}:
            return {**_SAFE, **names}[node.id.lower()]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
            return -walk(node.operand) if isinstance(node.op, ast.USub) else walk(node.operand)
        if isinstance(node, ast.BinOp):
            ops = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
                   ast.Div: np.divide, ast.Pow: np.power}  # fmt: skip
            if type(node.op) in ops:
                return float(ops[type(node.op)](walk(node.left), walk(node.right)))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and not node.keywords:
            f = _SAFE.get(node.func.id.lower())
            if callable(f):
                return float(f(*(walk(a) for a in node.args)))
        raise ValueError(f"cannot evaluate {expr!r} here")

    try:
        return walk(ast.parse(scaled, mode="eval"))
    except SyntaxError:
        raise ValueError(f"cannot evaluate {expr!r} here") from None


def _tran(words: list[str]) -> Tran:
    uic = "uic" in words
    nums = [spice_number(w) for w in words if w != "uic"]
    step, stop = nums[0], nums[1]
    start = nums[2] if len(nums) > 2 else 0.0
    tmax = nums[3] if len(nums) > 3 else None
    return Tran(step, stop, start, tmax, uic)


# ------------------------------------------------------------------ ngspice


def strip_control(text: str) -> list[str]:
    """The deck's physical lines up to ``.end``, without ``.control … .endc`` blocks."""
    out, control = [], False
    for raw in text.splitlines():
        low = raw.strip().lower()
        if low.startswith(".control"):
            control = True
            continue
        if control:
            control = not low.startswith(".endc")
            continue
        if re.fullmatch(r"\.end\b.*", low) and not low.startswith(".ends"):
            break  # SPICE reads nothing after .end
        out.append(raw)
    return out


def wrapper(
    text: str,
    tran: Tran,
    raw_out: Path,
    *,
    fine: bool = True,
    divisor: float = TMAX_DIVISOR,
    reltol: float = RELTOL,
    options: str = "",
) -> str:
    """A deck that runs ``text``'s circuit at its own ``.tran``, refined when ``fine``
    (``reltol``, by default RELTOL, the ``name=value`` ngspice ``options``, and
    ``TMAX = min(TSTEP/divisor, deck's TMAX)``), and
    writes every vector but those of length zero to a binary raw file (the doubles ngspice
    computed, a third of the ASCII file's size, whose 16 digits round the last bit;
    :func:`read_raw` reads both).
    The deck's own ``.control`` blocks are left out."""
    if fine:
        tmax = tran.step / divisor
        if tran.tmax:
            tmax = min(tmax, tran.tmax)
        options = f"option reltol={reltol!r} {options}".rstrip()
    else:
        tmax = tran.tmax
        options = ""
    args = f"{tran.step!r} {tran.stop!r}"
    if tmax is not None:
        args += f" {tran.start!r} {tmax!r}"
    elif tran.start:
        args += f" {tran.start!r}"
    if tran.uic:
        args += " uic"
    return "\n".join(
        [
            *strip_control(text),
            ".control",
            "set filetype=binary",
            options,
            "save all",
            f"tran {args}",
            # vectors ngspice declares but never fills (``.option savecurrents`` saves a
            # MOSFET's @m…[ib] as one) make ``write`` fail ("vector … is not available or
            # has zero length"), and no raw file is written: ngspice's
            # examples/mos/ro-meas.cir. Only zero-length vectors are removed, so every other
            # deck's file is what it was.
            "remzerovec",
            f"write {raw_out}",
            ".endc",
            ".end",
            "",
        ]
    )


def read_raw(path: Path, keep=None) -> tuple[list[str], np.ndarray]:
    """An ngspice raw file (its first plot, real): vector names and a (points, vectors)
    array, the plot's scale (time) first, then every other vector, or, given a predicate
    ``keep`` on a vector's name (e.g. :func:`kept`), those it keeps, in the file's order.

    The header is parsed line by line up to ``Values:`` (ASCII) or ``Binary:``, and its
    ``No. Points`` × ``No. Variables`` sizes the output, which the data then fill block by
    block: an ASCII block is parsed by ``np.fromstring`` (each point is its index and its
    ``No. Variables`` numbers), a binary one read as little-endian doubles (the point's
    values in order). So the peak memory is the output and one block, not the file held
    as text: a TSTEP/5000 run of ``xy_sandler23`` (1.0e7 points of 20 vectors, ~4.8 GB as
    ASCII) read whole as one string and its words grew past 23 GB; streamed, its 1.6 GB
    binary file reads in 1.61 GB (its TSTEP/500 ASCII file, 478 MB: 4.0 GB as one string,
    0.53 GB streamed; docs/circuits.md)."""
    with open(path, "rb") as f:
        header: dict[str, str] = {}
        names: list[str] = []
        while True:
            line = f.readline()
            if not line:
                raise ValueError(f"{path}: no 'Values:' or 'Binary:' line; not a raw file")
            text = line.decode(errors="replace").rstrip("\r\n")
            key, _, value = text.partition(":")
            key = key.strip().lower()
            if key == "variables":
                nvars = int(header["no. variables"])
                for _ in range(nvars):
                    names.append(f.readline().decode(errors="replace").split()[1])
                continue
            if key in ("values", "binary"):
                break
            header[key] = value.strip()
        if "complex" in header.get("flags", "real").lower():
            raise ValueError(
                f"{path}: a complex plot ({header['flags']!r}); read_raw reads real ones"
            )
        npts = int(header["no. points"])
        cols = [j for j, n in enumerate(names) if j == 0 or keep is None or keep(n)]
        data = np.empty((npts, len(cols)))
        if key == "binary":
            _fill_binary(f, data, nvars, cols, path)
        else:
            _fill_ascii(f, data, nvars, cols, path)
    return [names[j] for j in cols], data


_BLOCK = 1 << 16  # points a block: 10 MB of doubles at 20 vectors


def _fill_binary(f, data: np.ndarray, nvars: int, cols: list[int], path: Path) -> None:
    """``data``'s rows from ngspice's binary values: each point ``nvars`` doubles."""
    whole = cols == list(range(nvars))
    for p in range(0, len(data), _BLOCK):
        n = min(_BLOCK, len(data) - p)
        block = np.fromfile(f, dtype="<f8", count=n * nvars)
        if block.size != n * nvars:
            raise ValueError(f"{path}: binary values end at point {p + block.size // nvars}"
                             f" of the {len(data)} its header promises")  # fmt: skip
        block = block.reshape(n, nvars)
        data[p : p + n] = block if whole else block[:, cols]


def _fill_ascii(f, data: np.ndarray, nvars: int, cols: list[int], path: Path) -> None:
    """``data``'s rows from ngspice's ASCII values: each point its index, then ``nvars``
    numbers, all separated by white space; read in blocks of lines, the numbers of a
    point a block splits carried into the next."""
    width = nvars + 1  # the point's index first
    p = 0
    carry = np.empty(0)
    while p < len(data):
        lines = f.readlines(_BLOCK * width * 24)  # ~24 bytes a number
        if not lines:
            break
        chunk = b"".join(lines).decode(errors="replace")
        try:
            with warnings.catch_warnings():  # numpy < 2.3 only warns where a word is no number
                warnings.simplefilter("error", DeprecationWarning)
                numbers = np.fromstring(chunk, sep=" ")
        except (ValueError, DeprecationWarning) as e:
            raise ValueError(f"{path}: a value that is not a number after point {p}: {e}") from None
        numbers = np.concatenate([carry, numbers]) if carry.size else numbers
        n = min(numbers.size // width, len(data) - p)
        rows = numbers[: n * width].reshape(n, width)
        data[p : p + n] = rows[:, 1:][:, cols]
        carry = numbers[n * width :]
        p += n
    if p < len(data):
        raise ValueError(
            f"{path}: ASCII values end at point {p} of the {len(data)} its header promises"
        )


def _entry(deck: Path) -> dict:
    """``deck``'s ``EXPECTED.toml`` entry (``{}`` if it has none)."""
    # matched by path: a deck in a folder of its own (es_integrator/…) has a file entry
    # that is not its bare name
    for entry in load_expected().values():
        if (DATA / entry["file"]).resolve() == deck.resolve():
            return entry
    return {}


def reference_divisor(deck: Path) -> float:
    """``TSTEP/TMAX`` of ``deck``'s fine reference: its ``reference_tmax_divisor`` in
    ``EXPECTED.toml``, else :data:`TMAX_DIVISOR`."""
    return float(_entry(deck).get("reference_tmax_divisor", TMAX_DIVISOR))


def reference_reltols(deck: Path) -> tuple[float, ...]:
    """The ``reltol`` of each fine run ``deck``'s reference is made of: its
    ``reference_reltols`` in ``EXPECTED.toml`` (three or more, see
    :func:`reference_from_run`), else ``(RELTOL,)``."""
    reltols = tuple(float(r) for r in _entry(deck).get("reference_reltols", (RELTOL,)))
    if len(reltols) != 1 and (len(reltols) < 3 or len(reltols) % 2 == 0):
        raise ValueError(
            f"{deck.name}: reference_reltols {reltols} must be one value or an odd number ≥ 3"
        )
    return reltols


def reference_options(deck: Path) -> str:
    """The ngspice ``.options`` (``"name=value …"``) that ``deck``'s fine reference adds to
    ``reltol``: its ``reference_options`` in ``EXPECTED.toml``, else none. A deck whose
    compared signals are the rates of charges below the defaults' resolution needs them:
    ``es_cmos_nand``'s gate currents (peaks of 4–6 nA, a 9e-14 C swing of gate charge) at
    ``chgtol`` = 1e-14 C and ``abstol`` = 1 pA rang point to point by ±1.1e-10 A in
    ngspice's trapezoidal steps at the first input edge's end (``abstol=1e-15
    chgtol=1e-18``: smooth, within 2e-3 of ngspice at TMAX = 1 ns)."""
    return str(_entry(deck).get("reference_options", ""))


def run_ngspice(
    deck: Path,
    *,
    fine: bool = True,
    timeout: float = 900,
    reltol: float = RELTOL,
    divisor: float | None = None,
    keep=None,
    options: str | None = None,
):
    """Run ngspice 39 on ``deck`` (see :func:`wrapper`): ``(names, data, seconds)``;
    ``reltol``, ``divisor`` and ``options`` (defaults: the reference's) refine a ``fine``
    run further;
    ``keep`` (e.g. :func:`kept`) selects the vectors read (:func:`read_raw`)."""
    text = deck.read_text(errors="replace")
    tran = find_tran(text)
    if divisor is None:
        divisor = reference_divisor(deck) if fine else TMAX_DIVISOR
    if options is None:
        options = reference_options(deck) if fine else ""
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "out.raw"
        cir = Path(tmp) / "wrapper.cir"
        cir.write_text(
            wrapper(text, tran, raw, fine=fine, divisor=divisor, reltol=reltol, options=options)
        )
        t0 = time.perf_counter()
        # run beside the deck, so that its relative .include files are found
        proc = subprocess.run(
            [shutil.which("ngspice") or "/usr/bin/ngspice", "-b", str(cir)],
            cwd=deck.parent,
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        seconds = time.perf_counter() - t0
        if not raw.exists():
            tail = (proc.stdout[-1500:] + "\n" + proc.stderr[-1500:]).strip()
            raise RuntimeError(f"ngspice wrote no results for {deck.name}:\n{tail}")
        names, data = read_raw(raw, keep)
    return names, data, seconds


def kept(name: str) -> bool:
    """Node voltages ``v(n)`` and the branch currents ``i(name)`` of voltage sources and
    inductors (ngspice's raw-file names). Left out: the currents of other branch
    elements (E, H, B, XSPICE ports), device-internal nodes (``#``) and the helper nodes
    ngspice makes for ``par('…')`` expressions in ``.measure`` (``pa_00``, …)."""
    m = re.fullmatch(r"([vi])\((.+)\)", name.lower())
    if not m or "#" in m.group(2):
        return False
    kind, what = m.groups()
    if kind == "i":
        return what[0] in "vl"
    return not re.fullmatch(r"pa_\d+", what)


def reference_from_run(
    deck: Path, timeout: float = 900
) -> tuple[np.ndarray, dict[str, np.ndarray], float]:
    """The fine ngspice run of ``deck`` (:func:`fine_run`) at its own time points thinned
    from TSTART by :func:`thin`, each signal's min and max kept: ``(t, {vector: values},
    s)``."""
    t, signals, seconds = fine_run(deck, timeout)
    tran = find_tran(deck.read_text(errors="replace"))
    keep = thin(t, tran.start, list(signals.values()))
    return t[keep], {n: values[keep] for n, values in signals.items()}, seconds


def fine_run(deck: Path, timeout: float = 900) -> tuple[np.ndarray, dict[str, np.ndarray], float]:
    """The fine ngspice run of ``deck`` at every one of its own time points, unthinned:
    ``(t, {vector: values}, s)``.

    A deck with several :func:`reference_reltols` (an odd number ``≥ 3``) has for
    reference, at the first run's own points, the median ``med_r s_r(t_k)`` of its runs
    ``s_r`` (each other run linearly interpolated there; ``s`` the total seconds): where
    ngspice's fine runs do not reproduce one another — ``ng_transformers1``'s XSPICE
    windings, where each run has bursts of up to 1.9e5 V at instants of its own and none
    at the others' — no single run is the circuit's answer, and a value that one run
    alone has is dropped, while whatever a majority of the runs agree on stays.
    ``timeout``: each ngspice run's wall-clock limit in seconds."""
    reltols = reference_reltols(deck)
    names, data, seconds = run_ngspice(deck, keep=kept, reltol=reltols[0], timeout=timeout)
    if len(reltols) > 1:
        t = data[:, 0]
        stack = [data]
        for reltol in reltols[1:]:
            other_names, other, s = run_ngspice(deck, keep=kept, reltol=reltol, timeout=timeout)
            seconds += s
            column = {n: j for j, n in enumerate(other_names)}
            resampled = np.empty_like(data)
            resampled[:, 0] = t
            for j, n in enumerate(names[1:], 1):
                resampled[:, j] = np.interp(t, other[:, 0], other[:, column[n]])
            stack.append(resampled)
        data = np.median(np.stack(stack), axis=0)
    return data[:, 0], {n: data[:, j] for j, n in enumerate(names) if j}, seconds


#: a committed reference point and a fresh run's point this close (of the time itself)
#: are one point of ngspice's: the references made before times were written to 17
#: digits hold 10 (``es_rc``'s 0.0005017170139 for 0.0005017170139023744), and a run's
#: times differ in their last bits (``xy_vsin``'s end at 9.999999999999999e-06 against
#: 1e-05); across a source's jump (``xy_inductor``'s points 1.3e-12 s apart at 12 ms) such
#: a shift, interpolated, moves a value by 2.6e-6 of peak. The nearest point is taken.
SAME_POINT = 1e-9


def reference_gap(
    t: np.ndarray, committed: dict[str, np.ndarray], fine_t: np.ndarray, fine: dict
) -> dict[str, float]:
    """How far a committed reference ``(t, committed)`` is from a fine run ``(fine_t,
    fine)`` of the same deck, per vector, in its peak (the agreement measure's: ``max
    |committed|``, at least :data:`VNTOL`/:data:`ABSTOL`): at each committed time the fine
    run's own point there (within :data:`SAME_POINT` of the time), else the fine run
    linearly interpolated, as :func:`compare_ngspice` reads a run between its points (a
    kept point of another run, moved). A committed time outside the fine run's span is
    ``inf``; a vector either lacks, ``nan``."""
    close = SAME_POINT * np.abs(t)
    if t[0] < fine_t[0] - close[0] or t[-1] > fine_t[-1] + close[-1]:
        return {vector: np.inf for vector in set(committed) | set(fine)}
    j = np.clip(np.searchsorted(fine_t, t), 1, len(fine_t) - 1)
    nearest = np.where(np.abs(fine_t[j - 1] - t) <= np.abs(fine_t[j] - t), j - 1, j)
    same = np.abs(fine_t[nearest] - t) <= close
    gaps = {}
    for vector in set(committed) | set(fine):
        if vector not in committed or vector not in fine:
            gaps[vector] = np.nan
            continue
        values = committed[vector]
        floor = ABSTOL if vector.lower().startswith("i(") else VNTOL
        peak = max(float(np.max(np.abs(values))), floor)
        read = np.where(same, fine[vector][nearest], np.interp(t, fine_t, fine[vector]))
        gaps[vector] = float(np.max(np.abs(read - values))) / peak
    return gaps


def write_reference(path: Path, grid: np.ndarray, signals: dict[str, np.ndarray]) -> None:
    buf = io.StringIO()
    buf.write(",".join(["time", *signals]) + "\n")
    # times to 17 digits: a point ngspice puts just past a corner (0.0120000001 s) must not
    # be read back on the corner, where the other side's limit holds
    fmt = ["%.17g"] + ["%.10g"] * len(signals)
    np.savetxt(buf, np.column_stack([grid, *signals.values()]), delimiter=",", fmt=fmt)
    if path.is_file():
        with gzip.open(path, "rt") as f:
            if f.read() == buf.getvalue():
                return  # unchanged: a rewrite would differ only in gzip's time stamp
    path.parent.mkdir(parents=True, exist_ok=True)
    with gzip.open(path, "wt", compresslevel=9) as f:
        f.write(buf.getvalue())


def load_reference(name: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The committed reference of deck ``name``: ``(t, {ngspice vector: values})``."""
    with gzip.open(REFERENCES / f"{name}.csv.gz", "rt") as f:
        header = f.readline().strip().split(",")
        data = np.loadtxt(f, delimiter=",", ndmin=2)
    return data[:, 0], {h: data[:, j] for j, h in enumerate(header) if j}


# ------------------------------------------------------------------ the comparison


def load_expected() -> dict[str, dict]:
    """``EXPECTED.toml``: deck name → ``{file, status, match?, slow?}``."""
    with open(EXPECTED, "rb") as f:
        return tomllib.load(f)


def diracvi_keys(vector: str) -> list[str]:
    """diracvi's candidate names for an ngspice vector (see the module docstring)."""
    low = vector.lower()
    keys = [low]
    m = re.fullmatch(r"i\([a-z]\.(.+)\)", low)
    if m:
        keys.append(f"i({m.group(1)})")
    return keys


def compare(result, t: np.ndarray, ref: dict[str, np.ndarray]):
    """Worst relative error over the reference signals: ``(worst, {vector: error}, missing)``.

    ``error = max |diracvi − ngspice| / max(peak |ngspice|, floor)`` over the reference's
    times ``t``, diracvi sampled there by its own interpolant (``result.at``); ``missing`` lists the
    reference vectors diracvi does not report."""
    span = np.asarray(result.trajectory.t, dtype=float)  # the run's own span
    return compare_sampled(result.at(t), (span[0], span[-1]), t, ref)


def compare_ngspice(names: list[str], data: np.ndarray, t: np.ndarray, ref):
    """:func:`compare` for an ngspice run (``run_ngspice``'s names and data), linearly
    interpolated between its own points as a waveform viewer draws it, over the
    reference's times from its first point on (with UIC ngspice writes no t = 0 point,
    and its first step at the deck's settings is longer than the fine run's)."""
    times = data[:, 0]
    inside = t >= times[0]
    t = t[inside]
    ref = {k: v[inside] for k, v in ref.items()}
    have = {n: np.interp(t, times, data[:, j]) for j, n in enumerate(names) if j}
    return compare_sampled(have, (times[0], times[-1]), t, ref)


def compare_sampled(have: dict, span: tuple[float, float], t: np.ndarray, ref):
    """The comparison of waveforms ``have`` already sampled at ``t`` (their run covering
    ``span``) with the reference signals ``ref``."""
    have = {k.lower(): v for k, v in have.items()}
    errors, missing = {}, []
    for vector, values in ref.items():
        key = next((k for k in diracvi_keys(vector) if k in have), None)
        if key is None:
            missing.append(vector)
            continue
        mine = np.asarray(have[key], dtype=float)
        if t[-1] > span[1] * (1 + 1e-9) or t[0] < span[0] * (1 - 1e-9) - 1e-300:
            errors[vector] = np.inf  # the run does not cover the reference's times
            continue
        floor = ABSTOL if vector.lower().startswith("i(") else VNTOL
        peak = max(float(np.max(np.abs(values))), floor)
        errors[vector] = float(np.max(np.abs(mine - values))) / peak
    worst = max(errors.values(), default=np.inf)
    return worst, errors, missing


def elements(deck: Path) -> str:
    """The element letters a deck uses (``X`` for subcircuit instances), e.g. ``CDRV``."""
    letters = set()
    text = "\n".join(strip_control(deck.read_text(errors="replace")))
    for line in logical_lines(text):
        c = line[0].upper()
        if c.isalpha():
            letters.add(c)
    return "".join(sorted(letters))


# ------------------------------------------------------------------ what a deck needs

_BASIC = set("RCLKVID")
_KNOWN_DIRECTIVES = {".tran", ".ic", ".param", ".model", ".options", ".option", ".opt", ".end",
                     ".print", ".plot", ".save", ".ends"}  # fmt: skip
_DIODE_BASIC = {"is", "n"}


def needs(deck: Path) -> list[str]:
    """What a deck uses beyond today's reader (R C L K V I D, ``.tran``, ``.ic``, ``.param``,
    diode ``.model`` with IS and N, ``.options``): a deck-level survey for the table, found
    by scanning its lines (the reader itself stops at the first problem)."""
    text = deck.read_text(errors="replace")
    out: list[str] = []

    def add(item: str) -> None:
        if item not in out:
            out.append(item)

    if re.search(r"^\s*\.control\b", text, re.I | re.M):
        add(".control")
    lines = _with_includes(logical_lines("\n".join(strip_control(text))), deck.parent)
    tran = None
    for line in lines:
        low = line.lower()
        head = low.split()[0]
        if head.startswith("."):
            if head == ".model":
                words = re.findall(r"[a-z_0-9.#+-]+", low)
                mtype = words[2] if len(words) > 2 else "?"
                if mtype == "d":
                    params = set(re.findall(r"([a-z_]\w*)\s*=", low)) - _DIODE_BASIC
                    if params:
                        add("diode " + "/".join(sorted(p.upper() for p in params)))
                else:
                    add(f".model {mtype.upper()}")
            elif head == ".tran":
                tran = _tran(low.replace(",", " ").split()[1:])
            elif head not in _KNOWN_DIRECTIVES:
                add({".meas": ".measure", ".inc": ".include"}.get(head, head))
            continue
        letter = head[0].upper()
        if not letter.isalpha():
            add(f"a line starting with {head[0]!r}")
        elif letter not in _BASIC:
            add(letter)
        if letter in "VI":
            if re.search(r"\bac\b", low):
                add("AC spec")
            for form in ("exp", "sffm", "am", "trnoise", "trrandom", "file"):
                if re.search(rf"\b{form}\s*\(|\b{form}\s", low):
                    add(form.upper())
            if re.search(r"\b(pulse|sin|pwl)\s+[^(\s]", low):
                add("source without ( )")
            if re.search(r"\bpwl\b.*\b(td|r)\s*=", low):
                add("PWL TD=/R=")
            if re.search(r"\bsin\s*\(?\s*\S+\s+\S+\s+\S+\s+-", low):
                add("SIN with TD < 0")
    if tran is None:
        add("tran in .control only")
    elif tran.start:
        add("TSTART")
    if tran is not None and not tran.uic:
        add("DC OP (no UIC)")
    return out


def _with_includes(lines: list[str], folder: Path, depth: int = 0) -> list[str]:
    """``lines`` with each ``.include``/``.inc``/``.lib <file>`` of a local file spliced in
    (an included file has no title line)."""
    out: list[str] = []
    for line in lines:
        words = line.split()
        if words[0].lower() in (".include", ".inc", ".lib") and len(words) == 2 and depth < 5:
            path = folder / words[1].strip("'\"")
            if path.is_file():
                text = "* included\n" + path.read_text(errors="replace")
                out.append(line)
                out += _with_includes(logical_lines(text), path.parent, depth + 1)
                continue
        out.append(line)
    return out
