"""The result of a simulation: states, multipliers and diagnostics, with NetCDF I/O."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import jax
import numpy as np

from ..errors import ModelError
from ..status import SolveStatus

#: the array attributes of a Trajectory (PyTree children; see _flatten below)
_ARRAY_FIELDS = (
    "t",
    "q",
    "p",
    "_p_nodal",
    "_stage_record",
    "multipliers",
    "energy",
    "constraint_residual",
    "newton_iterations",
    "constraint_violation",
)
#: the static attributes (PyTree auxiliary data)
_STATIC_FIELDS = (
    "save_every",
    "coords",
    "constraint_names",
    "dt",
    "scheme",
    "discretization",
    "system_name",
    "message",
    "solver",
    "steps_requested",
)


class Trajectory:
    """States ``(t_k, q_k, p_k)`` and per-step diagnostics of a discrete Dirac simulation.

    With ``save_every = k`` only every k-th state is kept, and the per-step diagnostics
    are those of the step ending at each saved state (the violation and iteration counts
    cover every step of the interval); with ``save_states=False`` only the diagnostics
    and the final state are kept.

    Attributes:
        t: times of the saved states, shape (S+1,) (decreasing for ``scheme="minus"``).
        q, p: positions and momenta, shape (S+1, n); ``None`` for a diagnostics-only run.
            ``p`` is the scheme's own state: ``p_{k+1} = D₂L_d + f_d^+`` for (+). The
            (±) equations put a step's whole constraint impulse ``A(·)ᵀμ`` on the known
            end's line, so under the midpoint rule ``p`` lags the true momentum by half
            of it in the constrained directions: first order there (positions, and ``p``
            in unconstrained directions, keep order 2).
        p_nodal: momenta at the time nodes to the rule's order, shape (S+1, n):
            ``p_{k+1} − ½ A(·)ᵀμ_k`` under the midpoint rule (the impulse split by the
            rule's weights; on the first step ``p0`` itself is taken as exact); equal to
            ``p`` for the first-order retraction rule and for unconstrained systems. Use
            it for inductor currents, reaction-carrying momenta, and to continue a run.
        multipliers: shape (S, m): each subsystem's μ's, then the interaction λ's
            (``None`` for a diagnostics-only run).
        energy: ``E`` at the quadrature node of the step ending at each saved state, (S,).
        constraint_residual: the discrete constraints ``ω_{d±}`` of that step, (S, m)
            (``None`` for a diagnostics-only run).
        constraint_violation: ``max |ω_{d±}|`` over every step of each interval, (S,).
        newton_iterations: Newton iterations spent in each interval, (S,) (0 for steps
            taken by the affine step map).
        final_q, final_p: the last state reached, (n,) (every coordinate of the system,
            also in a run of chosen columns).
        coords, constraint_names: the column names of ``q`` and ``multipliers``.

    A run of chosen columns (``simulate(..., save_only=names)``) keeps ``q`` of the named
    coordinates and ``multipliers`` of the named constraint rows, in the order given
    (``coords`` and ``constraint_names`` are those names); ``p``, ``p_nodal``,
    ``constraint_residual``, ``energy`` and ``constraint_violation`` are ``None``.
        status: 0 if every requested step was taken; otherwise the failure code, and
            the arrays hold the steps completed before the failure.
        message: a human-readable account of ``status``.
        solver: which stepping method ran (``"affine step map"``, a solver's repr, and
            any fallback).
        stages, stage_multipliers: a staged rule's internal stages ``[Q₁ … Q_s]`` of each
            step, shape (S, n, s), and the multipliers ``ν`` of its stage rows, (S, m, s);
            kept only by ``simulate(..., keep_stages=True)`` (else ``None``).
    """

    def __init__(
        self,
        *,
        t,
        q,
        p,
        multipliers,
        p_nodal=None,
        stage_record=None,
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
        constraint_violation=None,
        step_index=None,
        save_every: int = 1,
        final_state=None,
        solver: str = "",
    ):
        def arr(x, dtype=np.float64):
            return None if x is None else np.asarray(x, dtype=dtype)

        self.t = np.asarray(t, dtype=np.float64)
        self.q, self.p = arr(q), arr(p)
        self._p_nodal = arr(p_nodal)
        self._stage_record = arr(stage_record)
        self.multipliers = arr(multipliers)
        # (energy None: a run of chosen columns, simulate(..., save_only=…), forms none)
        self.energy = arr(energy)
        self.constraint_residual = arr(constraint_residual)
        self.newton_iterations = np.asarray(newton_iterations, dtype=np.int64)
        if constraint_violation is None and self.constraint_residual is not None:
            con = self.constraint_residual
            constraint_violation = np.max(np.abs(con), axis=1, initial=0.0)
        self.constraint_violation = arr(constraint_violation)
        self.step_index = (
            np.arange(len(self.t)) if step_index is None else np.asarray(step_index, np.int64)
        )
        self.save_every = int(save_every)
        if final_state is None:
            q_prev = self.q[-2] if len(self.q) > 1 else self.q[-1]
            mu = self.multipliers[-1] if len(self.multipliers) else np.zeros(len(constraint_names))
            final_state = (self.q[-1], self.p[-1], q_prev, mu)
        self.final_state = tuple(np.asarray(a, dtype=np.float64) for a in final_state)
        self.coords = tuple(coords)
        self.constraint_names = tuple(constraint_names)
        self.dt = float(dt)
        self.scheme = scheme
        self.discretization = discretization
        self.system_name = system_name
        self.status = int(status)
        self.message = message
        self.solver = solver
        self.steps_requested = self.steps if steps_requested is None else steps_requested

    @classmethod
    def traced(cls, *, status, steps_requested, **fields) -> Trajectory:
        """A trajectory of JAX arrays, as a traced :func:`~diracvi.simulate` returns it
        (no conversion to NumPy; ``status`` is an array, ``message`` says how to read it)."""
        self = object.__new__(cls)
        for name in _ARRAY_FIELDS:
            setattr(self, name, fields.pop(name.lstrip("_"), None))
        self.final_state = tuple(fields.pop("final_state"))
        self.step_index = np.asarray(fields.pop("step_index"), dtype=np.int64)
        self.status = status
        self.steps_requested = steps_requested
        self.message = f"traced run: status is an array ({SolveStatus.legend()})"
        for name, value in fields.items():
            setattr(self, name, value)
        self.coords = tuple(self.coords)
        self.constraint_names = tuple(self.constraint_names)
        return self

    @classmethod
    def _of_run(cls, lazy, fields: dict) -> Trajectory:
        """A trajectory of a host run: the attributes ``fields`` as they are (no
        conversions), and ``lazy(name)`` makes each attribute in ``lazy.names`` on first
        access: a warm call does not pay for the arrays a user never reads."""
        self = object.__new__(cls)
        self.__dict__.update(fields)
        self._lazy = lazy
        return self

    def __getattr__(self, name: str):
        # only reached for an attribute not set: one that _of_run left to make lazily
        lazy = self.__dict__.get("_lazy")
        if lazy is None or name not in lazy.names:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        value = lazy(name)
        setattr(self, name, value)
        return value

    def __getstate__(self):
        # a pickled or copied trajectory carries its arrays, not the packed output
        lazy = self.__dict__.get("_lazy")
        for name in lazy.names if lazy is not None else ():
            getattr(self, name)
        return {k: v for k, v in self.__dict__.items() if k != "_lazy"}

    @property
    def p_nodal(self):
        """Momenta at the nodes to the rule's order (see the class documentation)."""
        return self.p if self._p_nodal is None else self._p_nodal

    def _stage_parts(self):
        """``(stages, stage_multipliers)`` from the kept records (rows ``[Q.ravel() ν.ravel()]``,
        see :func:`~diracvi.driver.stepping.stage_record`), or ``(None, None)``."""
        record = self._stage_record
        if record is None:
            return None, None
        n, m = len(self.coords), len(self.constraint_names)
        s = record.shape[-1] // (n + m)
        lead = record.shape[:-1]
        return (
            record[..., : n * s].reshape(*lead, n, s),
            record[..., n * s :].reshape(*lead, m, s),
        )

    @property
    def stages(self):
        """A staged rule's internal stage positions of every step, (S, n, s), in time order
        (``None`` unless the run was made with ``keep_stages=True``)."""
        return self._stage_parts()[0]

    @property
    def stage_multipliers(self):
        """The multipliers ``ν`` of every step's stage rows, (S, m, s) (``None`` unless
        ``keep_stages=True``)."""
        return self._stage_parts()[1]

    @property
    def success(self) -> bool:
        return self.status == 0

    @property
    def steps(self) -> int:
        """Number of steps taken."""
        return int(self.step_index[-1])

    @property
    def states_saved(self) -> bool:
        return self.q is not None

    @property
    def final_q(self) -> np.ndarray:
        return self.final_state[0]

    @property
    def final_p(self) -> np.ndarray:
        return self.final_state[1]

    def _states(self, what: str) -> None:
        if self.q is None:
            raise ModelError(
                f"{what}: this run kept no states (simulate(..., save_states=False)); "
                "rerun with save_states=True (and save_every=k to thin them), or use "
                "final_q / final_p and the diagnostics."
            )

    def _index(self, name: str) -> int:
        try:
            return self.coords.index(name)
        except ValueError:
            raise KeyError(
                f"no coordinate named {name!r}; this trajectory has {self.coords}"
            ) from None

    def __getitem__(self, name: str) -> np.ndarray:
        """The position history of one coordinate, e.g. ``traj["left.q2"]``."""
        self._states(f"traj[{name!r}]")
        return self.q[:, self._index(name)]

    def momentum(self, name: str) -> np.ndarray:
        """The momentum history of one coordinate."""
        self._states(f"traj.momentum({name!r})")
        return self.p[:, self._index(name)]

    def multiplier(self, name: str) -> np.ndarray:
        self._states(f"traj.multiplier({name!r})")
        try:
            return self.multipliers[:, self.constraint_names.index(name)]
        except ValueError:
            raise KeyError(
                f"no constraint named {name!r}; this trajectory has {self.constraint_names}"
            ) from None

    def dirac_residual(self, system) -> np.ndarray:
        r"""Per-step residual of ``(X_d^k, 𝔇^±L_d) ∈ D^{d±}_Δ``, shape (steps,).

        ``system`` is the system that produced this trajectory; see
        :func:`diracvi.dirac.trajectory_residual`. Covers every rule: a ``"lobatto"``
        run made with ``keep_stages=True`` is checked node by node from its kept stages,
        one without them by re-solving its stages from its states.
        """
        from ..dirac import trajectory_residual  # imported here: dirac imports this module

        self._states("traj.dirac_residual(system)")
        if self.save_every != 1:
            raise ModelError(
                f"traj.dirac_residual(system) needs every step, but this run saved every "
                f"{self.save_every}th state; rerun with save_every=1."
            )

        return trajectory_residual(system, self)

    def __repr__(self) -> str:
        return (
            f"Trajectory(system={self.system_name!r}, steps={self.steps}, dt={self.dt}, "
            f"scheme={self.scheme!r}, discretization={self.discretization!r}, "
            f"save_every={self.save_every}, solver={self.solver!r}, "
            f"status={self.status} ({self.message.splitlines()[0]}))"
        )

    # ------------------------------------------------------------------ I/O
    def to_xarray(self):
        """An ``xarray.Dataset`` with dims ``time`` (saved states), ``step`` (saved
        intervals), ``coord`` and ``constraint``."""
        import xarray as xr

        if self.energy is None:
            raise ModelError(
                "traj.to_xarray(): this run kept chosen columns only (simulate(..., "
                "save_only=…)), without the energies and momenta a Trajectory dataset "
                "holds. Fix: rerun without save_only, or write traj.q and traj.multipliers "
                "(named by traj.coords, traj.constraint_names) yourself."
            )
        data = {
            "energy": (("step",), self.energy),
            "constraint_violation": (("step",), self.constraint_violation),
            "newton_iterations": (("step",), self.newton_iterations),
            "step_index": (("time",), self.step_index),
            "final_q": (("coord",), self.final_state[0]),
            "final_p": (("coord",), self.final_state[1]),
            "final_q_prev": (("coord",), self.final_state[2]),
            "final_multipliers": (("constraint",), self.final_state[3]),
        }
        if self.q is not None:
            data.update(
                q=(("time", "coord"), self.q),
                p=(("time", "coord"), self.p),
                multipliers=(("step", "constraint"), self.multipliers),
                constraint_residual=(("step", "constraint"), self.constraint_residual),
            )
            if self._p_nodal is not None:
                data["p_nodal"] = (("time", "coord"), self._p_nodal)
        return xr.Dataset(
            data_vars=data,
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
                "save_every": self.save_every,
                "solver": self.solver,
                "created_by": "diracvi",
            },
        )

    @classmethod
    def from_xarray(cls, ds) -> Trajectory:
        missing = {"energy", "newton_iterations"} - set(ds.data_vars)
        if missing:
            raise ModelError(
                f"this dataset is not a diracvi trajectory: it lacks {sorted(missing)}."
            )
        steps, m = ds.sizes["step"], ds.sizes["constraint"]
        states = "q" in ds.data_vars

        def get(name, shape=None):
            if name not in ds.data_vars:
                return None
            values = ds[name].values
            return values if shape is None else values.reshape(shape)

        final = None
        if "final_q" in ds.data_vars:
            final = tuple(
                get(name, shape)
                for name, shape in (
                    ("final_q", None),
                    ("final_p", None),
                    ("final_q_prev", None),
                    ("final_multipliers", (m,)),
                )
            )
        return cls(
            t=ds["time"].values,
            q=get("q"),
            p=get("p"),
            p_nodal=get("p_nodal"),
            multipliers=get("multipliers", (steps, m)) if states else None,
            energy=ds["energy"].values,
            constraint_residual=get("constraint_residual", (steps, m)) if states else None,
            newton_iterations=ds["newton_iterations"].values,
            coords=[str(c) for c in ds["coord"].values],
            constraint_names=[str(c) for c in ds["constraint"].values],
            dt=float(ds.attrs["dt"]),
            scheme=str(ds.attrs["scheme"]),
            discretization=str(ds.attrs["discretization"]),
            system_name=str(ds.attrs.get("system_name", "system")),
            status=int(ds.attrs.get("status", 0)),
            message=str(ds.attrs.get("message", "success")),
            steps_requested=int(ds.attrs.get("steps_requested", steps)),
            constraint_violation=get("constraint_violation"),
            step_index=get("step_index"),
            save_every=int(ds.attrs.get("save_every", 1)),
            final_state=final,
            solver=str(ds.attrs.get("solver", "")),
        )

    def save(self, path, extra_attrs: dict | None = None, dataset=None) -> Path:
        """Write NetCDF atomically (a temporary file in the same folder, then a rename).

        ``dataset``: write this ``xarray.Dataset`` (the trajectory's own, with variables
        added, e.g. by :func:`diracvi.spice.to_dataset`) instead of :meth:`to_xarray`.
        """
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
            ds = self.to_xarray() if dataset is None else dataset
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


class _Index:
    """``step_index`` as PyTree auxiliary data: compared by value, hashable."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = np.asarray(value, dtype=np.int64)

    def __eq__(self, other):
        return isinstance(other, _Index) and np.array_equal(self.value, other.value)

    def __hash__(self):
        return hash(self.value.tobytes())


def _flatten(traj: Trajectory):
    children = (
        tuple(getattr(traj, name) for name in _ARRAY_FIELDS),
        traj.final_state,
        traj.status,
    )
    aux = (tuple(getattr(traj, name) for name in _STATIC_FIELDS), _Index(traj.step_index))
    return children, aux


def _unflatten(aux, children) -> Trajectory:
    self = object.__new__(Trajectory)
    arrays, final_state, status = children
    for name, value in zip(_ARRAY_FIELDS, arrays, strict=True):
        setattr(self, name, value)
    self.final_state = tuple(final_state)
    self.status = status
    static, index = aux
    for name, value in zip(_STATIC_FIELDS, static, strict=True):
        setattr(self, name, value)
    self.step_index = index.value
    return self


# A Trajectory is a PyTree (arrays as leaves), so a function calling simulate can
# return it from jax.jit or jax.vmap; untraced results keep their NumPy arrays.
jax.tree_util.register_pytree_node(Trajectory, _flatten, _unflatten)
