"""What a step solver is: a small immutable object that solves one step's equations.

A solver turns :class:`~diracvi.discretization.equations.StepEquations` and an initial guess
into the unknowns ``x = (q_other, μ)`` and a :class:`SolveStatus`. It may keep a *state* between
time steps (a factorized Jacobian, say); the driver threads that state through the scan
and resets it at the start of every chunk, so chunked and checkpointed runs repeat the
same arithmetic exactly.
"""

from __future__ import annotations

from typing import Any, ClassVar, NamedTuple

import equinox as eqx
import jax

from ..errors import ModelError
from ..status import SolveStatus  # noqa: F401  (re-exported: a solver's codes)


class StepResult(NamedTuple):
    x: jax.Array  # (q_other, μ)
    status: jax.Array  # SolveStatus code
    iterations: jax.Array  # residual evaluations
    residual_norm: jax.Array  # ‖r‖∞ at the last iterate evaluated
    state: Any  # carried to the next step


def check_newton_options(solver) -> None:
    """Reject Newton settings that cannot work, naming the argument and a valid value."""
    name = type(solver).__name__
    for arg, example in (("rtol", "1e-13"), ("floor", "1e-9")):
        value = getattr(solver, arg)
        if not (isinstance(value, int | float) and 0.0 < float(value) < 1.0):
            raise ModelError(
                f"{name}({arg}={value!r}): must be a number in (0, 1), e.g. {example}."
            )
    steps = solver.max_steps
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ModelError(f"{name}(max_steps={steps!r}): must be a whole number ≥ 1, e.g. 40.")
    value = solver.contraction
    if not (isinstance(value, int | float) and 0.0 < float(value) < 1.0):
        raise ModelError(
            f"{name}(contraction={value!r}): must be in (0, 1) — reused factors must shrink "
            "each update — e.g. 0.25."
        )


class StepSolver(eqx.Module):
    """Solves ``r(x) = 0`` for one time step: the (±) discrete Lagrange–Dirac equations in
    the unknowns ``x = (q_other, μ)`` given the known state, then the explicit momentum line.

    Contract for subclasses: ``check`` raises ``ModelError`` (host side, once per plan) when
    the solver cannot step the system; ``init`` gives the traceable state of a chunk;
    ``solve(eqs, guess, state)`` returns a ``StepResult`` whose ``status`` is a
    [`SolveStatus`][diracvi.SolveStatus] and never raises inside compiled code — a failed
    step is reported through the status, and ``dv.simulate`` turns it into ``StepFailure``.
    """

    #: whether a chunk stepped by this solver computes its per-step diagnostics inside
    #: the step loop rather than vectorized over the chunk afterwards (a solver for large
    #: models: the vectorized form holds every step's state and costs more per step)
    diagnostics_per_step: ClassVar[bool] = False

    def check(self, system, rule, scheme: str) -> None:
        """Raise :class:`~diracvi.ModelError` if this solver cannot step ``system`` under
        ``rule`` and ``scheme`` (host side, before anything is compiled)."""

    def init(self, eqs) -> Any:
        """The solver state before the first step of a chunk (traceable)."""
        raise NotImplementedError

    def solve(self, eqs, guess, state, atol=None) -> StepResult:
        """Solve ``eqs.residual(x) = 0`` from ``guess`` (traceable; failures are reported
        in the returned status, not raised). ``atol`` (optional, shaped as ``x``): the
        absolute accuracy per unknown the caller reads the solution to (the variable-step
        loop's coarse step); a solver may stop there or solve further."""
        raise NotImplementedError

    def momentum(self, eqs, x, state=None):
        """The explicit momentum line at the solved ``x`` (a solver that knows the
        system's structure may evaluate it more cheaply)."""
        return eqs.momentum(x)

    def step_program(self, advance):
        """How a chunk runs one step: ``advance`` (a function of one ignored operand,
        closing over the step's inputs, returning its outputs and the new state) as it is, or
        transformed (the traced driver's reverse mode rematerializes it:
        :class:`~diracvi.driver.traced.ImplicitStep`)."""
        return advance
