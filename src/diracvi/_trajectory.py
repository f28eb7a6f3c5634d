"""The result of a simulation: states, multipliers and diagnostics, with NetCDF I/O."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from ._errors import ModelError

#: status codes of a Trajectory, in the spirit of solve_ivp
STATUS_MESSAGES = {
    0: "success",
    1: "Newton did not converge",
    2: "the step equations became singular",
    3: "NaN or Inf appeared",
}


class Trajectory:
    """States ``(t_k, q_k, p_k)`` and per-step diagnostics of a discrete Dirac simulation.

    Attributes:
        t: times, shape (K+1,) (decreasing for ``scheme="minus"``).
        q, p: positions and momenta, shape (K+1, n).
        multipliers: shape (K, m): each subsystem's μ's, then the interaction λ's.
        energy: ``E`` at each step's quadrature node, shape (K,).
        constraint_residual: the discrete constraints ``ω_{d±}`` at each step, (K, m).
        newton_iterations: iterations per step, shape (K,).
        coords, constraint_names: the column names.
        status: 0 if every requested step was taken; otherwise the failure code, and
            the arrays hold the steps completed before the failure.
        message: a human-readable account of ``status``.
    """

    def __init__(
        self,
        *,
        t,
        q,
        p,
        multipliers,
        energy,
        constraint_residual,
        newton_iterations,
        coords,
        constraint_names,
        dt: float,
        scheme: str,
        discretization: str,
        system_name: str = "system",
        status: int = 0,
        message: str = "success",
        steps_requested: int | None = None,
    ):
        self.t = np.asarray(t, dtype=np.float64)
        self.q = np.asarray(q, dtype=np.float64)
        self.p = np.asarray(p, dtype=np.float64)
        self.multipliers = np.asarray(multipliers, dtype=np.float64)
        self.energy = np.asarray(energy, dtype=np.float64)
        self.constraint_residual = np.asarray(constraint_residual, dtype=np.float64)
        self.newton_iterations = np.asarray(newton_iterations, dtype=np.int64)
        self.coords = tuple(coords)
        self.constraint_names = tuple(constraint_names)
        self.dt = float(dt)
        self.scheme = scheme
        self.discretization = discretization
        self.system_name = system_name
        self.status = int(status)
        self.message = message
        self.steps_requested = len(self.energy) if steps_requested is None else steps_requested

    @property
    def success(self) -> bool:
        return self.status == 0

    @property
    def steps(self) -> int:
        """Number of steps taken (``len(t) - 1``)."""
        return len(self.t) - 1

    def _index(self, name: str) -> int:
        try:
            return self.coords.index(name)
        except ValueError:
            raise KeyError(
                f"no coordinate named {name!r}; this trajectory has {self.coords}"
            ) from None

    def __getitem__(self, name: str) -> np.ndarray:
        """The position history of one coordinate, e.g. ``traj["left.q2"]``."""
        return self.q[:, self._index(name)]

    def momentum(self, name: str) -> np.ndarray:
        """The momentum history of one coordinate."""
        return self.p[:, self._index(name)]

    def multiplier(self, name: str) -> np.ndarray:
        try:
            return self.multipliers[:, self.constraint_names.index(name)]
        except ValueError:
            raise KeyError(
                f"no constraint named {name!r}; this trajectory has {self.constraint_names}"
            ) from None

    def dirac_residual(self, system) -> np.ndarray:
        r"""Per-step residual of ``(X_d^k, 𝔇^±L_d) ∈ D^{d±}_Δ``, shape (steps,).

        ``system`` is the system that produced this trajectory; see
        :func:`diracvi.dirac.trajectory_residual`.
        """
        from .dirac import trajectory_residual  # imported here: dirac imports this module

        return trajectory_residual(system, self)

    def __repr__(self) -> str:
        return (
            f"Trajectory(system={self.system_name!r}, steps={self.steps}, dt={self.dt}, "
            f"scheme={self.scheme!r}, discretization={self.discretization!r}, "
            f"status={self.status} ({self.message.splitlines()[0]}))"
        )

    # ------------------------------------------------------------------ I/O
    def to_xarray(self):
        """An ``xarray.Dataset`` with dims ``time``, ``step``, ``coord``, ``constraint``."""
        import xarray as xr

        return xr.Dataset(
            data_vars={
                "q": (("time", "coord"), self.q),
                "p": (("time", "coord"), self.p),
                "multipliers": (("step", "constraint"), self.multipliers),
                "energy": (("step",), self.energy),
                "constraint_residual": (("step", "constraint"), self.constraint_residual),
                "newton_iterations": (("step",), self.newton_iterations),
            },
            coords={
                "time": self.t,
                "step": np.arange(len(self.energy)),
                "coord": list(self.coords),
                "constraint": list(self.constraint_names),
            },
            attrs={
                "dt": self.dt,
                "scheme": self.scheme,
                "discretization": self.discretization,
                "system_name": self.system_name,
                "status": self.status,
                "message": self.message,
                "steps_requested": self.steps_requested,
                "created_by": "diracvi",
            },
        )

    @classmethod
    def from_xarray(cls, ds) -> Trajectory:
        missing = {"q", "p", "multipliers", "energy", "constraint_residual"} - set(ds.data_vars)
        if missing:
            raise ModelError(
                f"this dataset is not a diracvi trajectory: it lacks {sorted(missing)}."
            )
        return cls(
            t=ds["time"].values,
            q=ds["q"].values,
            p=ds["p"].values,
            multipliers=ds["multipliers"].values.reshape(ds.sizes["step"], ds.sizes["constraint"]),
            energy=ds["energy"].values,
            constraint_residual=ds["constraint_residual"].values.reshape(
                ds.sizes["step"], ds.sizes["constraint"]
            ),
            newton_iterations=ds["newton_iterations"].values,
            coords=[str(c) for c in ds["coord"].values],
            constraint_names=[str(c) for c in ds["constraint"].values],
            dt=float(ds.attrs["dt"]),
            scheme=str(ds.attrs["scheme"]),
            discretization=str(ds.attrs["discretization"]),
            system_name=str(ds.attrs.get("system_name", "system")),
            status=int(ds.attrs.get("status", 0)),
            message=str(ds.attrs.get("message", "success")),
            steps_requested=int(ds.attrs.get("steps_requested", ds.sizes["step"])),
        )

    def save(self, path, extra_attrs: dict | None = None) -> Path:
        """Write NetCDF atomically (a temporary file in the same folder, then a rename)."""
        path = Path(path)
        if not path.parent.exists():
            raise ModelError(
                f"path={str(path)!r}: folder {str(path.parent)!r} does not exist; create it first."
            )
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.close(fd)
        # mkstemp creates the file 0600; give the result the permissions a plain open() would
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        try:
            ds = self.to_xarray()
            ds.attrs.update(extra_attrs or {})
            ds.to_netcdf(tmp, engine="h5netcdf")
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)
        return path


def load(path) -> Trajectory:
    """Read a trajectory written by :meth:`Trajectory.save`."""
    import xarray as xr

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"path={str(path)!r}: no such file; check the path.")
    try:
        with xr.open_dataset(path, engine="h5netcdf") as ds:
            ds.load()
            return Trajectory.from_xarray(ds)
    except (OSError, ValueError) as exc:
        if isinstance(exc, ModelError):
            raise
        raise ModelError(
            f"path={str(path)!r} could not be read as a diracvi NetCDF trajectory: {exc}"
        ) from exc
