"""Solvers for the implicit step equations."""

from .base import SolveStatus, StepResult, StepSolver
from .newton import NewtonSolver

__all__ = ["NewtonSolver", "SolveStatus", "StepResult", "StepSolver"]
