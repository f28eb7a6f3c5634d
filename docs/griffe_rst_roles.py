"""Griffe extension: Sphinx roles in docstrings (``:class:`~diracvi.Trajectory``` …) become
Markdown, so the API reference shows links or code, never raw roles.

A role whose target is a public name (in some documented module's ``__all__``, given in full
or by its bare name) becomes a cross-reference ``[`label`][module.name]``; any other target
(private modules, members, the standard library) becomes plain code. ``~`` keeps the last
component as the label, as in Sphinx.
"""

from __future__ import annotations

import importlib
import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|attr|mod|obj|data|exc):`(~?)([^`]+)`")
MODULES = ("diracvi", "diracvi.dirac", "diracvi.problems", "diracvi.components", "diracvi.spice")


def _public() -> dict[str, str]:
    """``{full path or bare name: full path}`` of every documented public name."""
    table: dict[str, str] = {}
    for module in reversed(MODULES):  # the top level wins a bare name
        try:
            names = importlib.import_module(module).__all__
        except ModuleNotFoundError:
            continue
        for name in names:
            table[f"{module}.{name}"] = table[name] = f"{module}.{name}"
    return table


class RstRoles(griffe.Extension):
    def __init__(self) -> None:
        super().__init__()
        self.public = _public()

    def _replace(self, match: re.Match) -> str:
        short, target = match.group(1) == "~", match.group(2).strip().removesuffix("()")
        label = target.rsplit(".", 1)[-1] if short else target
        full = self.public.get(target)
        return f"[`{label}`][{full}]" if full else f"`{label}`"

    def on_object(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None and ":`" in obj.docstring.value:
            obj.docstring.value = ROLE.sub(self._replace, obj.docstring.value)
