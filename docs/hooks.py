"""MkDocs hook: pages generated at build time (nothing generated is committed).

- **API reference** — one page per public module (``diracvi``, ``diracvi.dirac``,
  ``diracvi.problems``, and ``diracvi.components`` / ``diracvi.spice`` once they exist),
  one mkdocstrings entry per name of the module's ``__all__``: a new public name appears
  without editing the docs.
- **CLI reference** — typer's own ``utils docs`` output for ``diracvi.cli``.
- **Gallery** — every ``examples/*.py`` with a ``# gallery: TITLE`` line is run (two at a
  time) with the figure's path as its argument; its page shows the docstring, the figure
  and the code. A failing example fails the build.
- **Equations as MathML** — every ``\\( … \\)`` / ``\\[ … \\]`` that
  ``pymdownx.arithmatex`` (generic mode) marks is converted to MathML by ``latex2mathml``
  when the page is built, so the site shows its equations without a network and without a
  script (browsers render MathML Core natively). An equation that does not convert fails
  the build.

The nav sections "API reference" and "Gallery" of ``mkdocs.yml`` are filled here.
"""

from __future__ import annotations

import ast
import html
import importlib
import importlib.util
import inspect
import logging
import os
import re
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File

log = logging.getLogger("mkdocs.hooks.diracvi")

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
#: public modules documented, in nav order (missing ones are skipped)
MODULES = ("diracvi", "diracvi.dirac", "diracvi.problems", "diracvi.components", "diracvi.spice")
GALLERY_MARK = re.compile(r"^# gallery:\s*(.+)$", re.M)
EXAMPLE_TIMEOUT = 300  # seconds per example (each is meant to take well under a minute)

if str(ROOT / "src") not in sys.path:  # a source checkout without an installed diracvi
    sys.path.insert(0, str(ROOT / "src"))


def public_modules() -> dict[str, list[str]]:
    """``{module: sorted __all__}`` for every documented module that can be imported."""
    found = {}
    for name in MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name is not None and name.startswith(exc.name):
                continue  # the module does not exist (yet)
            raise
        found[name] = sorted(getattr(module, "__all__", ()))
    return found


def gallery_scripts() -> list[tuple[Path, str]]:
    """``(script, title)`` of every gallery example, in file-name order."""
    scripts = []
    for path in sorted(EXAMPLES.glob("*.py")):
        mark = GALLERY_MARK.search(path.read_text(encoding="utf-8"))
        if mark:
            scripts.append((path, mark.group(1).strip()))
    return scripts


def _markdown(doc: str) -> str:
    """A module docstring (reST-flavoured) as Markdown: roles and ````x```` become code,
    ``::``-introduced or indented blocks become Python code blocks."""
    doc = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", doc)
    doc = re.sub(r"``([^`]+)``", r"`\1`", doc)
    out, code = [], []
    for line in [*doc.splitlines(), "<end>"]:
        if line.startswith("    ") or (code and not line.strip()):
            code.append(line[4:])
            continue
        if code:
            out += ["```python", *[c for c in code if c.strip()], "```", ""]
            code = []
        out.append(line)
    return "\n".join(out[:-1]).replace("::\n", ":\n")


def api_identifier(module: str, name: str) -> str:
    """The dotted path mkdocstrings documents ``module.name`` under: ``module.name`` itself,
    unless a submodule has the same name as the function it exports (``problems.dc_motor``),
    then the object's defining path (else griffe would document the submodule)."""
    obj = getattr(importlib.import_module(module), name)
    if inspect.ismodule(obj) or importlib.util.find_spec(f"{module}.{name}") is None:
        return f"{module}.{name}"
    return f"{obj.__module__}.{obj.__qualname__}"


def _summary(obj) -> str:
    doc = (getattr(obj, "__doc__", None) or "").strip()
    if isinstance(obj, dict | list | tuple | str | int | float):
        return ""  # instances: their type's docstring says nothing about them
    first = " ".join(re.split(r"\n\s*\n", doc, maxsplit=1)[0].split())
    return _markdown(first).strip().replace("|", "\\|")


def _api_page(module: str, names: list[str]) -> str:
    mod = importlib.import_module(module)
    lines = [f"# `{module}`", "", _markdown((mod.__doc__ or "").strip("\n")), ""]
    lines += ["| name | summary |", "|---|---|"]
    lines += [
        f"| [`{n}`][{api_identifier(module, n)}] | {_summary(getattr(mod, n))} |" for n in names
    ]
    lines.append("")
    for n in names:
        lines += [f"::: {api_identifier(module, n)}", ""]
    return "\n".join(lines)


def _cli_page() -> str:
    out = subprocess.run(
        [sys.executable, "-m", "typer", "diracvi.cli", "utils", "docs", "--name", "diracvi"],
        capture_output=True,
        text=True,
        env=_env(),
        cwd=ROOT,
        check=False,
    )
    if out.returncode != 0:
        raise PluginError(f"typer could not document diracvi.cli:\n{out.stderr}")
    body = out.stdout.replace("# `diracvi`", "# Command line: `diracvi`", 1)
    return body


def cli_command_tree() -> dict[str, list[str]]:
    """``{"diracvi run": ["--out", ...], ...}``: every command and subcommand of the typer
    app, with the option strings of each (what the generated CLI page must show)."""
    import typer

    from diracvi.cli import app

    tree: dict[str, list[str]] = {}

    def walk(command, path: str) -> None:  # typer's (vendored) click Command / Group
        tree[path] = sorted(
            opt
            for p in command.params
            if p.param_type_name == "option"
            for opt in [*p.opts, *p.secondary_opts]
        )
        for name, sub in sorted(getattr(command, "commands", {}).items()):
            if not sub.hidden:
                walk(sub, f"{path} {name}")

    walk(typer.main.get_command(app), "diracvi")
    return tree


def cli_commands() -> list[str]:
    """The top-level commands, in the app's order."""
    import typer

    from diracvi.cli import app

    return [n for n, c in typer.main.get_command(app).commands.items() if not c.hidden]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT / "src"), str(EXAMPLES), *filter(None, [env.get("PYTHONPATH")])]
    )
    env["MPLBACKEND"] = "Agg"
    return env


def _run_example(script: Path, figure: Path) -> tuple[str, float]:
    t0 = time.perf_counter()
    try:
        out = subprocess.run(
            [sys.executable, str(script), str(figure)],
            capture_output=True,
            text=True,
            env=_env(),
            cwd=EXAMPLES,
            timeout=EXAMPLE_TIMEOUT,
            check=False,
        )
    except subprocess.TimeoutExpired as exc:
        raise PluginError(f"example {script.name} ran over {EXAMPLE_TIMEOUT} s") from exc
    if out.returncode != 0 or not figure.is_file():
        raise PluginError(
            f"example {script.name} failed (exit {out.returncode}) or wrote no figure:\n"
            f"{out.stderr[-3000:]}"
        )
    return out.stdout, time.perf_counter() - t0


def _gallery_page(script: Path, title: str, stdout: str) -> str:
    source = script.read_text(encoding="utf-8")
    doc = ast.get_docstring(ast.parse(source)) or ""
    # the docstring is shown as prose; the code block shows the script without it
    code = re.sub(r'^""".*?"""\n+', "", source, count=1, flags=re.S)
    code = GALLERY_MARK.sub("", code).lstrip("\n")
    return "\n".join(
        [
            f"# {title}",
            "",
            doc,
            "",
            f"![{title}]({script.stem}.png)",
            "",
            "Output, when this page was built:",
            "",
            "```text",
            stdout.strip() or "(nothing printed)",
            "```",
            "",
            f"Source: `examples/{script.name}`",
            "",
            "```python",
            code.rstrip(),
            "```",
            "",
        ]
    )


def _gallery_index(scripts) -> str:
    lines = [
        "# Gallery",
        "",
        "Each example is a script under `examples/` that runs in under a minute and",
        "writes its figure; the figures below were produced when this site was built.",
        "",
        '<div class="grid cards" markdown>',
        "",
    ]
    for script, title in scripts:
        lines += [
            f"-   [**{title}**]({script.stem}.md)",
            "",
            f"    [![{title}]({script.stem}.png)]({script.stem}.md)",
            "",
        ]
    lines += ["</div>", ""]
    return "\n".join(lines)


# ---------------------------------------------------------------- equations

#: what ``pymdownx.arithmatex`` (generic mode) writes: ``\\(…\\)`` in a span, ``\\[…\\]`` in a div
ARITHMATEX = re.compile(
    r'<(?P<tag>span|div) class="arithmatex">\\(?P<open>[(\[])(?P<tex>.*?)\\[)\]]</(?P=tag)>', re.S
)
MATHML = "{http://www.w3.org/1998/Math/MathML}"
#: MathML elements with a fixed number of children (a TeX argument lost in conversion shows
#: up as a missing child, e.g. ``\\frac{a}`` → an ``mfrac`` with one)
ARITY = {"mfrac": 2, "msub": 2, "msup": 2, "msubsup": 3, "mover": 2, "munder": 2,
         "munderover": 3, "mroot": 2}  # fmt: skip


def tex_to_mathml(tex: str, display: bool) -> str:
    """The MathML of one TeX equation; ``ValueError`` naming the equation when latex2mathml
    cannot convert it: it raises, leaves a TeX command (``\\foo``) or an ``&`` of an
    environment it does not know as text, writes malformed XML, or loses an argument."""
    from latex2mathml.converter import convert

    try:
        out = convert(tex, display="block" if display else "inline")
        root = ET.fromstring(out)
    except Exception as exc:  # latex2mathml's own errors, or XML it wrote malformed
        raise ValueError(f"equation {tex.strip()!r} does not convert to MathML: {exc}") from exc
    for node in root.iter():
        name = node.tag.removeprefix(MATHML)
        text = node.text or ""
        if name in {"mi", "mo", "mtext"} and ("\\" in text or text == "&"):
            raise ValueError(
                f"equation {tex.strip()!r}: {text!r} was not understood by latex2mathml "
                "(an unsupported command or environment; aligned → split, for instance)"
            )
        if name in ARITY and len(node) != ARITY[name]:
            raise ValueError(
                f"equation {tex.strip()!r}: <{name}> has {len(node)} parts, not {ARITY[name]} "
                "(a missing argument or brace)"
            )
    return out


def page_mathml(page_html: str, where: str) -> str:
    """``page_html`` with every arithmatex equation replaced by its MathML."""

    def one(m: re.Match) -> str:
        tex = html.unescape(m.group("tex"))
        try:
            return tex_to_mathml(tex, display=m.group("open") == "[")
        except ValueError as exc:
            raise PluginError(f"{where}: {exc}") from exc

    return ARITHMATEX.sub(one, page_html)


# ---------------------------------------------------------------- MkDocs events


def _fill_nav(nav, section: str, entries: list) -> None:
    for item in nav:
        if isinstance(item, dict) and section in item:
            item[section] = entries
            return
    nav.append({section: entries})


def on_config(config):
    modules = public_modules()
    api = [{"Overview": "reference/index.md"}]
    api += [{f"{m}": f"reference/{m}.md"} for m in modules]
    api.append({"Command line": "reference/cli.md"})
    if config.nav is not None:
        _fill_nav(config.nav, "API reference", api)
        gallery = [{"Overview": "gallery/index.md"}]
        gallery += [{title: f"gallery/{s.stem}.md"} for s, title in gallery_scripts()]
        _fill_nav(config.nav, "Gallery", gallery)
    return config


def on_files(files, config):
    def add(uri: str, content: str | bytes) -> None:
        files.append(File.generated(config, uri, content=content))

    modules = public_modules()
    index = [
        "# API reference",
        "",
        "Generated from the docstrings of every name in each public module's `__all__`.",
        "",
    ]
    for module, names in modules.items():
        add(f"reference/{module}.md", _api_page(module, names))
        index.append(f"- [`{module}`]({module}.md) — {len(names)} names")
    index.append(f"- [Command line](cli.md) — `diracvi {' | '.join(cli_commands())}`")
    add("reference/index.md", "\n".join(index) + "\n")
    add("reference/cli.md", _cli_page())

    scripts = gallery_scripts()
    with tempfile.TemporaryDirectory() as tmp:
        figures = {s: Path(tmp) / f"{s.stem}.png" for s, _ in scripts}
        t0 = time.perf_counter()
        with ThreadPoolExecutor(max_workers=2) as pool:
            runs = list(pool.map(lambda s: _run_example(s, figures[s]), [s for s, _ in scripts]))
        log.info("gallery: %d examples ran in %.0f s", len(scripts), time.perf_counter() - t0)
        for (script, title), (stdout, seconds) in zip(scripts, runs, strict=True):
            log.info("gallery: %s ran in %.0f s", script.name, seconds)
            add(f"gallery/{script.stem}.md", _gallery_page(script, title, stdout))
            add(f"gallery/{script.stem}.png", figures[script].read_bytes())
    add("gallery/index.md", _gallery_index(scripts))
    return files


def on_page_content(html_text, page, config, files):
    return page_mathml(html_text, page.file.src_uri)
