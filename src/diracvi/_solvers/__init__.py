"""Solvers for the implicit step equations."""

from .affine import AffineSolver
from .base import SolveStatus, StepResult, StepSolver
from .newton import NewtonSolver

__all__ = ["AffineSolver", "NewtonSolver", "SolveStatus", "StepResult", "StepSolver"]
