"""Exceptions raised by diracvi.

Every message names the argument (or model part), the offending value and what to do,
so that a modelling mistake never surfaces as a deep JAX traceback.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ._trajectory import Trajectory


class DiracviError(Exception):
    """Base class of every error diracvi raises on purpose."""


class ModelError(DiracviError, ValueError):
    """A system, interaction or argument is malformed (caught before any step is taken)."""


class UnsolvableStepError(DiracviError, ValueError):
    """The step equations have a singular Jacobian: some unknowns are not determined."""


class StepFailure(DiracviError, RuntimeError):
    """A step could not be solved; ``trajectory`` holds every step completed before it."""

    def __init__(self, message: str, trajectory: Trajectory):
        super().__init__(message)
        self.trajectory = trajectory
