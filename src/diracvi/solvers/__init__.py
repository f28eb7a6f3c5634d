"""Solvers for the implicit step equations."""

from typing import TYPE_CHECKING

from ..runtime.lazy import lazy_names

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


__getattr__, __dir__ = lazy_names(__name__, _PUBLIC, globals())

__all__ = [
    "AffineSolver",
    "NewtonSolver",
    "PartitionLayout",
    "PartitionedSolver",
    "SolveStatus",
    "StepResult",
    "StepSolver",
]
