"""Every command and code block of the README and the docs pages runs as written, top to
bottom, in a fresh directory — so a page cannot drift from the code.

How a page is read (``page_steps``), in order of its fenced blocks:

- ```` ```bash ```` / ```` ```console ```` — shell commands, one a line (``$ `` prompts of a
  console block, ``#`` comments and ``&&`` chains understood); each ``&&`` part is run by
  ``bash`` in the page's directory, with ``diracvi`` and ``python`` being the package and
  interpreter under test (``src/`` of this checkout). A part listed in ``SKIPPED`` is not
  run, for the reason given there; one listed in ``SLOW`` runs in ``test_slow_command``
  (``-m slow``) instead.
- a block with ``title="NAME"`` (```` ```text title="rc.cir" ````) is a file the page
  uses: it is written to ``NAME`` when reached (a Python one is also run, as the prose goes
  on to use its names).
- ```` ```python ```` — run in one namespace per page, in the page's directory.
- a block right after the line ``<!-- printed by the block above -->`` is what the step
  before it prints: the runner compares it with that step's standard output
  (``same_printout``: the words equal, each number to the digits shown, a number shown
  below 1e-10 — round-off — only below 1e-10 again).
- other blocks (``text`` without a title, untagged) are output or diagrams: not run.

Inline commands in prose (```` `diracvi bench --only gradients` ````) are not run (most
name a command, or take minutes); ``test_inline_commands_parse`` checks each against the
command line itself: the command exists, every option does, and a value of a choice
option is one of its choices (``a|b`` spans: each alternative). Inline script runs
(```` `python benchmarks/corpus.py --markdown` ````) are checked alike by
``test_inline_scripts_parse``: the script exists, and its own ``argparse`` parser accepts
the arguments (the script runs up to its ``parse_args`` and is stopped there).

The page runs are marked ``docs`` (deselected by default, run in CI by ``.ci/run``: a page
takes seconds to a minute); ``test_every_command_is_run_or_listed`` is in the default run
and fails when a page gains a command the tables do not cover or a table entry no page has.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^(?P<indent> *)```(?P<info>[^\n]*)\n(?P<body>.*?)^(?P=indent)```", re.S | re.M)
TITLE = re.compile(r'title="([^"]+)"')
PRINTED = "<!-- printed by the block above -->"

#: command (an ``&&`` part, as written) → why it is not run by these tests
SKIPPED = {
    "python3 -m venv .venv": "sets up the environment these tests already run in (.ci/run "
    "creates a fresh one and installs the package)",
    ". .venv/bin/activate": "activates that environment",
    "pip install .": "installing is .ci/run's first step",
    'pip install ".[test]"': "installing is .ci/run's first step",
    'pip install ".[docs]"': ".ci/run installs the docs extra before the docs tests",
    "pytest -n 2": "the whole suite: .ci/run runs it (from inside it would run itself)",
    "mkdocs build --strict": "tests/test_docs_site.py builds the site with --strict (-m docs)",
    "diracvi sweep model.py --param k=0.5:2:20 --scheduler tcp://HOST:8786 --out sweep.nc": (
        "needs a running Dask scheduler at HOST; the cluster path is tests/test_sweep.py's "
        "(a 2-worker LocalCluster) and docs/sweeps.md's LocalCluster block"
    ),
    "diracvi sweep model.py --param R=0.1:2:20 --scheduler tcp://HOST:8786 --out sweep.nc": (
        "needs a running Dask scheduler at HOST; the same sweep runs in-process just above"
    ),
    "python benchmarks/corpus.py --references": "regenerates the committed ngspice "
    "references under tests/data (minutes, needs ngspice): a maintainer's step",
    "python benchmarks/corpus.py --write-expected": "rewrites the committed "
    "tests/data/netlists/EXPECTED.toml; tests/test_corpus.py checks it instead",
}
#: python blocks not run: (page, first line) → why
SKIPPED_PYTHON = {
    ("architecture.md", "from .base import QuadratureRule"): "a module inside the package "
    "(relative import); tests/test_custom_rule.py registers and runs such a θ-rule",
    ("gradients.md", "import jax, jax.numpy as jnp"): "a sketch of the pattern (make_model, "
    "data are the reader's); tests/test_gradient_examples.py runs the page's two examples",
    ("sweeps.md", "from dask_jobqueue import SLURMCluster"): "needs a Slurm cluster",
    ("sweeps.md", "from dask_kubernetes.operator import KubeCluster"): "needs Kubernetes",
}
#: commands too long for a page run: each runs alone in ``test_slow_command`` (-m slow)
FULL_REPRODUCE = "the paper's experiments in full: 30 s of CPU, minutes on a busy machine"
SLOW = {
    "diracvi reproduce --out reproduce-out": FULL_REPRODUCE,
    "diracvi reproduce --out repro": FULL_REPRODUCE,
    "python benchmarks/corpus.py --markdown": "every public deck against ngspice (minutes)",
}


@dataclass(frozen=True)
class Step:
    kind: str  # "shell" | "python" | "file" | "printed"
    text: str  # the command, the code, the file's content, or the output shown
    line: int  # where it is on the page
    name: str = ""  # a file's name


def shell_commands(body: str, console: bool) -> list[str]:
    """The commands of a shell block: ``#`` comments dropped, ``$ `` prompts of a console
    block (other lines there are output), each ``&&`` part a command of its own."""
    commands = []
    for raw in body.splitlines():
        if console:
            if not raw.startswith("$ "):
                continue
            raw = raw[2:]
        words = shlex.split(raw, comments=True)
        if not words:
            continue
        commands += [part.strip() for part in _without_comment(raw, words).split("&&")]
    return commands


def _without_comment(raw: str, words: list[str]) -> str:
    """``raw`` as written (its quoting kept) up to its comment: the first `` #`` outside
    quotes, i.e. the first whose prefix already splits into all of ``words``."""
    for m in re.finditer(r"\s#", raw):
        try:
            if shlex.split(raw[: m.start()]) == words:
                return raw[: m.start()].strip()
        except ValueError:  # inside a quote
            continue
    return raw.strip()


def page_steps(page: Path) -> list[Step]:
    text = page.read_text(encoding="utf-8")
    steps = []
    for m in FENCE.finditer(text):
        info = m.group("info").strip()
        lang = info.split()[0] if info else ""
        body = "\n".join(line[len(m.group("indent")) :] for line in m.group("body").splitlines())
        line = text.count("\n", 0, m.start()) + 1
        title = TITLE.search(info)
        before = text[: m.start()].rstrip().rsplit("\n", 1)[-1].strip()
        if before == PRINTED:
            steps.append(Step("printed", body, line))
            continue
        if title:
            steps.append(Step("file", body + "\n", line, title.group(1)))
        if lang in ("bash", "console", "sh"):
            steps += [Step("shell", c, line) for c in shell_commands(body, lang == "console")]
        elif lang == "python":
            steps.append(Step("python", body, line))
    return steps


NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
ROUND_OFF = 1e-10


def same_printout(shown: str, printed: str) -> str | None:
    """``None`` if ``printed`` reads as the ``shown`` block, else what differs.

    Line by line (trailing spaces and blank lines at the end ignored): the text between
    numbers must be equal, and each number equal to the digits shown — half a unit of its
    last digit (``1.8e-15`` stands for [1.75e-15, 1.85e-15]). A number shown below
    ``ROUND_OFF`` in magnitude is round-off, whose digits depend on the machine's
    arithmetic: the printed one need only be below ``ROUND_OFF`` too."""
    a, b = shown.rstrip().splitlines(), printed.rstrip().splitlines()
    if len(a) != len(b):
        return f"{len(a)} lines shown, {len(b)} printed:\n{printed}"
    for k, (s, p) in enumerate(zip(a, b, strict=True), 1):
        s, p = s.rstrip(), p.rstrip()
        if NUMBER.sub("#", s) != NUMBER.sub("#", p):
            return f"line {k}: shown {s!r}, printed {p!r}"
        for x, y in zip(NUMBER.findall(s), NUMBER.findall(p), strict=True):
            shown_value, value = float(x), float(y)
            if abs(shown_value) < ROUND_OFF:
                ok = abs(value) < ROUND_OFF
            else:
                mantissa = x.lower().split("e")[0]
                decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
                exponent = int(x.lower().split("e")[1]) if "e" in x.lower() else 0
                ok = abs(value - shown_value) <= 0.5 * 10.0 ** (exponent - decimals) * (1 + 1e-9)
            if not ok:
                return f"line {k}: shown {x}, printed {y} (in {p!r})"
    return None


def test_printouts_are_compared_to_the_digits_shown():
    assert same_printout("a 1.8e-15 b\n7\n", "a 3.2e-16 b\n7") is None  # round-off
    assert same_printout("err 1.8e-15\n", "err 2.0e-09\n") is not None  # not round-off
    assert same_printout("v = 0.25 V\n", "v = 0.254 V\n") is None
    assert same_printout("v = 0.25 V\n", "v = 0.256 V\n") is not None
    assert same_printout("3 problems\n", "2 problems\n") is not None
    assert same_printout("line 3: R1\n", "line 3: R2\n") is not None
    assert same_printout("one\ntwo\n", "one\n") is not None


def _first_line(code: str) -> str:
    return next(line for line in code.splitlines() if line.strip()).strip()


def _skipped(page: Path, step: Step) -> bool:
    if step.kind == "shell":
        return step.text in SKIPPED or step.text in SLOW
    if step.kind == "python":
        return (page.name, _first_line(step.text)) in SKIPPED_PYTHON
    return False


def test_every_command_is_run_or_listed():
    """Each table entry is on some page (a stale entry would hide nothing, but mislead), and
    every page has steps the tests run."""
    steps = {page: page_steps(page) for page in PAGES}
    shell = {s.text for ss in steps.values() for s in ss if s.kind == "shell"}
    for command in [*SKIPPED, *SLOW]:
        assert command in shell, f"{command!r} is listed but no page has it"
    python = {(p.name, _first_line(s.text)) for p, ss in steps.items() for s in ss}
    for key in SKIPPED_PYTHON:
        assert key in python, f"{key} is listed but no page has it"
    run = [p.name for p, ss in steps.items() if any(not _skipped(p, s) for s in ss)]
    assert {"README.md", "getting-started.md", "circuits.md", "sweeps.md"} <= set(run)


def test_shell_blocks_are_read_as_written():
    body = "diracvi list   # the problems\n  # a comment line\na && b 'c # d'\n"
    assert shell_commands(body, console=False) == ["diracvi list", "a", "b 'c # d'"]
    assert shell_commands("$ diracvi list\noutput\n", console=True) == ["diracvi list"]


# ------------------------------------------------------------------ inline commands

INLINE = re.compile(r"`(diracvi(?: [^`]*)?)`")
#: ```` `python SCRIPT.py …` ```` spans, an environment prefix (``PYTHONPATH=src``) allowed
INLINE_SCRIPT = re.compile(r"`((?:[A-Za-z_]\w*=\S* )*python3? [^`\s]+\.py(?: [^`]*)?)`")


def inline_commands(page: Path, pattern: re.Pattern = INLINE) -> list[tuple[int, str]]:
    """The spans of ``page``'s prose (fenced blocks left out) that ``pattern`` finds —
    ```` `diracvi …` ```` by default —, each ``a|b`` word expanded into its alternatives:
    ``(line, command)``."""
    text = FENCE.sub(lambda m: "\n" * m.group(0).count("\n"), page.read_text(encoding="utf-8"))
    found = []
    for m in pattern.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        variants = [[]]
        for word in m.group(1).split():
            alternatives = (
                word.split("|") if "|" in word and not word.startswith("tcp:") else [word]
            )
            if word == "COMMAND":  # `diracvi COMMAND --help`: each of them
                alternatives = list(_command_names())
            variants = [[*v, a] for v in variants for a in alternatives]
        found += [(line, " ".join(v)) for v in variants]
    return found


def _command_names() -> list[str]:
    import typer.main

    from diracvi.cli import app

    return list(typer.main.get_command(app).commands)


def _rest(ctx) -> list[str]:
    """A group's words after its own options (click ≥ 8.2 keeps the subcommand's name
    apart, in ``_protected_args``)."""
    return [*getattr(ctx, "_protected_args", []), *ctx.args]


def check_inline(command: str, tmp: Path) -> str | None:
    """``None`` if the command line accepts ``command`` as far as it goes: every word
    names a command or an option that exists, every choice is one of its choices. A span
    that stops before a value or an argument the command needs (``diracvi sweep
    --scheduler``, ``diracvi run``) names it and passes. Nothing is run: click parses
    into a context without calling the command."""
    import importlib

    import typer.main

    from diracvi.cli import app

    group = typer.main.get_command(app)
    # the click that parses: typer ≥ 0.26 carries its own copy (``typer._click``)
    click = importlib.import_module(type(group).__mro__[1].__module__.rsplit(".", 1)[0])
    exceptions = click.exceptions
    words = shlex.split(command)[1:]
    for word in words:  # file arguments that must exist: empty stand-ins
        if "." in word and not word.startswith("-") and "/" not in word:
            (tmp / word).touch()
    previous = Path.cwd()
    os.chdir(tmp)
    try:
        ctx = group.make_context("diracvi", list(words))
        cmd, args = group, _rest(ctx)
        while hasattr(cmd, "resolve_command") and args:
            name, cmd, args = cmd.resolve_command(ctx, args)
            ctx = cmd.make_context(name, args, parent=ctx)
            args = _rest(ctx) if hasattr(cmd, "resolve_command") else []
        if cmd.name == "bench":  # its --only names are checked by the command itself
            from diracvi.bench import BENCHMARKS

            unknown = [name for name in ctx.params.get("only") or () if name not in BENCHMARKS]
            if unknown:
                return f"--only {unknown}: no such benchmark"
    except (exceptions.MissingParameter, exceptions.NoArgsIsHelpError):
        return None
    except exceptions.BadOptionUsage as e:
        return None if "requires an argument" in e.format_message() else e.format_message()
    except exceptions.ClickException as e:
        return e.format_message()
    except typer.Exit:  # --help, --version: the parse ends there
        return None
    finally:
        os.chdir(previous)
    return None


def test_inline_commands_parse(tmp_path):
    spans = [(p, line, c) for p in PAGES for line, c in inline_commands(p)]
    assert len(spans) > 20
    bad = [f"{p.name}:{line}: `{c}`: {problem}" for p, line, c in spans
           if (problem := check_inline(c, tmp_path))]  # fmt: skip
    assert not bad, "inline commands the command line refuses:\n" + "\n".join(bad)


def test_a_wrong_inline_command_is_caught(tmp_path):
    assert check_inline("diracvi bench --only gradients", tmp_path) is None
    assert check_inline("diracvi cache info", tmp_path) is None
    assert check_inline("diracvi sweep --scheduler", tmp_path) is None  # names the option
    assert "gradient" in check_inline("diracvi bench --only gradient", tmp_path)
    assert check_inline("diracvi run deck.cir --solver newton-ful", tmp_path) is not None
    assert check_inline("diracvi run deck.cir --steps-per 3", tmp_path) is not None
    assert check_inline("diracvi cache wipe", tmp_path) is not None
    assert check_inline("diracvi simulate rlc", tmp_path) is not None


class _Parsed(BaseException):
    """Raised in place of a script's work once its parser has accepted the arguments."""


def check_inline_script(command: str) -> str | None:
    """``None`` if ``command`` — ``[VAR=value …] python SCRIPT.py ARGS`` — names a script of
    this checkout that accepts ``ARGS``, else what is wrong. A script with an ``argparse``
    parser is run in this process, as ``__main__`` with ``sys.argv`` set, up to its
    ``parse_args``, which parses (an unknown option, a missing or mistyped argument exits
    with argparse's message) and then stops the script before it does any work. A script
    without a parser may be named only without arguments (nothing could check them)."""
    import argparse
    import ast
    import runpy

    words = shlex.split(command)
    while words and re.fullmatch(r"[A-Za-z_]\w*=.*", words[0]):
        words.pop(0)  # PYTHONPATH=src
    name, args = words[1], words[2:]
    script = ROOT / name
    if not script.is_file():
        return f"{name}: no such script in the repository"
    calls = {
        node.func.attr
        for node in ast.walk(ast.parse(script.read_text(encoding="utf-8")))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
    }
    if "parse_args" not in calls:
        return None if not args else f"{name} has no argparse parser: its arguments {args} " \
            "cannot be checked (give it one)"  # fmt: skip
    parse = argparse.ArgumentParser.parse_args

    def parse_and_stop(self, args=None, namespace=None):
        parse(self, args, namespace)
        raise _Parsed

    saved = sys.argv, list(sys.path), dict(os.environ)
    errors = io.StringIO()
    argparse.ArgumentParser.parse_args = parse_and_stop
    sys.argv = [str(script), *args]
    sys.path.insert(0, str(script.parent))  # as `python SCRIPT` puts it
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            runpy.run_path(str(script), run_name="__main__")
    except _Parsed:
        return None
    except SystemExit as exit:  # --help exits 0; a refused argument 2, with the message
        return None if exit.code in (0, None) else errors.getvalue().strip().splitlines()[-1]
    finally:
        argparse.ArgumentParser.parse_args = parse
        sys.argv, sys.path[:] = saved[0], saved[1]
        os.environ.clear()
        os.environ.update(saved[2])
    return f"{name} ran to its end without parsing its arguments"


def test_inline_scripts_parse():
    spans = [(p, line, c) for p in PAGES for line, c in inline_commands(p, INLINE_SCRIPT)]
    assert len(spans) >= 5
    bad = [f"{p.name}:{line}: `{c}`: {problem}" for p, line, c in spans
           if (problem := check_inline_script(c))]  # fmt: skip
    assert not bad, "inline script runs that would fail:\n" + "\n".join(bad)


def test_a_wrong_inline_script_is_caught():
    assert check_inline_script("python benchmarks/corpus.py --markdown --only rc") is None
    assert check_inline_script("PYTHONPATH=src python benchmarks/gradient_cost.py 15") is None
    assert check_inline_script("python examples/rolling_disk_long_run.py") is None
    assert "no such script" in check_inline_script("python benchmarks/corpse.py --markdown")
    assert "--markdwn" in check_inline_script("python benchmarks/corpus.py --markdwn")
    assert "invalid int" in check_inline_script("python benchmarks/rigid_formulations.py 1e5")
    assert "argument" in check_inline_script("python benchmarks/chunk_program.py --rounds")
    assert "no argparse" in check_inline_script("python examples/rolling_disk_long_run.py 5")
    assert INLINE_SCRIPT.fullmatch("`PYTHONPATH=src python benchmarks/ladder_step.py 100`")


# ------------------------------------------------------------------ running a page


def _bin(tmp: Path) -> Path:
    """``diracvi`` and ``python`` on PATH: this interpreter, this checkout's package."""
    bin_dir = tmp / "bin"
    bin_dir.mkdir()
    scripts = {
        "diracvi": f'exec "{sys.executable}" -c "from diracvi.cli import app; app()" "$@"\n',
        "python": f'exec "{sys.executable}" "$@"\n',
    }
    for name, body in scripts.items():
        path = bin_dir / name
        path.write_text("#!/bin/sh\n" + body)
        path.chmod(0o755)
    return bin_dir


def _env(bin_dir: Path) -> dict[str, str]:
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(bin_dir), env.get("PATH", "")])
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")]))
    env["MPLBACKEND"] = "Agg"
    return env


def _workdir(tmp: Path) -> Path:
    """A fresh directory that looks like a checkout for the commands that name the
    repository's own scripts (``python benchmarks/corpus.py``, ``examples/...``)."""
    work = tmp / "page"
    work.mkdir()
    for name in ("benchmarks", "examples", "tests"):
        (work / name).symlink_to(ROOT / name)
    return work


def _run_shell(command: str, work: Path, env, where: str, timeout: float = 900) -> str:
    out = subprocess.run(
        ["bash", "-c", command],
        cwd=work,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
    )
    assert out.returncode == 0, (
        f"{where}: `{command}` failed (exit {out.returncode}):\n{out.stdout[-3000:]}\n"
        f"{out.stderr[-3000:]}"
    )
    return out.stdout


def _pages_with_steps():
    return [p for p in PAGES if any(not _skipped(p, s) for s in page_steps(p))]


def run_page(page: Path, tmp: Path) -> None:
    """Run ``page``'s steps in order in a fresh directory under ``tmp``: commands by bash
    there, Python blocks in this process with it as the working directory."""
    work = _workdir(tmp)
    env = _env(_bin(tmp))
    previous = Path.cwd()
    os.chdir(work)
    try:
        namespace: dict = {"__name__": f"docs_{page.stem}"}
        printed = None  # what the last step run printed
        for step in page_steps(page):
            where = f"{page.name}:{step.line}"
            if _skipped(page, step):
                printed = None
                continue
            if step.kind == "file":
                (work / step.name).write_text(step.text, encoding="utf-8")
            elif step.kind == "shell":
                printed = _run_shell(step.text, work, env, where)
            elif step.kind == "printed":
                assert printed is not None, f"{where}: no step before it printed anything"
                problem = same_printout(step.text, printed)
                assert problem is None, f"{where}: the page shows what is not printed: {problem}"
            else:
                out = io.StringIO()
                with contextlib.redirect_stdout(out):
                    exec(compile(step.text, where, "exec"), namespace)
                printed = out.getvalue()
    finally:
        os.chdir(previous)


@pytest.mark.docs
@pytest.mark.parametrize("page", _pages_with_steps(), ids=lambda p: p.name)
def test_page_runs_top_to_bottom(page, tmp_path, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    run_page(page, tmp_path)


def test_a_page_whose_command_fails_fails(tmp_path):
    """The runner itself: files from titled blocks reach the commands after them, and a
    failing command fails the page, naming its line."""
    page = tmp_path / "page.md"
    page.write_text(
        '```text title="data.txt"\nhello\n```\n\n'
        "```bash\ngrep -q hello data.txt   # the file is there\n```\n\n"
        "```python\nassert open('data.txt').read() == 'hello\\n'\n```\n\n"
        "```bash\ngrep -q goodbye data.txt\n```\n",
        encoding="utf-8",
    )
    with pytest.raises(AssertionError, match=r"page\.md:13: `grep -q goodbye data\.txt` failed"):
        run_page(page, tmp_path)


def test_a_page_that_shows_other_output_fails(tmp_path):
    """A printed block is compared with what the step before it printed (Python or shell):
    the page passes while they agree and fails, naming the block's line, once they do not."""
    page = tmp_path / "page.md"
    body = (
        "```python\nprint(f'{2 / 3:.3f} and {1e-17:.1e}')\n```\n\n"
        "<!-- printed by the block above -->\n```text\n0.667 and 3.0e-16\n```\n\n"
        "```bash\necho 3 problems\n```\n\n"
        "<!-- printed by the block above -->\n```text\nSHOWN\n```\n"
    )
    page.write_text(body.replace("SHOWN", "3 problems"), encoding="utf-8")
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    run_page(page, tmp_path / "a")
    page.write_text(body.replace("SHOWN", "2 problems"), encoding="utf-8")
    with pytest.raises(AssertionError, match=r"page\.md:15: the page shows what is not printed"):
        run_page(page, tmp_path / "b")


@pytest.mark.slow
@pytest.mark.parametrize("command", sorted(SLOW))
def test_slow_command(command, tmp_path):
    """The pages' long commands, each alone in a fresh directory (they need no file a page
    writes)."""
    work = _workdir(tmp_path)
    _run_shell(command, work, _env(_bin(tmp_path)), f"SLOW[{command!r}]", timeout=3600)
