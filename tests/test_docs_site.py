"""The documentation site builds with ``--strict`` (broken links, missing references and
failing gallery examples fail it) and every public name has a rendered API entry.

Needs the ``docs`` extra; marked ``docs`` (deselected by default; ``pytest -m docs``).
"""

from __future__ import annotations

import html
import importlib
import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.docs

ROOT = Path(__file__).resolve().parents[1]


def _hooks():
    """docs/hooks.py (which modules and examples the site documents); needs mkdocs, so it is
    imported only when a docs test runs — the default run must collect without the extra."""
    pytest.importorskip("mkdocs")
    sys.path.insert(0, str(ROOT / "docs"))
    import hooks

    return hooks


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    pytest.importorskip("mkdocs")
    out = tmp_path_factory.mktemp("site")
    env = dict(os.environ, NO_MKDOCS_2_WARNING="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), env.get("PYTHONPATH")]))
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert run.returncode == 0, f"mkdocs build --strict failed:\n{run.stdout}\n{run.stderr}"
    return out


def test_every_public_name_has_a_rendered_api_entry(site):
    hooks = _hooks()
    modules = hooks.public_modules()
    assert {"diracvi", "diracvi.dirac", "diracvi.problems"} <= set(modules)
    for module, names in modules.items():
        assert names, f"{module} has an empty __all__"
        html = (site / "reference" / module / "index.html").read_text(encoding="utf-8")
        for name in names:
            anchor = hooks.api_identifier(module, name)
            entry = re.search(rf'id="{re.escape(anchor)}"', html)
            assert entry, f"no API entry for {anchor}"
            obj = getattr(importlib.import_module(module), name)
            # this entry's own HTML: up to the next entry's heading (a fixed window cut off
            # REGISTRY's docstring once its rendered value grew past 6000 characters)
            following = html.find('class="doc doc-heading"', html.index(">", entry.end()))
            after = html[entry.end() : following if following != -1 else len(html)]
            assert "doc-contents" in after, f"no docstring rendered for {anchor}"
            if inspect.isroutine(obj):  # functions show their signature
                assert "doc-signature" in after, f"no signature rendered for {anchor}"


def _headed_sections(page_html: str) -> dict[str, str]:
    """``{heading text: the HTML up to the next heading}`` of a rendered page."""
    parts = re.split(r"<h[1-6][^>]*>(.*?)</h[1-6]>", page_html, flags=re.S)
    text = [html.unescape(re.sub(r"<[^>]+>", "", h)).replace("¶", "") for h in parts[1::2]]
    text = [t.removeprefix("Command line:").strip() for t in text]
    return dict(zip(text, parts[2::2], strict=True))


def test_cli_reference_shows_every_command_and_option(site):
    """The CLI page is generated from the typer app: every command and subcommand has its
    section, and each section shows every option of that command."""
    hooks = _hooks()
    tree = hooks.cli_command_tree()
    assert {"diracvi sweep", "diracvi cache info", "diracvi cache clear"} <= set(tree)
    cli = (site / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    sections = _headed_sections(cli)
    for command, options in tree.items():
        assert command in sections, f"the CLI page has no section for {command}"
        for option in options:
            assert f"<code>{option}" in sections[command], f"{command} {option} is not shown"
    overview = (site / "reference" / "index.html").read_text(encoding="utf-8")
    assert " | ".join(hooks.cli_commands()) in overview


def test_gallery_is_rendered(site):
    scripts = _hooks().gallery_scripts()
    assert len(scripts) >= 6
    for script, _ in scripts:
        page = site / "gallery" / script.stem / "index.html"
        assert page.is_file(), f"no gallery page for {script.name}"
        figure = site / "gallery" / script.stem / f"{script.stem}.png"
        if not figure.is_file():  # use_directory_urls puts the figure next to the page dir
            figure = site / "gallery" / f"{script.stem}.png"
        assert figure.is_file() and figure.stat().st_size > 1000, f"no figure for {script.name}"
        assert f"{script.stem}.png" in page.read_text(encoding="utf-8")
    home = (site / "index.html").read_text(encoding="utf-8")
    assert "spring_chain.png" in home


def _doc_equations() -> list[tuple[str, str, bool]]:
    """``(page, tex, display)`` of every equation in docs/*.md, as arithmatex marks them."""
    import markdown

    hooks = _hooks()
    found = []
    for page in sorted((ROOT / "docs").glob("*.md")):
        md = markdown.Markdown(
            extensions=["pymdownx.arithmatex", "pymdownx.superfences"],
            extension_configs={"pymdownx.arithmatex": {"generic": True}},
        )
        for m in hooks.ARITHMATEX.finditer(md.convert(page.read_text(encoding="utf-8"))):
            found.append((page.name, html.unescape(m.group("tex")), m.group("open") == "["))
    return found


def test_every_equation_of_the_docs_converts_to_mathml():
    equations = _doc_equations()
    assert len(equations) >= 8  # docs/index.md alone has eight
    hooks = _hooks()
    for page, tex, display in equations:
        out = hooks.tex_to_mathml(tex, display)  # raises on an equation it cannot convert
        assert out.startswith("<math") and "\\" not in out, (page, tex)


@pytest.mark.parametrize(
    "tex",
    [r"\frac{a}", r"\unknowncommand x", r"\begin{aligned} a &= b \end{aligned}"],
)
def test_an_unconvertible_equation_is_refused(tex):
    with pytest.raises(ValueError, match="equation"):
        _hooks().tex_to_mathml(tex, display=True)


def test_the_site_shows_equations_as_mathml_and_loads_nothing_from_another_host(site):
    pages = sorted(site.rglob("*.html"))
    assert len(pages) > 20
    external = re.compile(r"""<(?:script|link|img|iframe)\b[^>]*(?:src|href)=["']?(?:https?:)?//""")
    for page in pages:
        text = page.read_text(encoding="utf-8")
        where = page.relative_to(site)
        assert not external.search(text), f"{where} loads {external.search(text)[0]}"
        assert 'class="arithmatex"' not in text, f"{where} has unconverted TeX"
    home = (site / "index.html").read_text(encoding="utf-8")
    assert home.count("<math") >= 8 and 'display="block"' in home
