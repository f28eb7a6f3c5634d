"""Solvers for the implicit step equations."""

from .base import SolveStatus, StepResult, StepSolver
from .newton import NewtonSolver
from .partitioned import PartitionedSolver, PartitionLayout

__all__ = [
    "NewtonSolver",
    "PartitionLayout",
    "PartitionedSolver",
    "SolveStatus",
    "StepResult",
    "StepSolver",
]
