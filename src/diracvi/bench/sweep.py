r"""A parameter sweep of 10⁴ RLC circuits: a Python loop of ``simulate`` against
``dv.sweep`` embedded and ``dv.sweep`` on a 2-worker Dask ``LocalCluster``.

Problem: the paper's RLC circuit (§5.2, monolithic, h = 0.1, 400 steps) built by
``problems.build_rlc`` (an ``equinox.Module`` Lagrangian and resistor, so every member
shares one compiled program), over a grid of R × C: 100 × 100 values in batches of 500
(8 × 8 in batches of 16 with ``--quick``).

- *loop*: ``dv.simulate(*build_rlc(R=R, C=C), dt, steps)`` for the first ``LOOP_RUNS``
  members — what a user without ``sweep`` writes. Every member is a new system, so
  every call analyses and compiles its own plan; timed and extrapolated linearly to the
  whole grid.
- *embedded*: ``dv.sweep(build_rlc, grid, ...)`` in this process.
- *cluster*: the same with ``client=`` a ``LocalCluster(n_workers=2,
  threads_per_worker=1, processes=True)`` (started before timing; not timed).

Each sweep side is timed once after a warm-up sweep of two batches (which compiles the
batch program, on each worker for the cluster). Before timing, the sweep's members must
equal the loop's single runs to 1e-11 relative (both take the affine step map: the loop
one ``simulate`` plan per circuit, the sweep every member's map built in one call per
batch) and the cluster's sweep must equal the embedded one bitwise.
"""

from __future__ import annotations

import time

import numpy as np

import diracvi as dv

from .. import problems
from ._core import BenchmarkError, Result, Row, Settings, relative_difference

NAME = "sweep"
DESCRIPTION = "10⁴ RLC circuits: Python loop of simulate vs dv.sweep embedded and on Dask"

SIDE = {False: 100, True: 8}  # grid values per parameter
BATCH = {False: 500, True: 16}  # members per batch: 20 (4) batches, both workers busy
LOOP_RUNS = {False: 5, True: 2}
DT, STEPS = 0.1, 400
AGREEMENT = 1e-11


def grid(side: int) -> dict:
    return {"R": np.linspace(0.2, 2.0, side), "C": np.linspace(1.0, 5.0, side)}


def _timed(call):
    start = time.perf_counter()
    out = call()
    return time.perf_counter() - start, out


def run(settings: Settings) -> Result:
    side, loop_runs = SIDE[settings.quick], LOOP_RUNS[settings.quick]
    params = grid(side)
    members = side * side
    batch = BATCH[settings.quick]
    kwargs = {"dt": DT, "steps": STEPS, "progress": False, "batch_size": batch}
    points = [(r, c) for r in params["R"] for c in params["C"]][:loop_runs]

    def loop():
        return [dv.simulate(*problems.build_rlc(R=r, C=c), dt=DT, steps=STEPS) for r, c in points]

    try:
        from distributed import Client, LocalCluster
    except ImportError:  # the embedded side still runs; the cluster row says why not
        Client = LocalCluster = None

    # the warm-up: two batches of the same size (the same compiled program), on a table
    rng = np.random.default_rng(1)
    warm = {"R": rng.uniform(0.2, 2.0, 2 * batch), "C": rng.uniform(1.0, 5.0, 2 * batch)}
    dv.sweep(problems.build_rlc, samples=warm, **kwargs)
    t_loop, singles = _timed(loop)
    t_embedded, embedded = _timed(lambda: dv.sweep(problems.build_rlc, params, **kwargs))
    flat = embedded.stack(member=("R", "C")).transpose("member", ...)
    diff = max(
        max(
            relative_difference(flat["qC"].values[i], singles[i]["qC"]),
            relative_difference(flat["energy"].values[i], singles[i].energy),
        )
        for i in range(loop_runs)
    )
    if diff > AGREEMENT:
        raise BenchmarkError(
            f"the sweep's members differ from single simulate runs by {diff:.2e} (relative) "
            f"> {AGREEMENT:g}: the two would not be computing the same thing."
        )
    if not bool((embedded.status == 0).all()):
        raise BenchmarkError("some members of the sweep failed.")

    if LocalCluster is None:
        return _without_cluster(label_of(members), t_loop, loop_runs, members, t_embedded, diff)
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
    ):
        dv.sweep(problems.build_rlc, samples=warm, client=client, **kwargs)
        t_cluster, remote = _timed(
            lambda: dv.sweep(problems.build_rlc, params, client=client, **kwargs)
        )
    identical = all(
        np.array_equal(
            embedded[v].values, remote[v].values, equal_nan=embedded[v].dtype.kind == "f"
        )
        for v in embedded.data_vars
    )
    if not identical:
        raise BenchmarkError("the cluster's sweep differs from the embedded one.")

    per_loop = t_loop / loop_runs
    t_loop_all = per_loop * members
    rate = {
        "loop": loop_runs / t_loop,
        "embedded": members / t_embedded,
        "cluster": members / t_cluster,
    }
    label = label_of(members)
    ran = ", ".join(sorted(set(np.asarray(embedded.solver.values).ravel().astype(str))))
    note = (
        f"members/s: loop {rate['loop']:.3g} (timed over {loop_runs}, extrapolated), "
        f"embedded {rate['embedded']:.3g}, cluster {rate['cluster']:.3g}; "
        f"agree to {diff:.1e}; cluster = embedded bitwise"
    )
    rows = [
        Row(
            NAME,
            f"{label}: Python loop of simulate ÷ dv.sweep embedded",
            t_embedded,
            t_loop_all,
            t_loop_all / t_embedded,
            solver=f"sweep: {ran}, vmapped; loop: {singles[0].solver}",
            notes=note,
        ),
        Row(
            NAME,
            f"{label}: Python loop of simulate ÷ dv.sweep on a 2-worker LocalCluster",
            t_cluster,
            t_loop_all,
            t_loop_all / t_cluster,
            solver=f"sweep: {ran}, vmapped, Dask tasks",
            notes="one timed call after a warm-up sweep; cluster startup not timed",
        ),
    ]
    details = {
        "members": members,
        "steps": STEPS,
        "loop_runs_timed": loop_runs,
        "seconds": {"loop_extrapolated": t_loop_all, "embedded": t_embedded, "cluster": t_cluster},
        "members_per_second": rate,
        "agreement_relative": diff,
        "cluster_equals_embedded_bitwise": identical,
    }
    return Result(rows, details)


def label_of(members: int) -> str:
    return f"{members:,} RLC circuits × {STEPS} steps (R × C grid)"


def _without_cluster(label, t_loop, loop_runs, members, t_embedded, diff) -> Result:
    """The rows when Dask is not installed: the embedded sweep, and a cluster row not run."""
    t_loop_all = t_loop / loop_runs * members
    rows = [
        Row(
            NAME,
            f"{label}: Python loop of simulate ÷ dv.sweep embedded",
            t_embedded,
            t_loop_all,
            t_loop_all / t_embedded,
            notes=f"members/s: loop {loop_runs / t_loop:.3g}, embedded "
            f"{members / t_embedded:.3g}; agree to {diff:.1e}",
        ),
        Row(
            NAME,
            f"{label}: dv.sweep on a 2-worker LocalCluster",
            None,
            None,
            None,
            notes="Dask is not installed: pip install 'diracvi[distributed]'",
            status="not run",
        ),
    ]
    return Result(rows, {"members": members, "cluster": "not run (no dask.distributed)"})
