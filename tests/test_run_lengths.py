"""One compiled march per model and octave of run lengths.

The number of saved records is a runtime value of the march's program
(``driver/chunk.py``: ``capacity``, ``SizedChunk``): a second ``simulate`` of the same
model with another step count traces and compiles nothing, and the steps it takes are
bitwise those of a program compiled for exactly its length.

White-box: reads internals of ``diracvi.driver``."""

import jax
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.discretization.rules import get_rule
from diracvi.driver.chunk import CompiledChunk, capacity
from diracvi.driver.plan import get_plan


class _Traced(list):
    """The JAX trace and XLA compile events of the calls made inside the block."""

    def listen(self, event, *_, fun_name="", **__):
        if event.endswith(("jaxpr_trace_duration", "backend_compile_duration")):
            self.append((event, fun_name))

    def __enter__(self):
        jax.monitoring.register_event_duration_secs_listener(self.listen)
        return self

    def __exit__(self, *_):
        jax.monitoring.unregister_event_duration_listener(self.listen)


def test_the_capacity_ladder_holds_every_run_with_little_filler():
    caps = set()
    for blocks in range(1, 20000):
        cap = capacity(blocks)
        caps.add(cap)
        assert cap >= blocks and cap % 16 == 0
        assert cap - blocks < max(16, blocks / 8)  # the filler rows of a run
    assert len(caps) < 200  # a model compiles few programs for 20000 lengths


# the pendulum is stepped by Newton (its own choice), the driven RLC by Newton when
# asked (its time-dependent force through the runtime clock)
@pytest.mark.parametrize(
    ("name", "lengths", "save_every", "solver"),
    [
        ("cartesian-pendulum", (20, 27), 1, None),
        pytest.param("cartesian-pendulum", (30, 45), 3, None, marks=pytest.mark.slow),
        pytest.param("rlc-sine", (70, 75), 1, dv.NewtonSolver(), marks=pytest.mark.slow),
    ],
)
def test_a_new_step_count_compiles_no_new_march(name, lengths, save_every, solver):
    problem = problems.get(name)

    def run(steps):
        return dv.simulate(
            problem.system, problem.q0, problem.p0, dt=problem.dt, steps=steps,
            save_every=save_every, discretization="midpoint", solver=solver,
        )  # fmt: skip

    first = run(lengths[0])
    with _Traced() as traced:
        second = run(lengths[1])
    assert traced == []
    assert "newton" in second.solver.lower() and "newton" in first.solver.lower()
    assert second.steps == lengths[1] and len(second.energy) == lengths[1] // save_every

    # the same steps as the program of exactly this length (today's static scan)
    plan = get_plan(problem.system, get_rule("midpoint"), "plus", problem.dt, solver,
                    problem.q0, problem.p0)  # fmt: skip
    static = CompiledChunk(
        plan.stepped_system, plan.rule, "plus", plan.fallback, save_every, True,
        lengths[1] // save_every, guard=None,
    )  # fmt: skip
    zeros = np.zeros(plan.system.m)
    carry, _, saved = static(plan.h_array, np.zeros(2), (problem.q0, problem.p0, problem.q0, zeros))
    np.testing.assert_array_equal(second.q[1:], saved["q"])
    np.testing.assert_array_equal(second.p[1:], saved["p"])
    # the energy is evaluated from those bitwise-equal states, but inside another
    # program: XLA may contract its products into FMAs differently there (1 ulp seen)
    np.testing.assert_allclose(second.energy, saved["energy"], rtol=4 * np.finfo(float).eps)
    np.testing.assert_array_equal(second.multipliers, saved["mu"])
    for ours, theirs in zip(second.final_state, carry, strict=True):
        np.testing.assert_array_equal(ours, theirs)


def test_a_run_that_fails_inside_a_counted_chunk_reports_its_step():
    """A step past the run's end is never a failure, a step inside it is: a run whose
    Newton iterations are too few fails at its first step, not later or never."""
    problem = problems.get("cartesian-pendulum")
    traj = dv.simulate(
        problem.system, problem.q0, problem.p0, dt=problem.dt, steps=5,
        solver=dv.NewtonSolver(max_steps=1), throw=False,
    )  # fmt: skip
    assert traj.status != 0 and traj.steps == 0


def test_a_linear_models_affine_run_keeps_a_program_per_length():
    """The affine map's runs are not counted (their blocks' width follows the length):
    the plan hands out a chunk of exactly the run's records."""
    problem = problems.get("rlc")
    traj = dv.simulate(problem.system, problem.q0, problem.p0, dt=problem.dt, steps=40)
    assert traj.solver == "affine step map"
    plan = get_plan(problem.system, get_rule("retraction"), "plus", problem.dt, None,
                    problem.q0, problem.p0)  # fmt: skip
    chunk = plan.chunk(True, 1, True, 40)
    assert isinstance(chunk, CompiledChunk) and chunk.layout.blocks == 40
