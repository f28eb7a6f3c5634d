"""Exceptions raised by diracvi.

Every message names the argument (or model part), the offending value and what to do,
so that a modelling mistake never surfaces as a deep JAX traceback.
"""

from __future__ import annotations

from typing import Any


class DiracviError(Exception):
    """Base class of every error diracvi raises on purpose."""


class ModelError(DiracviError, ValueError):
    """A system, interaction or argument is malformed (caught before any step is taken)."""


class UnsolvableStepError(DiracviError, ValueError):
    """The step equations have a singular Jacobian: some unknowns are not determined."""


class StepFailure(DiracviError, RuntimeError):
    """A step could not be solved; ``trajectory`` holds every step completed before it
    (a :class:`~diracvi.Trajectory`; typed loosely so that this module, which every layer
    imports, imports none of them)."""

    def __init__(self, message: str, trajectory: Any):
        super().__init__(message)
        self.trajectory = trajectory
