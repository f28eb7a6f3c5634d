"""The paper's §5 experiments, run with diracvi: each torn model beside its monolithic twins.

For each example the torn (interconnected) problem is simulated together with

- ``system.monolithic()`` — the same Lagrangian and constraints on the same ``Q``, as one
  system (the paper's theorem says the two step maps coincide), and
- the hand-built reduced model ``problem.reduced`` without port variables (what the
  paper calls "the monolithic system"), compared on the shared coordinates;

plus the studies the paper lacks: the midpoint rule beside the paper's retraction rule
(against the exact solution) and, for the circuit, the paper's printed resistor sign.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np

from .. import problems
from ..driver.simulate import simulate
from ..driver.trajectory import Trajectory
from ..model.system import LagrangeDiracSystem
from ..problems import Problem
from . import metrics, paper
from .timing import TIMING_PROTOCOL, time_simulations


@dataclass(frozen=True)
class Settings:
    """How much work ``reproduce`` does: the paper's protocol, or a quick smoke run."""

    quick: bool = False
    repeats: int = 1000
    long_steps: int = 100_000
    refinements: int = 3  # step sizes h, h/2, h/4 for the order study

    @classmethod
    def make(cls, quick: bool = False, repeats: int | None = None) -> Settings:
        if quick:
            return cls(quick=True, repeats=repeats or 20, long_steps=10_000, refinements=2)
        return cls(quick=False, repeats=repeats or 1000, long_steps=100_000, refinements=3)


@dataclass(frozen=True)
class Example:
    """One §5 example: its torn problem and what its figures show."""

    key: str  # summary key, e.g. "spring_chain"
    problem: str  # registry name of the torn model
    paper: dict
    headline: str | None = None  # reduced coordinate of the "capacitor charge" figure
    long_run: bool = False  # the 100,000-step energy run (spring chain only)
    resistor_sign: bool = False  # compare the paper's printed force sign (RLC only)


EXAMPLES = (
    Example("spring_chain", "spring-chain-torn", paper.SPRING_CHAIN, long_run=True),
    Example("rlc", "rlc-torn", paper.RLC, headline="qC", resistor_sign=True),
)


@dataclass
class ExampleResult:
    """Every trajectory and number of one example (the figures and summary read these)."""

    example: Example
    problem: Problem
    interconnected: Trajectory
    monolithic: Trajectory
    reduced: Trajectory
    long_run: Trajectory | None = None
    rules: dict[str, Trajectory] = field(default_factory=dict)
    energy_errors: dict[str, tuple] = field(default_factory=dict)  # rule → (t, E_k − E_exact)
    exact_samples: tuple | None = None  # (t, exact q(t)) at the sampled steps
    exact: Callable | None = None  # reduced-coordinate exact solution q(t)
    sign: dict[str, Trajectory] = field(default_factory=dict)
    summary: dict = field(default_factory=dict)

    @property
    def reduced_system(self):
        return self.problem.reduced.system

    @property
    def shared(self) -> dict[str, str]:
        return dict(self.problem.shared)

    @property
    def ports(self) -> tuple[tuple[str, str], ...]:
        return tuple(tuple(p) for p in self.problem.ports)

    def torn_name(self, reduced_name: str) -> str:
        """The torn model's coordinate that the reduced model calls ``reduced_name``."""
        for torn, red in self.shared.items():
            if red == reduced_name:
                return torn
        raise KeyError(f"{reduced_name!r} is not a shared coordinate of {self.problem.name!r}")


def _run(problem_or_system, q0, p0, dt, steps, discretization="retraction") -> Trajectory:
    return simulate(problem_or_system, q0, p0, dt=dt, steps=steps, discretization=discretization)


def interaction_names(system) -> tuple[str, ...]:
    """Names of the interaction rows (the λ's) among ``system.constraint_names``."""
    return tuple(getattr(system, "interaction_names", ()))


def paper_sign_system(system: LagrangeDiracSystem) -> LagrangeDiracSystem:
    """``system`` with its force negated, ``F'(q, v) = −F(q, v)``.

    Under the left-point rule this is exactly the paper's printed discrete force
    ``f_d^− = −h F`` (§5.2), which makes the resistor a negative resistance.
    """

    def lagrangian(q, v):
        return system.lagrangian(q, v)

    def forms(q):
        return system.constraint_forms(q)

    def force(q, v):
        return -system.force(q, v)

    return LagrangeDiracSystem(
        system.coords,
        lagrangian,
        constraints=forms if system.m else None,
        force=force,
        name=f"{getattr(system, 'name', 'system')}-paper-sign",
        constraint_names=system.constraint_names if system.m else None,
    )


#: where each rule evaluates E(q, v) within a step, as a fraction of h
NODE_OFFSET = {"retraction": 0.0, "midpoint": 0.5}


def exact_energy(system, exact: Callable, t, eps: float = 1e-6) -> np.ndarray:
    """``E(q(t), q̇(t))`` along the exact solution.

    ``q`` and ``q̇`` come from ``exact`` at ``t ± eps`` (mean and central difference, both
    accurate to O(eps²)); each call of ``exact`` is a matrix exponential per instant.
    """
    t = np.asarray(t, dtype=np.float64)
    after, before = exact(t + eps), exact(t - eps)
    q, v = 0.5 * (after + before), (after - before) / (2.0 * eps)
    energy = jax.vmap(system.energy)(jnp.asarray(q), jnp.asarray(v))
    return np.asarray(energy)


#: the exact solution (a matrix exponential per instant) is evaluated at this many
#: evenly spaced steps of a run, the same physical instants at every step size
SAMPLES = 100


def sample_steps(steps: int, refine: int = 1) -> np.ndarray:
    """Indices of :data:`SAMPLES` + 1 evenly spaced states of a ``steps``-step run, scaled
    to the same instants of the run refined ``refine`` times."""
    base = np.unique(np.linspace(0, steps, SAMPLES + 1).round().astype(int))
    return base * refine


def energy_error(traj: Trajectory, system, exact: Callable):
    """``(t, E_k − E_exact)`` at sampled steps, the exact energy taken at the quadrature
    node of each step (``t_k`` for the retraction rule, ``t_k + h/2`` for the midpoint)."""
    k = sample_steps(traj.steps - 1)
    node = traj.t[k] + NODE_OFFSET[traj.discretization] * (traj.t[k + 1] - traj.t[k])
    return node, traj.energy[k] - exact_energy(system, exact, node)


def _error_vs_exact(traj: Trajectory, index, reference, pairs: dict[str, str], coords) -> float:
    """``max |q_k − q(t_k)|`` over the sampled steps ``index`` and the shared coordinates;
    ``reference`` holds the exact ``q(t_k)`` at those steps, in reduced coordinates."""
    return max(
        metrics.max_abs(traj[t][index] - reference[:, coords.index(r)]) for t, r in pairs.items()
    )


def run_example(example: Example, settings: Settings, progress) -> ExampleResult:
    """Simulate one example and fill ``ExampleResult.summary`` (see module doc)."""
    torn = problems.get(example.problem)
    reduced = torn.reduced
    dt, steps = torn.dt, torn.steps
    progress.step(f"{example.key}: interconnected, monolithic and reduced runs")
    inter = _run(torn.system, torn.q0, torn.p0, dt, steps)
    mono_system = torn.system.monolithic()
    mono = _run(mono_system, torn.q0, torn.p0, dt, steps)
    red = _run(reduced.system, reduced.q0, reduced.p0, dt, steps)
    result = ExampleResult(example, torn, inter, mono, red, exact=reduced.exact)

    if example.long_run:
        progress.step(f"{example.key}: {settings.long_steps:,}-step energy run")
        result.long_run = _run(torn.system, torn.q0, torn.p0, dt, settings.long_steps)

    progress.step(f"{example.key}: retraction vs midpoint against the exact solution")
    rule_summary = {}
    if reduced.exact is not None:
        # the same physical instants in every run, so the exact solution is evaluated once
        t_sampled = inter.t[sample_steps(steps)]
        result.exact_samples = (t_sampled, reduced.exact(t_sampled))
        for rule in ("retraction", "midpoint"):
            model = torn if rule in torn.discretizations else reduced
            pairs = (
                result.shared if model is torn else metrics.identity_pairs(reduced.system.coords)
            )
            dts = [dt / 2**i for i in range(settings.refinements)]
            runs = [
                _run(model.system, model.q0, model.p0, h, steps * 2**i, rule)
                for i, h in enumerate(dts)
            ]
            result.rules[rule] = runs[0]
            result.energy_errors[rule] = energy_error(runs[0], reduced.system, reduced.exact)
            errors = [
                _error_vs_exact(
                    r,
                    sample_steps(steps, 2**i),
                    result.exact_samples[1],
                    pairs,
                    reduced.system.coords,
                )
                for i, r in enumerate(runs)
            ]
            rule_summary[rule] = {
                "model": model.name,
                "dts": dts,
                "sampled_times": len(sample_steps(steps)),
                "max_error_vs_exact": errors,
                "fitted_order": metrics.fitted_order(errors, dts),
                "max_energy_error": metrics.max_abs(result.energy_errors[rule][1]),
            }

    if example.resistor_sign:
        progress.step(f"{example.key}: the paper's printed resistor sign")
        result.sign = {
            "physical": red,
            "paper": _run(paper_sign_system(reduced.system), reduced.q0, reduced.p0, dt, steps),
        }

    progress.step(
        f"{example.key}: timing the interconnected model, interleaved with the reduced and "
        "monolithic ones",
        total=settings.repeats,
    )
    timing = time_simulations(
        {
            "reduced": (reduced.system, reduced.q0, reduced.p0),
            "monolithic": (mono_system, torn.q0, torn.p0),
            "interconnected": (torn.system, torn.q0, torn.p0),
        },
        dt=dt,
        steps=steps,
        repeats=settings.repeats,
        tick=progress.tick,
    )

    result.summary = _summarize(result, settings, rule_summary, timing)
    return result


def _summarize(result: ExampleResult, settings: Settings, rules: dict, timing: dict) -> dict:
    torn, inter, mono, red = (
        result.problem,
        result.interconnected,
        result.monolithic,
        result.reduced,
    )
    same = metrics.identity_pairs(torn.system.coords)
    ports = metrics.port_deviation(inter, result.ports)
    interaction = interaction_names(torn.system)
    pt = result.example.paper["timing"]
    summary = {
        "title": result.example.paper["title"],
        "problem": torn.name,
        "reduced_problem": torn.reduced.name,
        "coords": list(torn.system.coords),
        "reduced_coords": list(torn.reduced.system.coords),
        "shared": result.shared,
        "ports": [list(p) for p in result.ports],
        "constraint_names": list(inter.constraint_names),
        "interaction_constraints": list(interaction),
        "parameters": torn.parameters or torn.reduced.parameters,
        "q0": np.asarray(torn.q0).tolist(),
        "p0": np.asarray(torn.p0).tolist(),
        "dt": torn.dt,
        "steps": torn.steps,
        "t_final": float(inter.t[-1]),
        "paper": {k: result.example.paper[k] for k in ("parameters", "q0", "p0", "dt", "steps")},
        "max_position_difference": {
            "interconnected_vs_monolithic": metrics.position_difference(inter, mono, same),
            "interconnected_vs_reduced": metrics.position_difference(inter, red, result.shared),
            "monolithic_vs_reduced": metrics.position_difference(mono, red, result.shared),
        },
        "max_energy_difference": {
            "interconnected_vs_monolithic": metrics.max_abs(inter.energy - mono.energy),
            "interconnected_vs_reduced": metrics.max_abs(inter.energy - red.energy),
        },
        "constraint_deviation": {
            "position": {name: metrics.max_abs(d) for name, d in ports.items()},
            "position_max": max((metrics.max_abs(d) for d in ports.values()), default=0.0),
            "discrete_interaction_max": metrics.max_abs(
                metrics.constraint_rows(inter, interaction)
            ),
            "discrete_all_max": metrics.max_abs(inter.constraint_residual),
        },
        "energy": {
            "interconnected": metrics.energy_stats(inter.energy),
            "monolithic": metrics.energy_stats(mono.energy),
            "reduced": metrics.energy_stats(red.energy),
        },
        "solver": {
            "interconnected": inter.solver,
            "monolithic": mono.solver,
            "reduced": red.solver,
        },
        "newton_iterations_mean": {
            "interconnected": float(inter.newton_iterations.mean()),
            "monolithic": float(mono.newton_iterations.mean()),
            "reduced": float(red.newton_iterations.mean()),
        },
        "discretizations": rules,
        "timing": {
            "protocol": TIMING_PROTOCOL,
            "repeats": settings.repeats,
            "reduced_s": timing["reduced"]["min_s"],
            "monolithic_s": timing["monolithic"]["min_s"],
            "interconnected_s": timing["interconnected"]["min_s"],
            "median_s": {k: v["median_s"] for k, v in timing.items()},
            "ratio_interconnected_to_reduced": (
                timing["interconnected"]["min_s"] / timing["reduced"]["min_s"]
            ),
            "ratio_interconnected_to_monolithic": (
                timing["interconnected"]["min_s"] / timing["monolithic"]["min_s"]
            ),
            "paper": {
                "repeats": pt["repeats"],
                "monolithic_s": pt["monolithic_s"],
                "interconnected_s": pt["interconnected_s"],
                "ratio": pt["interconnected_s"] / pt["monolithic_s"],
            },
        },
    }
    if result.long_run is not None:
        summary["long_run"] = {
            "steps": result.long_run.steps,
            "t_final": float(result.long_run.t[-1]),
            "energy": metrics.energy_stats(result.long_run.energy),
        }
    if result.sign:
        physical, printed = result.sign["physical"], result.sign["paper"]
        summary["resistor_sign"] = {
            "physical": metrics.energy_stats(physical.energy),
            "paper_printed": metrics.energy_stats(printed.energy),
            "physical_energy_nonincreasing": metrics.energy_stats(physical.energy)["nonincreasing"],
            "paper_printed_energy_growth": float(printed.energy[-1] / printed.energy[0]),
        }
    return summary
