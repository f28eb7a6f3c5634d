r"""Every result code of a step, a run, an ensemble member and a sweep point, with its message.

One enum (in the manner of optimistix's ``RESULTS``): each code carries its short
``summary`` (what a traced run and a stored trajectory say) and :meth:`SolveStatus.explain`
gives the full account of a failed step — which step, what residual, what to try. A
solver returns a code, the compiled loop carries it, the host writes the message once.
"""

from __future__ import annotations

import enum

import numpy as np


class SolveStatus(enum.IntEnum):
    """Outcome of one step's solve (the ``status`` of a ``StepResult`` and of a run).

    ``SUCCESS``: the residual met the tolerance. ``MAX_ITERATIONS``: it did not within the
    solver's iteration budget. ``SINGULAR``: the linear solve produced non-finite values
    from finite inputs. ``NONFINITE``: the model itself produced NaN/Inf. ``dv.simulate``
    raises ``StepFailure`` (keeping the partial trajectory) at the first step whose status
    is not ``SUCCESS`` (the trajectory's ``status``/``message`` say why).
    ``AFFINE_REJECTED`` is internal: the affine step map's verification rejected a step,
    and the driver steps on from there with Newton, so no result reports it.
    """

    def __new__(cls, value: int, summary: str):
        member = int.__new__(cls, value)
        member._value_ = value
        member.summary = summary
        return member

    SUCCESS = 0, "success"
    MAX_ITERATIONS = 1, "Newton did not converge"
    SINGULAR = 2, "the step equations became singular"  # non-finite linear solve
    NONFINITE = 3, "NaN or Inf appeared"  # the model itself produced NaN/Inf
    AFFINE_REJECTED = 4, "the affine step map's verification rejected the step"

    def explain(self, *, step: int, t: float, iterations, res_norm, coords, q) -> str:
        """The message of a run that stopped at ``step`` (time ``t``) with this code."""
        where = f"at step {step} (t = {t:.6g})"
        if self is SolveStatus.MAX_ITERATIONS:
            return (
                f"Newton did not converge {where} after {iterations} iterations; residual "
                f"‖r‖∞ = {res_norm:.3e}. Try a smaller dt, check that the initial data are "
                "consistent, or raise NewtonSolver(max_steps=...)."
            )
        if self is SolveStatus.SINGULAR:
            return (
                f"The step equations are not solvable {where}: the step Jacobian became "
                "singular (the linear solve returned non-finite values). The constraints or "
                "the Lagrangian degenerate at this state; try a smaller dt or check the model."
            )
        if self is SolveStatus.NONFINITE:
            bad = [c for c, x in zip(coords, q, strict=True) if not np.isfinite(x)]
            return (
                f"NaN or Inf appeared {where}" + (f" in {bad}" if bad else "") + ": the model "
                "returned non-finite values (a division by zero, a singular mass matrix, or a "
                "blow-up). Try a smaller dt; check L, the constraints and the force at this "
                "state."
            )
        return f"{self.summary} {where}."

    @classmethod
    def legend(cls) -> str:
        """``0 success, 1 …``: how to read a status array of a traced run."""
        public = [s for s in cls if s is not cls.AFFINE_REJECTED]
        return ", ".join(f"{int(s)} {s.summary}" for s in public)


__all__ = ["SolveStatus"]
