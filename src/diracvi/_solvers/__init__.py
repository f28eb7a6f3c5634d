"""Solvers for the implicit step equations."""

from .newton import NewtonSolver, SolveStatus

__all__ = ["NewtonSolver", "SolveStatus"]
