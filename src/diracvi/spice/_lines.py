r"""Netlist text → logical lines: the title rule, comments, ``+`` continuations,
``.include``/``.lib`` of local files, ``.control … .endc`` blocks, and the tokens of a line.

SPICE's rules as ngspice applies them: the first line of the top file is the title
(whatever it says); ``*`` starts a comment line, ``;`` and `` $ `` an inline comment;
``+`` continues the previous line. An included file has no title line, and a ``.end``
in it ends that file only. ``.lib FILE ENTRY`` takes the lines between ``.lib ENTRY``
and ``.endl`` of ``FILE``. Paths are relative to the including file (to the working
directory for netlist text). Every problem found is collected (:class:`Problems`), not
raised, so that one :class:`NetlistError` can list them all.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ModelError

_TOKEN = re.compile(r"\{[^}]*\}|'[^']*'|=|[^\s,()={}']+")
#: the characters other than blanks that separate or group a line's tokens
_PLAIN = frozenset(",()={}'")


class NetlistError(ModelError):
    """A netlist that cannot be read or built; ``problems`` lists every line at fault
    as ``(where, text, why)`` (``where`` is ``"line 7"`` or ``"sub.inc line 3"``)."""

    def __init__(self, message: str, problems=()):
        super().__init__(message)
        self.problems = list(problems)


class LineError(NetlistError):
    """One line's problem; the reader collects these (see :class:`Problems`)."""

    def __init__(self, line: Line, why: str):
        self.line, self.why = line, why
        super().__init__(f"{line.where}: {why}\n    {line.text}", [(line.where, line.text, why)])
        self.seq = line.seq


@dataclass
class Line:
    """A logical line: its text (continuations joined) and where it starts."""

    number: int
    text: str
    file: str = ""  # "" for the top netlist, else the included file's name
    seq: int = 0  # its place in the netlist with includes expanded (orders the problems)

    @property
    def where(self) -> str:
        return f"{self.file} line {self.number}" if self.file else f"line {self.number}"

    def fail(self, why: str) -> LineError:
        """The error to raise for this line (``why`` says what is wrong and the fix)."""
        return LineError(self, why)

    def with_text(self, text: str) -> Line:
        return Line(self.number, text, self.file, self.seq)


@dataclass
class Problems:
    """Every problem of a netlist, in netlist order; ``check()`` raises them together.

    A line of a subcircuit definition that fails in several instances is one problem
    naming the instances (``in xa.x1, xb: …``)."""

    found: dict = field(default_factory=dict)  # (where, text, why) -> (place, [chains])

    def add(self, error: NetlistError, chain: str = "") -> None:
        for item in error.problems or [("netlist", "", str(error))]:
            _, chains = self.found.setdefault(item, (getattr(error, "seq", 1 << 60), []))
            if chain and chain not in chains:
                chains.append(chain)

    @property
    def items(self) -> list:
        """``(where, text, why)`` in netlist order, the instance chains in ``why``."""
        ranked = sorted(self.found.items(), key=lambda kv: kv[1][0])
        return [(w, t, _chained(why, chains)) for (w, t, why), (_, chains) in ranked]

    def check(self) -> None:
        items = self.items
        if not items:
            return
        head = "1 problem" if len(items) == 1 else f"{len(items)} problems"
        body = "\n".join(
            f"{where}: {why}" + (f"\n    {text}" if text else "") for where, text, why in items
        )
        raise NetlistError(f"the netlist has {head}:\n{body}", items)


def _chained(why: str, chains: list) -> str:
    if not chains:
        return why
    shown = ", ".join(chains[:4]) + (f" and {len(chains) - 4} more" if len(chains) > 4 else "")
    return f"in {shown}: {why}"


@dataclass
class Source:
    """The logical lines of a netlist with its includes expanded, and what was set aside."""

    title: str
    lines: list[Line]
    control: list[Line] = field(default_factory=list)  # commands of .control blocks
    notes: list[str] = field(default_factory=list)
    count: int = 0  # lines taken so far


def split(line: Line) -> tuple[list[str], dict[str, str]]:
    """Positional tokens and ``key=value`` pairs (keys lower-case); parentheses and
    commas separate tokens, ``{…}`` and ``'…'`` stay whole."""
    text = line.text
    if _PLAIN.isdisjoint(text):  # no separator but blanks (R1 a b 10): the words
        return text.split(), {}
    if text.count("(") != text.count(")") or text.count("{") != text.count("}"):
        raise line.fail("unbalanced parentheses or braces (close every '(' and '{')")
    tokens = _TOKEN.findall(text)
    pos, kw = [], {}
    i = 0
    while i < len(tokens):
        if i + 1 < len(tokens) and tokens[i + 1] == "=":
            if i + 2 >= len(tokens) or tokens[i + 2] == "=":
                raise line.fail(f"'{tokens[i]}=' has no value (write {tokens[i]}=VALUE)")
            kw[tokens[i].lower()] = tokens[i + 2]
            i += 3
            continue
        if tokens[i] == "=":
            raise line.fail("'=' without a name before it (write NAME=VALUE)")
        pos.append(tokens[i])
        i += 1
    return pos, kw


def card(line: Line) -> str:
    """The line's first word, lower-case (``.tran``, ``r1``, …)."""
    return line.text.split(None, 1)[0].lower()


def _physical_lines(text: str) -> list[str]:
    """The file's lines up to a DOS end-of-file mark (ctrl-Z, 0x1A), which vendor model
    files still carry (``TL072.301`` in ngspice's examples) and ngspice ignores."""
    return text.split("\x1a", 1)[0].splitlines()


def load(text: str, base: Path | None, problems: Problems) -> Source:
    """The logical lines of netlist ``text`` (its includes expanded; ``base`` is the
    folder of the netlist file, ``None`` for text)."""
    raw = _physical_lines(text)
    if not raw or not any(r.strip() for r in raw):
        raise NetlistError("the netlist is empty (SPICE expects a title line, then elements).")
    source = Source(raw[0].strip(), [])
    _expand(raw[1:], 2, "", base or Path.cwd(), source, problems, depth=0)
    return source


#: leading characters ngspice turns into '*' (a comment line), warning "Unusual leading
#: characters": a lone ')' closing a '.model NAME TYPE(' card whose parameters follow on
#: '+' lines is the common case (its '(' then stays open, which the .model reader accepts)
_UNUSUAL_LEAD = set('=[]?()&%$"!:,;\f')


def _logical(
    raw: list[str], first: int, file: str, problems: Problems, notes: list | None = None
) -> list[Line]:
    lines: list[Line] = []
    for k, text in enumerate(raw, start=first):
        body = re.split(r";| \$ |\t\$ ", text, maxsplit=1)[0].rstrip()
        stripped = body.strip()
        if not stripped or stripped.startswith("*"):
            continue
        if stripped[0] in _UNUSUAL_LEAD:
            if notes is not None:
                where = Line(k, stripped, file).where
                notes.append(
                    f"{where}: {stripped[:20]!r} read as a comment (a line starting with "
                    f"{stripped[0]!r}, as ngspice does)"
                )
            continue
        if stripped.startswith("+"):
            if not lines:
                problems.add(
                    Line(k, text.strip(), file).fail(
                        "a '+' continuation with nothing to continue (join it to an element "
                        "or directive line)"
                    )
                )
                continue
            lines[-1].text += " " + stripped[1:].strip()
            continue
        lines.append(Line(k, stripped, file))
    return lines


def _expand(raw, first, file, base, source, problems, depth) -> None:
    lines = _logical(raw, first, file, problems, source.notes)
    k = 0
    while k < len(lines):
        line = lines[k]
        line.seq, source.count = source.count, source.count + 1
        word = card(line)
        k += 1
        if word == ".end":  # the top netlist ends here; an included file's .end ends that file
            return
        if word == ".control":
            end = next((j for j in range(k, len(lines)) if card(lines[j]) == ".endc"), None)
            if end is None:
                problems.add(line.fail("'.control' without '.endc' (close the block)"))
                return
            source.control += lines[k:end]
            source.notes.append(
                f"{line.where}: .control … .endc block skipped (ngspice's interactive "
                "commands; a 'tran' in it is used when the netlist has no .tran)"
            )
            k = end + 1
            continue
        if word == ".endc":
            problems.add(line.fail("'.endc' without '.control' before it (remove it)"))
            continue
        if word in (".include", ".inc", ".lib"):
            args = line.text.split()[1:]
            if word == ".lib" and len(args) == 1 and not _is_file(base, args[0]):
                # a section definition `.lib NAME … .endl` here: used only when referenced
                end = next((j for j in range(k, len(lines)) if card(lines[j]) == ".endl"), None)
                if end is None:
                    problems.add(line.fail(f"'.lib {args[0]}' section without '.endl'"))
                    return
                k = end + 1
                continue
            _include(line, word, args, base, source, problems, depth)
            continue
        if word == ".endl":
            continue  # the end of a library section whose start was followed
        source.lines.append(line)


def _is_file(base: Path, name: str) -> bool:
    path = base / _unquote(name)
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def _unquote(name: str) -> str:
    return name[1:-1] if len(name) > 1 and name[0] == name[-1] and name[0] in "'\"" else name


def _include(line, word, args, base, source, problems, depth) -> None:
    form = ".lib FILE ENTRY" if word == ".lib" else f"{word} FILE"
    if not args or len(args) > (2 if word == ".lib" else 1):
        problems.add(line.fail(f"expected '{form}'"))
        return
    if depth > 20:
        problems.add(line.fail("includes nested more than 20 deep (does a file include itself?)"))
        return
    path = base / _unquote(args[0])
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except (OSError, ValueError) as exc:
        problems.add(
            line.fail(
                f"cannot read {str(path)!r} ({exc.__class__.__name__}): {word} takes a local "
                "file, relative to the including file"
            )
        )
        return
    raw = _physical_lines(text)
    if word == ".lib" and len(args) == 2:
        words = [r.lower().split() for r in raw]
        heads = [j for j, w in enumerate(words) if len(w) == 2 and w[0] == ".lib"]
        start = next((j for j in heads if words[j][1] == args[1].lower()), None)
        if start is None:
            sections = [raw[j].split()[1] for j in heads]
            problems.add(
                line.fail(f"library {str(path)!r} has no section {args[1]!r} (it has {sections})")
            )
            return
        ends = [j for j in range(start + 1, len(raw)) if words[j][:1] == [".endl"]]
        stop = ends[0] if ends else len(raw)
        part = raw[start + 1 : stop]
        _expand(part, start + 2, path.name, path.parent, source, problems, depth + 1)
        return
    _expand(raw, 1, path.name, path.parent, source, problems, depth + 1)
