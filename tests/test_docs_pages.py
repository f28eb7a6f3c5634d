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
- other blocks (``text`` without a title, untagged) are output or diagrams: not run.

The page runs are marked ``docs`` (deselected by default, run in CI by ``.ci/run``: a page
takes seconds to a minute); ``test_every_command_is_run_or_listed`` is in the default run
and fails when a page gains a command the tables do not cover or a table entry no page has.
"""

from __future__ import annotations

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
    kind: str  # "shell" | "python" | "file"
    text: str  # the command, the code, or the file's content
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
        if title:
            steps.append(Step("file", body + "\n", line, title.group(1)))
        if lang in ("bash", "console", "sh"):
            steps += [Step("shell", c, line) for c in shell_commands(body, lang == "console")]
        elif lang == "python":
            steps.append(Step("python", body, line))
    return steps


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


def _run_shell(command: str, work: Path, env, where: str, timeout: float = 900) -> None:
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
        for step in page_steps(page):
            where = f"{page.name}:{step.line}"
            if _skipped(page, step):
                continue
            if step.kind == "file":
                (work / step.name).write_text(step.text, encoding="utf-8")
            elif step.kind == "shell":
                _run_shell(step.text, work, env, where)
            else:
                exec(compile(step.text, where, "exec"), namespace)
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


@pytest.mark.slow
@pytest.mark.parametrize("command", sorted(SLOW))
def test_slow_command(command, tmp_path):
    """The pages' long commands, each alone in a fresh directory (they need no file a page
    writes)."""
    work = _workdir(tmp_path)
    _run_shell(command, work, _env(_bin(tmp_path)), f"SLOW[{command!r}]", timeout=3600)
