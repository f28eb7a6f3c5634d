"""A package's public names imported at their first use (PEP 562's module ``__getattr__``).

A package lists each public name with the module that defines it; the first use of a name
imports that module and binds all of its listed names in the package, so a netlist run
imports the parts and solvers it builds, not the rigid bodies or the partitioned solver.
"""

from __future__ import annotations

import importlib


def lazy_names(package: str, public: dict[str, str], namespace: dict):
    """``(__getattr__, __dir__)`` for ``package`` (its ``__name__``), whose names map to
    their modules in ``public``; ``namespace`` is the package's ``globals()``."""

    def __getattr__(name: str):
        if name not in public:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        where = public[name]
        module = importlib.import_module(f"{package}.{where}")
        for other, home in public.items():
            if home == where:
                namespace[other] = getattr(module, other)
        return namespace[name]

    def __dir__() -> list[str]:
        return sorted({*namespace, *public})

    return __getattr__, __dir__


__all__ = ["lazy_names"]
