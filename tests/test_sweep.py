"""``dv.sweep``: members equal single runs, one compilation per structure, Dask equals
embedded bitwise (also after a worker dies), and ``out=`` resumes after an interruption.

White-box: reads internals of ``diracvi.sweeps``."""

from __future__ import annotations

import functools
import os
import signal
import sys
import textwrap

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.sweeps import batch as _sweep

DT, STEPS = 0.1, 60
BATCH = 4  # one batch shape in every test: the compiled programs are shared
GRID = {"R": [0.5, 1.0, 2.0], "C": [1.0, 3.0]}


def same(a, b) -> bool:
    """Bitwise equal data (NaN equal to NaN), variable by variable."""
    assert set(a.data_vars) == set(b.data_vars)
    return all(
        np.array_equal(a[v].values, b[v].values, equal_nan=a[v].dtype.kind == "f")
        for v in a.data_vars
    )


def single(R, C):
    system, q0, p0 = problems.build_rlc(R=R, C=C)
    return dv.simulate(system, q0, p0, dt=DT, steps=STEPS, solver=dv.NewtonSolver())


@pytest.fixture(scope="module")
def grid_sweep():
    """The RLC over GRID, embedded (shared: compiling is most of a small sweep's time)."""
    return dv.sweep(problems.build_rlc, GRID, dt=DT, steps=STEPS, batch_size=BATCH)


def test_members_equal_single_runs(grid_sweep):
    ds = grid_sweep
    assert ds["qC"].dims == ("R", "C", "time") and ds["energy"].dims == ("R", "C", "step")
    assert (ds.status.values == 0).all() and (ds.message.values == "success").all()
    for R, C in [(2.0, 1.0)]:  # a corner (each single run compiles anew)
        traj, member = single(R, C), ds.sel(R=R, C=C)
        q = np.stack([member[c].values for c in traj.coords], axis=1)
        p = np.stack([member[f"p({c})"].values for c in traj.coords], axis=1)
        scale = np.max(np.abs(traj.q)) + np.max(np.abs(traj.p))
        assert np.max(np.abs(q - traj.q)) <= 1e-12 * scale
        assert np.max(np.abs(p - traj.p)) <= 1e-12 * scale
        assert np.allclose(member.energy.values, traj.energy, rtol=1e-12, atol=0)
        assert np.max(member.constraint_violation.values) <= 1e-12
    np.testing.assert_array_equal(ds.time.values, traj.t)


def test_samples_table_and_saving_every_kth_state(grid_sweep):
    samples = {"R": [2.0, 0.5, 1.0, 2.0], "C": [3.0, 1.0, 3.0, 1.0]}  # GRID points, reordered
    ds = dv.sweep(problems.build_rlc, samples=samples, dt=DT, steps=STEPS, batch_size=BATCH)
    assert ds["qL"].dims == ("sample", "time")
    np.testing.assert_array_equal(ds.R.values, samples["R"])
    for i, (R, C) in enumerate(zip(samples["R"], samples["C"], strict=True)):
        member = grid_sweep.sel(R=R, C=C)
        np.testing.assert_allclose(ds["qL"].values[i], member["qL"].values, rtol=1e-12, atol=1e-12)
    thin = dv.sweep(problems.build_rlc, GRID, dt=DT, steps=STEPS, save_every=10, batch_size=BATCH)
    assert thin.sizes["time"] == STEPS // 10 + 1
    np.testing.assert_allclose(
        thin["qC"].values, grid_sweep["qC"].values[..., ::10], rtol=1e-12, atol=1e-12
    )


def test_a_grid_compiles_once():
    _sweep._PROGRAMS.clear()
    before = _sweep.TRACE_COUNT
    grid = {"R": np.linspace(0.5, 2.0, 5), "C": np.linspace(1.0, 4.0, 3)}
    ds = dv.sweep(problems.build_rlc, grid, dt=DT, steps=STEPS, batch_size=4)  # 4 batches
    # one program for the 4 batches: traced once, or loaded untraced from the program
    # store if another test (or process) of this run compiled it first
    (chunk,) = [fn for key, fn in _sweep._PROGRAMS.items() if key[0] == "chunk"]
    traced = _sweep.TRACE_COUNT - before
    assert traced <= 1 and len(chunk._programs) <= 1
    assert traced == 1 or len(chunk._programs) == 1  # compiled here, or loaded
    assert (ds.status == 0).all()


def closure_build(R):
    """Parameters captured by a plain function: a new structure for every member."""
    system, q0, p0 = problems.build_rlc(R=R)

    def lagrangian(q, v):
        return 0.5 * 0.75 * v[1] ** 2 - q[2] ** 2 / 6.0

    def force(q, v):
        return np.array([-R, 0.0, 0.0]) * v

    system = dv.LagrangeDiracSystem(
        system.coords, lagrangian, constraints=np.array([[1.0, -1.0, -1.0]]), force=force
    )
    return system, q0, p0


@pytest.mark.slow  # two structures: six compilations
def test_members_that_do_not_group_still_run():
    kwargs = {"dt": DT, "steps": STEPS, "batch_size": BATCH}
    ds = dv.sweep(closure_build, {"R": [0.5, 1.5]}, **kwargs)
    module = dv.sweep(problems.build_rlc, {"R": [0.5, 1.5]}, **kwargs)
    np.testing.assert_allclose(ds["qC"].values, module["qC"].values, rtol=1e-12, atol=1e-13)


def test_a_singular_member_fails_alone():
    """R = 0 leaves the resistor's and the capacitor's momentum rows dependent (the
    left-point rule): that member reports it; the others run."""
    ds = dv.sweep(problems.build_rlc, {"R": [0.0, 1.0]}, dt=DT, steps=STEPS, batch_size=BATCH)
    assert ds.status.values.tolist() == [2, 0]
    assert "not solvable" in str(ds.message.values[0]) and "R=0" in str(ds.message.values[0])
    assert np.isnan(ds["qC"].values[0, 1:]).all() and ds.steps_taken.values.tolist() == [0, STEPS]


def kicked_build(R, C):
    """build_rlc with a resistor momentum the degenerate Lagrangian does not allow."""
    system, q0, p0 = problems.build_rlc(R=R, C=C)
    return system, q0, p0 + np.array([1.0, 0.0, 0.0]) * (R > 1.5)


def test_inconsistent_initial_data_warn_once_for_the_sweep():
    grid = {"R": [1.0, 2.0], "C": [1.0, 3.0]}
    with pytest.warns(dv.InconsistentInitialDataWarning, match=r"2 member\(s\).*R=2, C=1"):
        dv.sweep(kicked_build, grid, dt=DT, steps=STEPS, batch_size=BATCH)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"params": {"X": [1.0]}}, ["'X'", "build"]),
        ({"params": {"R": []}}, ["params['R']", "empty"]),
        ({"params": {"R": [[1.0, 2.0]]}}, ["params['R']", "1-D"]),
        ({"samples": {"R": [1.0, 2.0], "C": [1.0]}}, ["samples", "lengths"]),
        ({"params": {"R": [1.0]}, "samples": {"C": [1.0]}}, ["params=", "samples="]),
        ({}, ["params=", "samples="]),
        ({"params": {"time": [1.0]}}, ["'time'", "reserved"]),
        ({"params": {"R": [1.0]}, "batch_size": 0}, ["batch_size"]),
    ],
)
def test_bad_input_names_the_argument(kwargs, words):
    with pytest.raises(dv.ModelError) as info:
        dv.sweep(problems.build_rlc, dt=DT, steps=10, **kwargs)
    for word in words:
        assert word in str(info.value)


def test_a_build_that_raises_is_named():
    def build(R):
        raise ValueError("no such part")

    with pytest.raises(dv.ModelError, match=r"build\(R=2\) raised ValueError: no such part"):
        dv.sweep(build, {"R": [2.0]}, dt=DT, steps=10)


# ------------------------------------------------------------------ out=
_CALLS = {"count": 0, "stop_after": None}


def counted_build(R, C):
    """build_rlc that counts its calls and can be stopped (a simulated interruption)."""
    _CALLS["count"] += 1
    if _CALLS["stop_after"] is not None and _CALLS["count"] > _CALLS["stop_after"]:
        raise KeyboardInterrupt
    return problems.build_rlc(R=R, C=C)


def test_out_of_core_sweep_resumes_after_an_interruption(tmp_path):
    grid = {"R": np.linspace(0.5, 2.0, 5), "C": [1.0, 2.0, 3.0]}  # 15 members
    kwargs = {"dt": DT, "steps": STEPS, "batch_size": BATCH}  # 4 batches
    whole = dv.sweep(counted_build, grid, **kwargs)
    path = tmp_path / "sweep.nc"
    _CALLS.update(count=0, stop_after=9)  # dies in the third batch, two are on disk
    with pytest.raises(KeyboardInterrupt):
        dv.sweep(counted_build, grid, out=path, **kwargs)
    _CALLS.update(count=0, stop_after=None)
    with dv.sweep(counted_build, grid, out=path, **kwargs) as resumed:
        assert _CALLS["count"] == 15 - 8  # the finished batches were skipped
        assert same(resumed.load(), whole)
    with dv.sweep(counted_build, grid, out=path, **kwargs) as again:  # all done: no work
        assert _CALLS["count"] == 7 and same(again.load(), whole)
    with pytest.raises(dv.ModelError, match="different sweep"):
        dv.sweep(counted_build, grid, out=path, **{**kwargs, "steps": 2 * STEPS})


# ------------------------------------------------------------------ Dask
@pytest.fixture(scope="module")
def client():
    """A 2-worker cluster of processes (skipped without the [distributed] extra)."""
    distributed = pytest.importorskip("distributed")
    import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # workers rebuild builds
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


def first_call(marker) -> bool:
    """True exactly once over all processes: the call that creates ``marker``."""
    try:
        os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
    except FileExistsError:
        return False
    return True


def fails_once(R, C, marker):
    """A build whose first call on any worker raises (a transient failure)."""
    if first_call(marker):
        raise OSError("transient")
    return problems.build_rlc(R=R, C=C)


def kills_once(R, C, marker):
    """A build that kills its worker process the first time it runs (a lost machine)."""
    if first_call(marker):
        os.kill(os.getpid(), signal.SIGKILL)
    return problems.build_rlc(R=R, C=C)


def test_cluster_equals_embedded_bitwise(client, grid_sweep):
    kwargs = {"dt": DT, "steps": STEPS, "batch_size": BATCH}
    remote = dv.sweep(problems.build_rlc, GRID, client=client, **kwargs)
    assert same(grid_sweep, remote)


def test_a_failed_batch_is_retried_with_identical_results(client, tmp_path, grid_sweep):
    kwargs = {"dt": DT, "steps": STEPS, "batch_size": BATCH}
    build = functools.partial(fails_once, marker=str(tmp_path / "failed"))
    remote = dv.sweep(build, GRID, client=client, **kwargs)
    assert (tmp_path / "failed").exists()
    assert same(remote, grid_sweep)


def test_a_killed_worker_loses_nothing(client, tmp_path, grid_sweep):
    kwargs = {"dt": DT, "steps": STEPS, "batch_size": BATCH}
    build = functools.partial(kills_once, marker=str(tmp_path / "killed"))
    remote = dv.sweep(build, GRID, client=client, out=tmp_path / "s.nc", **kwargs)
    assert (tmp_path / "killed").exists()
    assert same(remote.load(), grid_sweep)
    remote.close()


MODEL = """
import equinox as eqx
import jax.numpy as jnp
import numpy as np

import diracvi as dv


class Capacitor(eqx.Module):  # a class only this file defines: the workers cannot import it
    capacitance: np.ndarray

    def __call__(self, q, v):
        return 0.5 * 0.75 * v[1] ** 2 - q[2] ** 2 / (2.0 * self.capacitance)


class Resistor(eqx.Module):
    resistance: np.ndarray

    def __call__(self, q, v):
        return jnp.stack([-self.resistance * v[0], 0.0 * v[1], 0.0 * v[2]])


def build(R=1.0, C=3.0):
    system = dv.LagrangeDiracSystem(
        ("qR", "qL", "qC"),
        Capacitor(np.asarray(C)),
        constraints=np.array([[1.0, -1.0, -1.0]]),
        force=Resistor(np.asarray(R)),
    )
    return system, np.zeros(3), np.array([0.0, 7.5, 0.0])
"""


def test_a_model_file_runs_on_workers_that_cannot_import_it(client, tmp_path, grid_sweep):
    model = tmp_path / "circuit.py"
    model.write_text(MODEL)
    kwargs = {"dt": DT, "steps": STEPS, "batch_size": BATCH}
    remote = dv.sweep(str(model), GRID, client=client, **kwargs)
    assert same(remote, grid_sweep)  # build_rlc is the same circuit


# ------------------------------------------------------------------ CLI
def test_cli_sweep_writes_the_dataset(tmp_path):
    import xarray as xr
    from typer.testing import CliRunner

    from diracvi.cli import app

    model = tmp_path / "model.py"
    model.write_text(
        textwrap.dedent(
            """
            from diracvi import problems

            def build(R=1.0, C=3.0):
                return problems.build_rlc(R=R, C=C)
            """
        )
    )
    out = tmp_path / "sweep.nc"
    args = ["sweep", str(model), "--param", "R=0.5:2:3", "--param", "C=1,3"]
    args += ["--dt", str(DT), "--steps", str(STEPS), "--batch-size", str(BATCH), "--out", str(out)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        np.testing.assert_allclose(ds.R.values, [0.5, 1.25, 2.0])
        np.testing.assert_allclose(ds.C.values, [1.0, 3.0])
        assert (ds.status.values == 0).all()
    bad = CliRunner().invoke(app, [*args[:3], "R=1:2", "--dt", "0.1", "--steps", "5"])
    assert bad.exit_code == 2 and "start:stop:count" in bad.output


class _SeriesLoop(eqx.Module):
    """``L = ½ l q̇² − q²/(2C)`` of a series RLC loop's charge; parameters as array leaves."""

    ell: jax.Array
    cap: jax.Array

    def __call__(self, q, v):
        return 0.5 * self.ell * v[0] ** 2 - q[0] ** 2 / (2.0 * self.cap)


class _Drag(eqx.Module):
    r: jax.Array

    def __call__(self, q, v):
        return -self.r * v


def series_rlc(R, C):
    system = dv.LagrangeDiracSystem(
        ("q",), _SeriesLoop(jnp.asarray(0.5), jnp.asarray(C)), force=_Drag(jnp.asarray(R))
    )
    return system, np.array([1.0]), np.array([0.0])


def test_a_linear_sweep_is_stepped_by_the_affine_map_and_equals_simulate():
    # one driver: the sweep's plan is simulate's, so a linear circuit takes the affine
    # map (one per member) and every member equals its own simulate call
    grid = {"R": [0.1, 0.5, 2.0], "C": [0.5, 2.0]}
    ds = dv.sweep(series_rlc, grid, dt=DT, steps=STEPS, batch_size=BATCH)
    assert set(ds.solver.values.ravel()) == {"affine step map"}
    assert (ds.status.values == 0).all()
    for R in grid["R"]:
        for C in grid["C"]:
            traj = dv.simulate(*series_rlc(R, C), dt=DT, steps=STEPS)
            assert traj.solver == "affine step map"
            member = ds.sel(R=R, C=C)
            np.testing.assert_allclose(member["q"].values, traj.q[:, 0], rtol=0, atol=1e-12)
            np.testing.assert_allclose(member["p(q)"].values, traj.p[:, 0], rtol=0, atol=1e-12)
    # solver= is simulate's: Newton steps the same members to round-off
    newton = dv.sweep(series_rlc, grid, dt=DT, steps=STEPS, batch_size=BATCH,
                      solver=dv.NewtonSolver())  # fmt: skip
    assert set(newton.solver.values.ravel()) == {repr(dv.NewtonSolver())}
    np.testing.assert_allclose(newton["q"].values, ds["q"].values, rtol=0, atol=1e-11)


def test_a_linear_sweep_builds_all_its_maps_in_one_call_per_batch(monkeypatch):
    # the maps of a batch's members are formed together (one vmapped probe program, the
    # solves and block maps stacked): one assembly per batch, never one per member; and
    # simulate's single-model builder is not called at all
    from diracvi.driver import plan
    from diracvi.solvers import affine

    def per_member(*args, **kwargs):
        raise AssertionError("a sweep built one member's affine map on its own")

    monkeypatch.setattr(plan, "build", per_member)
    grid = {"R": [0.1, 0.5, 2.0], "C": [0.5, 2.0]}  # 6 members: batches of 4 and 2
    before = affine.ASSEMBLY_COUNT
    ds = dv.sweep(series_rlc, grid, dt=DT, steps=STEPS, batch_size=BATCH)
    assert affine.ASSEMBLY_COUNT - before == 2
    assert set(ds.solver.values.ravel()) == {"affine step map"}
    assert ds.attrs["solver"] == "auto"
    # large members are probed in slices (bounded memory): the same maps, still one
    # assembly per batch (here 2 members per slice: 3 · (1 + 1) · 3 numbers each)
    monkeypatch.setattr(affine, "PROBE_NUMBERS", 36)
    before = affine.ASSEMBLY_COUNT
    sliced = dv.sweep(series_rlc, grid, dt=DT, steps=STEPS, batch_size=BATCH)
    assert affine.ASSEMBLY_COUNT - before == 2
    np.testing.assert_allclose(sliced["q"].values, ds["q"].values, rtol=0, atol=1e-12)


class _Duffing(eqx.Module):
    """``L = ½ q̇² − ½ q² − a q⁴/4``: linear (affine steps) only at ``a = 0``."""

    a: jax.Array

    def __call__(self, q, v):
        return 0.5 * v[0] ** 2 - 0.5 * q[0] ** 2 - 0.25 * self.a * q[0] ** 4


def duffing(a):
    system = dv.LagrangeDiracSystem(("q",), _Duffing(jnp.asarray(a)), name="duffing")
    return system, np.array([1.0]), np.array([0.0])


def test_members_of_one_structure_take_each_its_own_plan():
    # one structure, but only the a = 0 member is affine: it is stepped by its map, the
    # others by Newton, each as its own simulate call would be (not the first member's
    # choice for all)
    ds = dv.sweep(duffing, {"a": [0.0, 2.0]}, dt=DT, steps=STEPS, batch_size=BATCH)
    assert ds.solver.values.tolist() == ["affine step map", "NewtonSolver()"]
    for a in (0.0, 2.0):
        traj = dv.simulate(*duffing(a), dt=DT, steps=STEPS)
        assert traj.solver == str(ds.solver.sel(a=a).values)
        member = ds.sel(a=a)
        np.testing.assert_allclose(member["q"].values, traj.q[:, 0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(member["p(q)"].values, traj.p[:, 0], rtol=0, atol=1e-12)
