"""Checkpoints of long runs: completed chunks on disk, so a killed run resumes exactly.

The file is an ordinary trajectory NetCDF (``dv.load`` reads it) with two extra
attributes: a fingerprint of everything that determines the run, and whether the run is
still in progress. It is rewritten atomically after every chunk (temporary file, then
rename), so a kill at any instant leaves either the previous or the new checkpoint.

Resuming is bitwise identical to an uninterrupted run because (i) chunks always start at
multiples of ``checkpoint_every`` from step 0, so both runs execute the same compiled
chunk programs on the same inputs, and (ii) the scan carry — the state plus the previous
position and multipliers that seed Newton's initial guess — is rebuilt exactly from the
saved float64 arrays.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from ..errors import ModelError
from .trajectory import Trajectory


def fingerprint(
    system, q0, p0, *, dt, steps, scheme, discretization, solver, chunk, save=(1, True), t0=0.0
) -> str:
    """A hash of everything that determines the run's numbers."""
    description = json.dumps(
        {
            "coords": list(system.coords),
            "constraints": list(system.constraint_names),
            "system": repr(system),
            "dt": float(dt).hex(),
            "t0": float(t0).hex(),
            "steps": int(steps),
            "scheme": scheme,
            "discretization": discretization,
            "solver": repr(solver),
            "chunk": int(chunk),
            "save": [int(save[0]), bool(save[1])],
        },
        sort_keys=True,
    ).encode()
    digest = hashlib.sha256(description)
    digest.update(np.asarray(q0, dtype=np.float64).tobytes())
    digest.update(np.asarray(p0, dtype=np.float64).tobytes())
    return digest.hexdigest()


def write(traj: Trajectory, path: Path, key: str, in_progress: bool, extra=None) -> None:
    attrs = {"checkpoint": key, "in_progress": int(in_progress), **(extra or {})}
    traj.save(path, extra_attrs=attrs)


def read(path: Path, key: str) -> tuple[Trajectory, bool, dict] | None:
    """The saved run, whether it is still in progress and the file's attributes, or None
    if there is none yet."""
    if not path.exists():
        return None
    import xarray as xr

    try:
        with xr.open_dataset(path, engine="h5netcdf") as ds:
            ds.load()
    except (OSError, ValueError) as exc:
        raise ModelError(
            f"checkpoint={str(path)!r} exists but is not a readable diracvi checkpoint "
            f"({exc}); delete it or choose another path."
        ) from exc
    if ds.attrs.get("checkpoint") != key:
        raise ModelError(
            f"checkpoint={str(path)!r} was written by a different run (other system, "
            "initial state, dt, steps, scheme, discretization, solver or checkpoint_every); "
            "delete it to start afresh, or choose another path."
        )
    return Trajectory.from_xarray(ds), bool(ds.attrs.get("in_progress", 0)), dict(ds.attrs)
