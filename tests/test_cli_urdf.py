"""``diracvi run robot.urdf``: a URDF robot released from rest, its motion saved by name."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from typer.testing import CliRunner

import diracvi as dv
from diracvi import components as cp
from diracvi.cli import EXIT_USAGE, app

ARM = Path(__file__).parent / "data" / "urdf" / "spatial_arm.urdf"
runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.mark.slow  # ~30 s of compiling (two builds of the arm); the refusals below stay default
def test_run_urdf_writes_the_motion_by_name(tmp_path):
    out = tmp_path / "arm.nc"
    result = invoke("run", ARM, "--dt", "2e-3", "--steps", 40, "--out", out, "--plot")
    assert result.exit_code == 0, result.output
    assert "final joints: yaw" in result.output
    assert "<limit> ignored" in result.output  # the file's shoulder limit, noted
    assert (tmp_path / "arm.png").stat().st_size > 0
    ds = xr.open_dataset(out)
    assert list(ds.joint.values) == ["yaw", "shoulder", "elbow"]
    assert list(ds.body.values) == ["turret", "upper_arm", "forearm"]
    # the same run in-process: the saved names are the model's own coordinates
    model = cp.read_urdf(ARM, quiet=True).build()
    traj = dv.simulate(
        model.system, model.q0, model.p0, dt=2e-3, steps=40, discretization="midpoint"
    )
    np.testing.assert_allclose(ds.q.values, traj.q, rtol=0, atol=1e-12)
    for j in ds.joint.values:
        np.testing.assert_allclose(
            ds.joint_position.sel(joint=j).values, model.joint_position(traj.q, j), atol=1e-12
        )
    assert np.all(ds.joint_position.isel(time=0).values == 0.0)  # released at the zero pose
    for b in ds.body.values:
        np.testing.assert_array_equal(
            ds.body_position.sel(body=b).values, model.body(traj.q, b)[:, 0:3]
        )
    rot = ds.body_orientation.values
    gram = np.einsum("tbji,tbjk->tbik", rot, rot)
    assert np.max(np.abs(gram - np.eye(3))) < 1e-13  # orthonormal at every saved time
    # roll, pitch, yaw by name: R = Rz(yaw) Ry(pitch) Rx(roll) rebuilt from them
    roll, pitch, yaw = np.moveaxis(ds.body_angles.sel(angle=["roll", "pitch", "yaw"]).values, -1, 0)
    cr, sr, cp_, sp, cy, sy = (
        np.cos(roll),
        np.sin(roll),
        np.cos(pitch),
        np.sin(pitch),
        np.cos(yaw),
        np.sin(yaw),
    )
    rebuilt = np.stack(
        [
            np.stack([cy * cp_, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
            np.stack([sy * cp_, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
            np.stack([-sp, cp_ * sr, cp_ * cr], -1),
        ],
        -2,
    )
    np.testing.assert_allclose(rebuilt, rot, atol=1e-12)
    # the arm falls: its joints move, and the energy is held by the midpoint rule
    assert np.max(np.abs(ds.joint_position.isel(time=-1).values)) > 1e-3
    assert np.ptp(ds.energy.values) < 1e-6 * abs(ds.energy.values[0])


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--discretization", "retraction"), "steps with midpoint or lobatto"),
        (("--raw", "x.raw"), "is a URDF robot"),
    ],
)
def test_run_urdf_refuses_what_does_not_apply(args, message):
    result = invoke("run", ARM, *args)
    assert result.exit_code == EXIT_USAGE
    assert message in result.output


def test_run_urdf_names_a_missing_file(tmp_path):
    result = invoke("run", tmp_path / "robot.urdf")
    assert result.exit_code == EXIT_USAGE
    assert "robot.urdf" in result.output and "does not exist" in result.output
