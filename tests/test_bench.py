"""The benchmark suite: its NumPy baselines are independent implementations of the same
step equations (they agree with diracvi to 1e-12), its helpers, and ``diracvi bench``.

No timing is asserted anywhere: only that the numbers are produced and reported.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

import diracvi as dv
from diracvi import problems
from diracvi.bench import (
    BENCHMARKS,
    BenchmarkError,
    Settings,
    chain_scaling,
    rlc,
    spring_chain,
    work_precision,
)
from diracvi.bench._core import Row, Target, interleaved, relative_difference
from diracvi.bench._paper import AGREEMENT, check_agreement, in_order
from diracvi.bench._worker import WorkerFailed, run_child
from diracvi.bench.report import markdown
from diracvi.cli import EXIT_USAGE, app
from diracvi.reproduce.paper import RLC, SPRING_CHAIN


def paper_run(module, paper, problem):
    """diracvi's torn trajectory and the NumPy baseline's, from the paper's data."""
    coords = problem.system.coords
    q0 = in_order(paper["q0"], module.COORDS, coords)
    p0 = in_order(paper["p0"], module.MOMENTA, coords)
    traj = dv.simulate(problem.system, q0, p0, dt=paper["dt"], steps=paper["steps"])
    return traj, q0, p0


def test_numpy_spring_chain_is_the_same_discrete_system():
    paper = SPRING_CHAIN
    problem = problems.spring_chain_torn(dt=paper["dt"], steps=paper["steps"])
    traj, q0, p0 = paper_run(spring_chain, paper, problem)
    np.testing.assert_array_equal(q0, problem.q0)  # the problem is the paper's model
    baseline = spring_chain.numpy_torn_chain(
        paper["parameters"], q0, p0, paper["dt"], paper["steps"]
    )
    diffs = check_agreement(traj, *baseline, what="spring chain")
    assert max(diffs.values()) <= AGREEMENT
    # the port constraint q2 = q̄2 is kept by the baseline too
    q = baseline[0]
    assert np.max(np.abs(q[:, 1] - q[:, 2])) < 1e-12


def test_numpy_rlc_is_the_same_discrete_system():
    paper, prm = RLC, RLC["parameters"]
    problem = problems.rlc_torn(prm["R"], prm["l"], prm["C"], dt=paper["dt"], steps=paper["steps"])
    traj, q0, p0 = paper_run(rlc, paper, problem)
    baseline = rlc.numpy_torn_rlc(prm, q0, p0, paper["dt"], paper["steps"])
    diffs = check_agreement(traj, *baseline, what="RLC")
    assert max(diffs.values()) <= AGREEMENT


def test_agreement_check_catches_the_papers_printed_resistor_sign():
    """The printed (anti-dissipative) sign is a different discrete system: the check
    refuses to time it against diracvi."""
    paper, prm = RLC, RLC["parameters"]
    problem = problems.rlc_torn(dt=paper["dt"], steps=paper["steps"])
    traj, q0, p0 = paper_run(rlc, paper, problem)
    printed = rlc.numpy_torn_rlc({**prm, "R": -prm["R"]}, q0, p0, paper["dt"], paper["steps"])
    with pytest.raises(BenchmarkError, match="disagree"):
        check_agreement(traj, *printed, what="RLC")


def test_interleaved_times_every_call_alternately():
    order = []
    calls = {name: (lambda name=name: order.append(name)) for name in "abc"}
    times = interleaved(calls, repeats=4)
    assert {k: v.shape for k, v in times.items()} == {k: (4,) for k in "abc"}
    assert np.all(np.concatenate(list(times.values())) >= 0)
    assert order[:3] == ["a", "b", "c"]  # the untimed warm-up calls
    firsts = order[3::3]
    assert firsts == ["a", "b", "c", "a"]  # the starting side rotates


def test_interleaved_reads_the_clock_it_is_given():
    """Each timed call is the difference of two readings of ``clock`` around it (a clock
    that advances by 1 per reading and 10 per call: every time is 11)."""
    ticks = [0.0]

    def clock():
        ticks[0] += 1.0
        return ticks[0]

    def call():
        ticks[0] += 10.0

    times = interleaved({"a": call, "b": call}, repeats=3, clock=clock)
    assert all(np.array_equal(v, [11.0, 11.0, 11.0]) for v in times.values())


def test_targets_and_rows():
    assert Target(">=", 100).met(120.0) and not Target(">=", 100).met(99.0)
    assert Target("<=", 1.05).met(1.0) and Target("in", 0.9, 1.1).met(1.02)
    assert Target("<=", 1.05).met(None) is None
    assert Row("x", "y", None, None, None, Target("<=", 5), status="not run").met is False
    assert Row("x", "y", 1.0, 2.0, 2.0).met is None
    assert relative_difference([1.0, 2.0], [1.0, 2.0]) == 0.0


def test_factor_values_count_what_the_run_stepped_with():
    chain = problems.chain_torn(20, 2)  # linear: the affine step map
    traj = dv.simulate(chain.system, chain.q0, chain.p0, dt=chain.dt, steps=10)
    assert traj.solver.startswith("affine")
    two_n = 2 * chain.system.n
    assert chain_scaling.factor_values(chain) >= two_n * two_n  # at least the one-step map
    pendulum = problems.double_pendulum_torn()  # nonlinear: Newton's LU factors
    dv.simulate(pendulum.system, pendulum.q0, pendulum.p0, dt=pendulum.dt, steps=10)
    size = pendulum.system.n + pendulum.system.m
    # Newton carries its LU factors and |J| (each equation's scale for the round-off test)
    assert chain_scaling.factor_values(pendulum) == 2 * size * size
    kernel = chain_scaling.stream_kernel(16, steps=3)
    assert np.all(np.isfinite(np.asarray(kernel())))


def test_child_processes_report_json_or_fail_cleanly():
    printed = 'print("noise"); print(\'{"a": 1}\')'
    assert run_child(["-c", printed], timeout=30)["a"] == 1
    with pytest.raises(WorkerFailed, match="longer than"):
        run_child(["-c", "import time; time.sleep(30)"], timeout=0.5)
    with pytest.raises(WorkerFailed, match="exit code 3"):
        run_child(["-c", "import sys; sys.exit(3)"], timeout=30)
    with pytest.raises(WorkerFailed, match="memory"):
        run_child(
            ["-c", "import time; x = b'x' * 200_000_000; time.sleep(30)"],
            timeout=30,
            max_rss_bytes=50_000_000,
        )


def test_bench_help_names_every_benchmark():
    """``--only``'s help lists the names literally (the CLI does not import the
    benchmarks to start): every benchmark there is must be named, in the table's order."""
    import re

    from diracvi.bench import BENCHMARKS

    result = CliRunner().invoke(app, ["bench", "--help"], terminal_width=400)
    text = " ".join(re.sub("[│╭╮╰╯─]", " ", result.output).split())  # rich's box drawn
    listed = re.search(r"repeatable\):(.*?)\.\s", text).group(1)
    assert [name.strip() for name in listed.split(",")] == list(BENCHMARKS)


def test_bench_rejects_an_unknown_benchmark():
    result = CliRunner().invoke(app, ["bench", "--only", "nope"])
    assert result.exit_code == EXIT_USAGE
    assert "no such benchmark" in result.output


# 19 s, in `-m slow` (CI time): CI's docs tests run the README's `diracvi bench --quick
# --only rlc`; the table's parts are checked by default (test_targets_and_rows, the
# 80-column test below)
@pytest.mark.slow
def test_bench_quick_prints_one_table_and_writes_json(tmp_path):
    out = tmp_path / "bench.json"
    only = [
        arg for name in ("spring-chain", "rlc", "pendulum", "ensemble") for arg in ("--only", name)
    ]
    result = CliRunner().invoke(
        app, ["bench", "--quick", *only, "--json", str(out)], env={"COLUMNS": "240"}
    )
    assert result.exit_code == 0, result.output
    for header in ("benchmark", "diracvi", "baseline", "ratio", "target", "met?", "solver"):
        assert header in result.output
    assert "machine:" in result.output and "jax" in result.output
    data = json.loads(out.read_text())
    assert data["settings"]["quick"] is True
    assert {row["benchmark"] for row in data["rows"]} == {
        "spring-chain",
        "rlc",
        "pendulum",
        "ensemble",
    }
    assert all(row["status"] == "measured" for row in data["rows"])
    assert set(BENCHMARKS) >= set(data["durations_s"])
    assert Settings(quick=True).paper_repeats == data["settings"]["paper_repeats"]
    table = markdown(data)
    assert table.startswith("| benchmark | diracvi | baseline | ratio |")
    assert len(table.splitlines()) == len(data["rows"]) + 4


def test_table_on_an_80_column_console_breaks_no_word():
    from rich.console import Console

    from diracvi.bench.report import Report, table

    label = "spring chain: torn ÷ hand-built reduced (the paper's 'monolithic')"
    notes = "agree to 9.0e-13; min of 10; diracvi call ≈ 606 µs fixed + 106 ns/step"
    row = Row("spring-chain", label, 1e-3, 2e-3, 0.5, solver="affine step map", notes=notes)
    report = Report(settings=Settings(quick=True), machine={}, rows=[row])
    console = Console(width=80, record=True, highlight=False)
    console.print(table(report, width=80))
    text = console.export_text()
    assert max(len(line) for line in text.splitlines()) <= 80
    lines = text.splitlines()
    for word in (label + " " + notes).split():  # every word whole on some line
        assert any(word in line for line in lines), word


@pytest.mark.parametrize("name", list(work_precision.CASES))
def test_work_precision_reference_starts_where_the_model_does(name):
    """Each work–precision case's reduced ODE (hand-written NumPy, no diracvi) starts at
    the model's state: ``to_q(y₀) = q₀``, and the reduced velocity at t = 0 (a centred
    difference of a DOP853 run) has the model's momentum ``∂L/∂v(q₀, v₀) = p₀``."""
    from scipy.integrate import solve_ivp

    case = work_precision.CASES[name]()
    np.testing.assert_allclose(case.to_q(case.y0), case.q0, rtol=0, atol=1e-12)
    eps = 1e-5

    def q_at(t):
        sol = solve_ivp(case.rhs, (0.0, t), case.y0, method="DOP853", rtol=1e-13, atol=1e-13)
        return case.to_q(sol.y[:, -1])

    velocity = (q_at(eps) - q_at(-eps)) / (2 * eps)
    momentum = dv.momenta(case.system, case.q0, velocity)
    np.testing.assert_allclose(
        momentum, case.p0, rtol=0, atol=1e-7 * max(1.0, np.abs(case.p0).max())
    )


# ~5 s of CPU (the jit of the right-hand side, 2000 DOP853 steps): in `-m slow`
@pytest.mark.slow
def test_first_call_scipy_route_reaches_the_published_andrews_solution():
    """The ``first-call`` baseline (jit index-1 ODE by autodiff of the model's L, F, g,
    DOP853 at 1e-10) is Andrews' mechanism: at t = 0.03 it has the test set's angles."""
    from diracvi.bench.first_call import scipy_route
    from diracvi.problems.andrews import REFERENCE_Q, REFERENCE_T

    q = scipy_route(problems.get("andrews"), REFERENCE_T)
    np.testing.assert_allclose(q, REFERENCE_Q, rtol=0, atol=1e-7)  # measured 1.7e-9


# each case compiles a lobatto run (4–30 s of CPU)
@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "tol"),  # measured 7.0e-7, 1.1e-7, 8.3e-7
    [("four-bar", 2e-6), ("double-pendulum-torn", 1e-6), ("andrews", 2e-6)],
)
def test_first_call_scipy_route_agrees_with_diracvi_at_the_horizon(name, tol):
    """diracvi's lobatto run (order 4) and the scipy route end at the same angles (the
    torn pendulum's through its shared coordinates), within lobatto's own error."""
    from diracvi.bench.first_call import reduced_model, scipy_route

    problem = problems.get(name)
    traj = dv.simulate(
        problem.system, problem.q0, problem.p0, dt=problem.dt, steps=problem.steps,
        discretization="lobatto",
    )  # fmt: skip
    pick = reduced_model(problem)[3]
    q = scipy_route(problem, problem.t0 + problem.dt * problem.steps)
    np.testing.assert_allclose(np.asarray(traj.q[-1])[pick], q, rtol=0, atol=tol)


def test_matched_accuracy_front_and_interpolation():
    """ngspice's time at diracvi's error (``bench.circuits``): the front keeps only the
    runs no other beats in both error and time, and on it the interpolation is log-log,
    so a power law ``s = c·e^(−1/2)`` (trapezoidal at a maximum step) is read back
    exactly between its points; past the front's most accurate run there is no answer."""
    from diracvi.bench.circuits import front, seconds_at

    law = [(e, 0.1 * e**-0.5) for e in (1e-3, 1e-4, 1e-5)]
    dominated = [(5e-4, 20.0), (2e-5, 100.0)]  # costlier than a more accurate run
    points = law + dominated
    assert front(points) == sorted(law)
    for err in (3e-4, 5e-5, 1.7e-5):
        assert seconds_at(points, err) == pytest.approx(0.1 * err**-0.5, rel=1e-12)
    assert seconds_at(points, 1e-5) == pytest.approx(0.1 * 1e-5**-0.5, rel=1e-12)
    assert seconds_at(points, 1e-2) == law[0][1]  # reached by the cheapest: its time
    assert seconds_at(points, 9e-6) is None
