"""Trajectories: lookup by name, xarray, NetCDF round trip."""

import numpy as np
import pytest

import diracvi as dv
from conftest import run
from diracvi import problems


@pytest.fixture(scope="module")
def traj():
    return run(problems.get("rlc-torn"), steps=40)


def test_shapes_and_lookup(traj):
    n, m = 5, 3
    assert traj.t.shape == (41,) and traj.q.shape == (41, n) and traj.p.shape == (41, n)
    assert traj.multipliers.shape == (40, m) and traj.constraint_residual.shape == (40, m)
    assert traj.energy.shape == (40,)
    assert traj.coords == ("rl.qR", "rl.qL", "rl.qS1", "cap.qS2", "cap.qC")
    assert traj.constraint_names == ("rl.KCL", "cap.KCL", "rl.qS1=cap.qS2")
    np.testing.assert_array_equal(traj["cap.qC"], traj.q[:, 4])
    np.testing.assert_array_equal(traj.momentum("rl.qL"), traj.p[:, 1])
    with pytest.raises(KeyError, match="no coordinate named 'qC'"):
        traj["qC"]


def test_netcdf_round_trip_is_exact(traj, tmp_path):
    path = traj.save(tmp_path / "rlc.nc")
    back = dv.load(path)
    for field in ("t", "q", "p", "multipliers", "energy", "constraint_residual"):
        np.testing.assert_array_equal(getattr(back, field), getattr(traj, field))
    assert back.coords == traj.coords and back.constraint_names == traj.constraint_names
    assert (back.dt, back.scheme, back.discretization) == (0.1, "plus", "retraction")
    assert not list(tmp_path.glob(".*tmp"))  # the atomic write left nothing behind


def test_round_trip_without_constraints(tmp_path):
    traj = run(problems.get("spring-chain"), steps=5)
    back = dv.load(traj.save(tmp_path / "chain.nc"))
    assert back.multipliers.shape == (5, 0)
    np.testing.assert_array_equal(back.q, traj.q)


def test_to_xarray_dims(traj):
    ds = traj.to_xarray()
    assert ds["q"].dims == ("time", "coord")
    assert list(ds["coord"].values) == list(traj.coords)
    assert float(ds["q"].sel(coord="cap.qC").isel(time=-1)) == traj["cap.qC"][-1]


def test_load_reports_missing_and_foreign_files(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such file"):
        dv.load(tmp_path / "missing.nc")
    (tmp_path / "junk.nc").write_text("not netcdf")
    with pytest.raises(dv.ModelError, match="could not be read"):
        dv.load(tmp_path / "junk.nc")
