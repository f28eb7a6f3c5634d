r"""Driven RLC, 1000 steps: the cost of a time-dependent source on the affine fast path.

Problem: :func:`diracvi.problems.rlc_sine` — a series RLC loop in branch charges (three
KCL one-forms) driven by ``V(t) = V₀ sin ωt`` (``force=F(q, v, t)``), 1000 midpoint
steps. Side by side, timed interleaved in one process: the same circuit written
autonomously (``force=F(q, v)`` with a constant source ``V₀``), same step, same length.

Both must be stepped by the affine step map (the driven one as ``x_{k+1} = M x_k +
c(t_k)``, one offset per step); otherwise :class:`BenchmarkError`, because the ratio would
not measure what it claims. Before timing, the driven run is checked against the closed
form (to the rule's accuracy at this step), so a fast but wrong path cannot pass.
Target: driven ÷ autonomous ≤ 1.5.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

import diracvi as dv

from .. import problems
from ._core import BenchmarkError, Result, Row, Settings, Target, interleaved
from ._core import summary as time_summary

NAME = "driven"
DESCRIPTION = "driven RLC (sine source), 1000 affine steps: cost ÷ the autonomous run"

STEPS = 1000
DT = 0.01
#: the midpoint rule's global error on [0, 10] at h = 0.01 is ~1e-4 (order 2, C ≈ 1.6)
ACCURACY = 1e-3


def autonomous_twin(problem: dv.problems.Problem) -> dv.LagrangeDiracSystem:
    """The circuit of ``problem`` with a constant source ``V₀`` in place of ``V₀ sin ωt``."""
    prm = problem.parameters
    ell, cap, r, v0 = prm["l"], prm["C"], prm["R"], prm["V0"]
    return dv.LagrangeDiracSystem(
        problem.system.coords,
        lambda q, v: 0.5 * ell * v[2] ** 2 - q[3] ** 2 / (2.0 * cap),
        constraints=np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 1.0, -1.0, 0.0], [0.0, 0.0, 1.0, -1.0]]),
        force=lambda q, v: jnp.stack([v0 + 0.0 * v[0], -r * v[1], 0.0 * v[2], 0.0 * v[3]]),
        name="rlc_dc",
    )


def run(settings: Settings) -> Result:
    problem = problems.rlc_sine(dt=DT, steps=STEPS)
    auto = autonomous_twin(problem)
    kwargs = {"dt": DT, "steps": STEPS, "discretization": "midpoint"}

    def driven():
        return dv.simulate(problem.system, problem.q0, problem.p0, **kwargs)

    def autonomous():
        return dv.simulate(auto, problem.q0, problem.p0, **kwargs)

    d, a = driven(), autonomous()
    if d.solver != "affine step map" or a.solver != "affine step map":
        raise BenchmarkError(
            f"driven run stepped by {d.solver!r}, autonomous by {a.solver!r}: both must use "
            "the affine step map for the ratio to mean anything."
        )
    error = float(np.max(np.abs(d.q - problem.exact(d.t))))
    if not error <= ACCURACY:
        raise BenchmarkError(f"the driven run is off its closed form by {error:.2e} > {ACCURACY}.")
    times = interleaved({"driven": driven, "autonomous": autonomous}, settings.numpy_repeats)
    t_driven = float(times["driven"].min())
    t_auto = float(times["autonomous"].min())
    rows = [
        Row(
            NAME,
            f"driven RLC {STEPS} steps (V₀ sin ωt, midpoint): cost ÷ autonomous run",
            t_driven,
            t_auto,
            t_driven / t_auto,
            target=Target("<=", 1.5),
            solver=d.solver,
            notes=f"error vs closed form {error:.1e}; min of {settings.numpy_repeats}, interleaved",
        )
    ]
    details = {
        "problem": problem.name,
        "steps": STEPS,
        "dt": DT,
        "error_vs_closed_form": error,
        "times": {name: time_summary(t) for name, t in times.items()},
    }
    return Result(rows, details)
