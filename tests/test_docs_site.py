"""The documentation site builds with ``--strict`` (broken links, missing references and
failing gallery examples fail it) and every public name has a rendered API entry.

Needs the ``docs`` extra; marked ``docs`` (deselected by default; ``pytest -m docs``).
"""

from __future__ import annotations

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
            after = html[entry.end() : entry.end() + 6000]
            assert "doc-contents" in after, f"no docstring rendered for {anchor}"
            if inspect.isroutine(obj):  # functions show their signature
                assert "doc-signature" in after, f"no signature rendered for {anchor}"


def test_cli_reference_and_gallery_are_rendered(site):
    cli = (site / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    for command in ("list", "run", "plot", "reproduce", "bench"):
        assert f"diracvi {command}" in cli
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
