r"""An ensemble of 10⁴ initial conditions in one call against a Python loop of single runs.

Problem: the paper's torn spring chain (``problems.spring_chain_torn``, 1000 steps). The
initial conditions are the paper's ``(q₀, p₀)`` plus Gaussian perturbations (σ = 0.1,
fixed seed), each projected onto the consistent set (joined ports at equal positions,
momenta the degenerate Lagrangian allows) with ``dv.project_initial_state``.

One side is ``dv.simulate_ensemble(system, q0s, p0s, ..., save_states=False)`` over all
members (one vmapped, compiled call); the other is a Python loop of ``dv.simulate(...,
save_states=False)`` over the first ``LOOP_RUNS`` members, timed interleaved with it and
extrapolated linearly to the whole ensemble (each single run does the same work, so the
loop's time is proportional to its length). Before timing, the ensemble's final states
and energies of those members (``ens[i]``) must equal the single runs' to 1e-12
relative.
"""

from __future__ import annotations

import numpy as np

import diracvi as dv

from .. import problems
from ._core import BenchmarkError, Result, Row, Settings, interleaved, relative_difference
from ._core import summary as time_summary

NAME = "ensemble"
DESCRIPTION = "10⁴ initial conditions in one vmapped call vs a Python loop of single runs"

MEMBERS = {False: 10_000, True: 100}
LOOP_RUNS = {False: 100, True: 10}
SIGMA = 0.1
SEED = 20261121
AGREEMENT = 1e-12


def initial_conditions(problem, members: int, seed: int = SEED):
    """``members`` consistent perturbations of ``(problem.q0, problem.p0)``, shape (B, n)."""
    rng = np.random.default_rng(seed)
    n = problem.system.n
    q = problem.q0 + SIGMA * rng.standard_normal((members, n))
    p = problem.p0 + SIGMA * rng.standard_normal((members, n))
    pairs = [dv.project_initial_state(problem.system, a, b) for a, b in zip(q, p, strict=True)]
    return np.stack([a for a, _ in pairs]), np.stack([b for _, b in pairs])


def run(settings: Settings) -> Result:
    members, loop_runs = MEMBERS[settings.quick], LOOP_RUNS[settings.quick]
    problem = problems.spring_chain_torn()
    system = problem.system
    q0s, p0s = initial_conditions(problem, members)
    kwargs = {"dt": problem.dt, "steps": problem.steps, "save_states": False}

    def ensemble():
        return dv.simulate_ensemble(system, q0s, p0s, **kwargs)

    def loop():
        return [dv.simulate(system, q0s[i], p0s[i], **kwargs) for i in range(loop_runs)]

    ens, singles = ensemble(), loop()
    if not ens.success:
        raise BenchmarkError(f"{int(np.sum(ens.status != 0))} ensemble members failed.")
    members_run = [ens[i] for i in range(loop_runs)]
    diff = max(
        relative_difference([t.final_q for t in members_run], [t.final_q for t in singles]),
        relative_difference([t.final_p for t in members_run], [t.final_p for t in singles]),
        relative_difference([t.energy for t in members_run], [t.energy for t in singles]),
    )
    if diff > AGREEMENT:
        raise BenchmarkError(
            f"the ensemble's final states differ from single runs by {diff:.2e} (relative) "
            f"> {AGREEMENT:g}: the two would not be computing the same thing."
        )
    times = interleaved({"ensemble": ensemble, "loop": loop}, settings.long_repeats)
    t_ens = float(times["ensemble"].min())
    t_loop = float(times["loop"].min()) * members / loop_runs
    rows = [
        Row(
            NAME,
            f"ensemble of {members:,} × {problem.steps} steps (torn spring chain): "
            "Python loop ÷ one simulate_ensemble call",
            t_ens,
            t_loop,
            t_loop / t_ens,
            solver=ens.solver
            if ens.solver == singles[0].solver
            else f"{ens.solver} (single runs: {singles[0].solver})",
            notes=f"loop timed over {loop_runs} runs, extrapolated ×{members // loop_runs}; "
            f"agree to {diff:.1e}; min of {settings.long_repeats}",
        )
    ]
    details = {
        "problem": problem.name,
        "members": members,
        "steps": problem.steps,
        "loop_runs_timed": loop_runs,
        "agreement_relative": diff,
        "times": {name: time_summary(t) for name, t in times.items()},
        "loop_extrapolated_s": t_loop,
        "per_member_s": {"ensemble": t_ens / members, "loop": t_loop / members},
    }
    return Result(rows, details)
