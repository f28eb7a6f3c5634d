"""Solvers for the implicit step equations."""

from .affine import AffineSolver
from .base import SolveStatus, StepResult, StepSolver
from .newton import NewtonSolver
from .partitioned import PartitionedSolver, PartitionLayout

__all__ = [
    "AffineSolver",
    "NewtonSolver",
    "PartitionLayout",
    "PartitionedSolver",
    "SolveStatus",
    "StepResult",
    "StepSolver",
]
