"""Every Python snippet in docs/getting-started.md runs, in order, in one namespace."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOC = Path(__file__).resolve().parents[1] / "docs" / "getting-started.md"
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def python_blocks(text: str) -> list[str]:
    return BLOCK.findall(text)


# 19 s, in `-m slow`: CI's docs tests run every block of getting-started.md top to bottom
# (tests/test_docs_pages.py, `pytest -m docs`)
@pytest.mark.slow
def test_getting_started_snippets_run(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the walk saves chain.nc in the working folder
    blocks = python_blocks(DOC.read_text(encoding="utf-8"))
    assert len(blocks) >= 8
    namespace: dict = {"__name__": "getting_started"}
    for i, code in enumerate(blocks):
        exec(compile(code, f"{DOC.name}[block {i}]", "exec"), namespace)
    assert (tmp_path / "chain.nc").is_file()


def test_walk_covers_the_public_names():
    text = DOC.read_text(encoding="utf-8")
    for name in (
        "dv.LagrangeDiracSystem",
        "dv.connect",
        "dv.interconnect",
        "monolithic()",
        "diracvi reproduce",
        "report.html",
        "summary.json",
    ):
        assert name in text


def test_every_public_name_has_a_docstring():
    """The API reference renders each name's docstring: none may be empty."""
    import importlib
    import inspect

    for module_name in (
        "diracvi",
        "diracvi.dirac",
        "diracvi.problems",
        "diracvi.components",
        "diracvi.spice",
    ):
        module = importlib.import_module(module_name)
        for name in module.__all__:
            obj = getattr(module, name)
            if not (inspect.isclass(obj) or inspect.isroutine(obj)):
                continue  # data (e.g. problems.REGISTRY) carries an attribute docstring
            assert (obj.__doc__ or "").strip(), f"{module_name}.{name} has no docstring"


def test_walk_lists_every_figure_reproduce_writes():
    from diracvi.reproduce import FIGURES

    text = DOC.read_text(encoding="utf-8")
    missing = [name for name in FIGURES if f"`{name}`" not in text]
    assert not missing, f"docs/getting-started.md does not list {missing}"
