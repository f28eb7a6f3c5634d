"""A staged ("lobatto") run that keeps its stages lies in the induced Dirac structure at
every stage node, and its steps satisfy the discrete step relation, to round-off
(``diracvi.dirac._stagewise``); a changed stage, stage multiplier or momentum is caught.

Models: the Chaplygin sleigh (nonholonomic, configuration-dependent one-form; reference
Bloch 2003 §1.7, checked here against the closed form of its speed and heading) and the
paper's RLC circuit torn in two (degenerate Lagrangian, interaction rows). Bound as in
``test_dirac_trajectory.py``: ``1e-10 · max(1, max |p|)``.
"""

from __future__ import annotations

import copy

import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.dirac import step_residuals

BOUND = 1e-10
STEPS = 40

_RUNS: dict = {}
_PROBLEMS: dict = {}


def _run(name, scheme, keep_stages=True):
    """``(system, traj)``: one system object per problem, so the diagnostic compiles once."""
    prob = _PROBLEMS.setdefault(name, problems.get(name))
    key = (name, scheme, keep_stages)
    if key not in _RUNS:
        _RUNS[key] = dv.simulate(
            prob.system,
            prob.q0,
            prob.p0,
            dt=0.05,
            steps=STEPS,
            scheme=scheme,
            discretization="lobatto",
            keep_stages=keep_stages,
        )
    return prob.system, _RUNS[key]


def _scale(traj):
    return max(1.0, float(np.max(np.abs(traj.p))))


# a lobatto plan costs 10–30 s of compilation here: the sleigh forward by default, the
# torn RLC backward (its affine step map, interaction rows) and the bitwise comparison
# (a second program) with -m slow
CASES = [
    ("chaplygin-sleigh", "plus"),
    pytest.param("rlc-torn", "minus", marks=pytest.mark.slow),
]


@pytest.mark.parametrize(("name", "scheme"), CASES)
def test_kept_stages_lie_in_the_dirac_structure_at_every_node(name, scheme):
    system, traj = _run(name, scheme)
    n, m = system.n, system.m
    assert traj.stages.shape == (STEPS, n, 2)
    assert traj.stage_multipliers.shape == (STEPS, m, 2)
    parts = step_residuals(system, traj)
    # the stage-by-stage pieces: rows at the three nodes, the step relation, three nodes
    assert parts.constraint.shape == (STEPS, 3 * m)
    assert parts.fiber.shape == (STEPS, 3 * n)
    assert np.max(parts.total) <= BOUND * _scale(traj)
    np.testing.assert_array_equal(parts.multipliers, traj.multipliers)
    np.testing.assert_array_equal(traj.dirac_residual(system), parts.total)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "scheme"), [("chaplygin-sleigh", "plus"), ("rlc-torn", "minus")])
def test_keeping_the_stages_changes_nothing_else(name, scheme):
    """``keep_stages`` only adds outputs: the run is bitwise the one without it."""
    _, kept = _run(name, scheme)
    _, plain = _run(name, scheme, keep_stages=False)
    assert plain.stages is None and plain.stage_multipliers is None
    for field in ("q", "p", "multipliers", "energy", "constraint_residual"):
        np.testing.assert_array_equal(getattr(kept, field), getattr(plain, field))


def _with_record(traj, change):
    bad = copy.copy(traj)
    record = traj._stage_record.copy()  # rows [Q.ravel() ν.ravel()] (stepping.stage_record)
    change(record)
    bad._stage_record = record
    return bad


@pytest.mark.parametrize(("name", "scheme"), CASES)
def test_a_changed_stage_multiplier_or_momentum_is_caught_at_its_step(name, scheme):
    system, traj = _run(name, scheme)
    n, j = system.n, 17
    floor = BOUND * _scale(traj)

    def stage(record):  # Q₂'s first coordinate (column 1 of the (n, 2) stage block)
        record[j, 1] += 1e-6

    def multiplier(record):  # ν of the first row at the second stage column
        record[j, 2 * n + 1] += 1e-6

    for change in (stage, multiplier):
        res = step_residuals(system, _with_record(traj, change)).total
        assert res[j] > 1e-8 and np.max(np.delete(res, j)) <= floor, change.__name__
    bad = copy.copy(traj)
    bad.p = traj.p.copy()
    bad.p[j, 0] += 1e-6  # a stored momentum: used by the two steps that meet at it
    res = step_residuals(system, bad).total
    assert res[j - 1] > 1e-8 and res[j] > 1e-8
    assert np.max(np.delete(res, [j - 1, j])) <= floor


def test_the_sleigh_runs_to_its_closed_form():
    """The sleigh model is the published one: at dt = 0.05 the order-4 run meets the
    closed-form speed, turning rate and heading (the contact point by DOP853) to 1e-6."""
    _, traj = _run("chaplygin-sleigh", "plus")
    prob = _PROBLEMS["chaplygin-sleigh"]
    assert np.max(np.abs(traj.q - prob.numerical_solution(traj.t))) < 1e-6
    u_omega = prob.parameters["speed_and_turn"](traj.t)
    theta, vel = traj.q[:, 2], np.gradient(traj.q, traj.t, axis=0, edge_order=2)
    speed = np.cos(theta) * vel[:, 0] + np.sin(theta) * vel[:, 1]
    # a difference quotient of the positions: its own O(dt²) error
    assert np.max(np.abs(speed - u_omega[:, 0])) < 1e-3
    assert np.max(np.abs(vel[:, 2] - u_omega[:, 1])) < 1e-3


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"discretization": "midpoint"}, "has no internal stages"),
        ({"save_every": 2}, "save_every=2"),
        ({"save_states": False}, "save_states=False"),
    ],
)
def test_keep_stages_refuses_what_it_cannot_keep(options, match):
    prob = problems.get("chaplygin-sleigh")
    kwargs = {"dt": 0.05, "steps": 4, "discretization": "lobatto", "keep_stages": True}
    with pytest.raises(dv.ModelError, match=match):
        dv.simulate(prob.system, prob.q0, prob.p0, **{**kwargs, **options})
