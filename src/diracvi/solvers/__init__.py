"""Solvers for the implicit step equations."""

import importlib
from typing import TYPE_CHECKING

#: public name -> its module, imported at the first use of the name: a module of this
#: package (a linear netlist's sparse map, its condensed solve) does not import the others
_PUBLIC = {
    "AffineSolver": "affine",
    "NewtonSolver": "newton",
    "PartitionLayout": "partitioned",
    "PartitionedSolver": "partitioned",
    "SolveStatus": "base",
    "StepResult": "base",
    "StepSolver": "base",
}

if TYPE_CHECKING:  # the same names as type checkers and the API docs (griffe) read them
    from .affine import AffineSolver
    from .base import SolveStatus, StepResult, StepSolver
    from .newton import NewtonSolver
    from .partitioned import PartitionedSolver, PartitionLayout


def __getattr__(name: str):
    """A public name, imported at its first use."""
    if name not in _PUBLIC:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_PUBLIC[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_PUBLIC})


__all__ = [
    "AffineSolver",
    "NewtonSolver",
    "PartitionLayout",
    "PartitionedSolver",
    "SolveStatus",
    "StepResult",
    "StepSolver",
]
