"""Simulate a netlist: :func:`run` reads, steps and names the results.

By default a run has SPICE's time semantics: ``.tran``'s TSTEP is the output interval,
the steps are chosen by an error estimate for ``.options``' tolerances, never longer than
TMAX and ending exactly on every source corner, and the waveforms are reported on the
TSTEP grid from TSTART. ``dt=`` forces a fixed step instead (the trajectory's own points
are then the output).

A linear circuit's variable steps (from :data:`SPARSE_MIN_COORDINATES` coordinates)
are solved on sparse step maps
(:mod:`diracvi.driver.adaptive_sparse`, O(n) per step for a ladder), any other circuit's
by Newton in one compiled loop (:mod:`diracvi.driver.adaptive`); ``result.trajectory.solver``
says which ran.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import jax
import numpy as np

from ..driver import events
from ..driver.adaptive import TOO_MANY, Controls, adaptive
from ..driver.adaptive_sparse import DEFAULT_ERROR, ERRORS, adaptive_sparse
from ..driver.algebraic import inertia
from ..driver.budget import TriesBudget
from ..driver.delay import lines, simulate_lines
from ..driver.events import relays
from ..driver.law_corners import corner_nodes
from ..driver.sparse_lines import line_breakpoints, line_hmax
from ..errors import ModelError, StepFailure
from ..model.interconnect import InterconnectedSystem
from ..model.roundoff import force_corners
from ..solvers.limiting import junctions
from ..solvers.sparse_affine import NotSparseAffine
from . import _netcdf
from ._measure import Measurement, measure
from ._operating_point import OperatingPoint
from ._operating_point import operating_point as _operating_point
from ._parse import Netlist, read
from ._probe import waveforms
from ._resample import Sampled, Sampler
from ._save import differences
from ._stream import KEEP_MAX, StreamRecord, step_signals
from ._tran import TranSettings, breakpoints, override, source_cycles, tran_settings


@dataclass(frozen=True)
class Internal:
    """A variable-step run's own points: nodes ``time``, step sizes ``h``, and the
    waveforms sampled at the nodes (``internal["v(out)"]``)."""

    time: np.ndarray
    h: np.ndarray
    waveforms: Mapping

    def __getitem__(self, key: str) -> np.ndarray:
        return _lookup(self.waveforms, key)


@dataclass(frozen=True, eq=False)
class Result(Mapping):
    """A netlist's transient: the trajectory and its SPICE-named waveforms.

    A read-only mapping over the saved vectors (``netlist.vectors``: the ``.save``
    lines, else node voltages and voltage-source and inductor currents), named as
    ngspice names them: ``result["v(out)"]``, ``result["i(v1)"]`` over ``result.time``;
    ``keys()``, ``items()``, ``len``. Any other waveform of the circuit can still be
    asked for by name (``result["i(R1)"]``, ``"i(R1)" in result``); names are
    case-insensitive.
    ``result.time`` is the TSTEP grid from TSTART for a variable-step run, the steps of a
    fixed-step one.
    ``result.internal``: a variable-step run's own points (``None`` for a fixed step,
    and for a large circuit's run that formed only the TSTEP grid, see :mod:`._stream`;
    ``internal=True`` keeps them);
    ``result.trajectory``: the :class:`~diracvi.Trajectory` of a fixed-step run, the
    :class:`~diracvi.driver.adaptive.AdaptiveRun` of a variable-step one;
    ``result.settings``: the :class:`~diracvi.spice._tran.TranSettings` used;
    ``result.measurements``: the netlist's ``.measure tran`` lines, measured
    (:mod:`._measure`).
    """

    netlist: Netlist
    trajectory: object
    waveforms: dict
    times: np.ndarray | None = None
    internal: Internal | None = None
    settings: TranSettings | None = None
    #: a variable-step run's step-centred signals and their sampler (:mod:`._resample`)
    centred: tuple | None = None

    @property
    def time(self) -> np.ndarray:
        """The output times."""
        return self.trajectory.t if self.times is None else self.times

    def at(self, times) -> dict[str, np.ndarray]:
        """Every waveform at ``times`` (within the run), as the run itself samples it:
        a variable-step run by quadratic interpolation through its step centres within
        each interval between corners (what the TSTEP grid gets, see :mod:`._resample`),
        a fixed-step run linearly between its nodes."""
        times = np.asarray(times, dtype=np.float64)
        if self.centred is None and self.times is not None:
            raise ModelError(
                f"result.at(): the step-centred signals of this run were not kept (a large "
                f"circuit's are O(signals · steps); over {KEEP_MAX} numbers only the TSTEP "
                "grid is formed, while the run steps). Fix: spice.run(..., internal=True) "
                "keeps them, or read the waveforms on result.time."
            )
        if self.centred is not None:
            sampler, signals, start = self.centred
            return _pin_start(signals.sample(sampler, times), times, start)
        t = np.asarray(self.trajectory.t, dtype=np.float64)
        return {
            k: np.interp(times, t, np.asarray(v, dtype=float)) for k, v in self.waveforms.items()
        }

    @cached_property
    def measurements(self) -> tuple[Measurement, ...]:
        """The ``.measure tran`` results in the netlist's order (each with its
        ``value``, or ``failed`` saying why there is none)."""
        return measure(self.netlist.measures, self)

    def _saved(self) -> dict:
        vectors = self.netlist.vectors or tuple((k, k) for k in self.waveforms)
        return {name: key for name, key in vectors if key in self.waveforms}

    def __getitem__(self, key: str) -> np.ndarray:
        want = key.replace(" ", "").lower()
        for name, wave in self._saved().items():
            if name == want:
                return self.waveforms[wave]
        for name, values in self.waveforms.items():
            if name.lower() == want:
                return values
        lean = self.centred is None and self.times is not None  # formed while stepping
        hint = (
            "; this run formed only the saved vectors (a large circuit's run: see "
            "spice/_stream.py): name it on a .save line, or pass internal=True"
            if lean
            else ""
        )
        raise KeyError(
            f"{key!r} is not a waveform of this circuit; the saved ones are "
            f"{list(self._saved())}, others {sorted(self.waveforms)}{hint}"
        )

    def __contains__(self, key) -> bool:
        if not isinstance(key, str):
            return False
        try:
            self[key]
        except KeyError:
            return False
        return True

    def __iter__(self):
        return iter(self._saved())

    def __len__(self) -> int:
        return len(self._saved())

    def __repr__(self) -> str:
        t = self.time
        names = list(self._saved())
        shown = ", ".join(names[:8]) + (f", … ({len(names)} in all)" if len(names) > 8 else "")
        return (
            f"<spice.Result {self.netlist.title!r}: t {t[0]:g} → {t[-1]:g} s, "
            f"{self._steps()}; vectors {shown}>"
        )

    __str__ = __repr__

    def _steps(self) -> str:
        if self.times is None:
            return f"{len(self.time) - 1} steps of {float(self.trajectory.dt):g} s"
        h = self.trajectory.h
        return f"{len(h)} variable steps of {h.min():.3g} … {h.max():.3g} s"

    def to_xarray(self):
        """The dataset of the saved vectors (``.save``, else every ``v(<node>)`` and
        ``i(<element>)``) over ``time``: one variable each, named as ngspice names them,
        or, beyond ``SEPARATE_MAX`` vectors, one variable ``vectors(time, vector)`` with
        the names as the ``vector`` coordinate (thousands of NetCDF variables take
        minutes to create; one 2-d variable a fraction of a second). A fixed-step run
        adds the trajectory's diagnostics, final state and attributes, and its states
        (``q``, ``p``, multipliers) up to ``STATES_MAX`` coordinates (above, the file
        would be O(coordinates · steps): the vectors are what a netlist asks for)."""
        import xarray as xr

        saved = self._saved()
        if len(saved) <= SEPARATE_MAX:
            data = {name: (("time",), self.waveforms[key]) for name, key in saved.items()}
            layout = "one variable per vector"
        else:
            stacked = np.stack([self.waveforms[key] for key in saved.values()], axis=1)
            data = {"vectors": (("time", "vector"), stacked)}
            layout = "vectors(time, vector)"
        coords = {"time": self.time}
        if len(saved) > SEPARATE_MAX:
            coords["vector"] = list(saved)
        if self.internal is None and self.times is None:
            traj = self.trajectory
            ds = traj.to_xarray()
            if traj.q is not None and traj.q.shape[1] > STATES_MAX:
                ds = ds.drop_vars([v for v in STATE_VARIABLES if v in ds.data_vars])
                ds.attrs["states"] = (
                    f"not written: {traj.q.shape[1]} coordinates (more than {STATES_MAX}); "
                    "the saved vectors are"
                )
            ds = ds.assign(data).assign_coords({k: v for k, v in coords.items() if k != "time"})
            ds.attrs["vectors"] = layout
            ds.attrs.update(self._measure_attrs())
            return ds
        ds = xr.Dataset(data, coords=coords)
        ds.attrs.update(self._variable_attrs(layout))
        ds.attrs.update(self._measure_attrs())
        return ds

    def _measure_attrs(self) -> dict:
        """``measure_<name>``: each measurement's value, or why it failed (a later line
        of the same name wins, as ngspice's last print does; a later line that did not
        read does not, as ngspice prints nothing for it)."""
        out = {}
        for m in self.measurements:
            key = f"measure_{m.name}"
            if m.failed is None:
                out[key] = m.value
            elif key not in out or not m.failed.startswith("not read: "):
                out[key] = f"failed: {m.failed}"
        return out

    def _variable_attrs(self, layout: str) -> dict:
        """A variable-step run's file attributes: the layout, the run and its settings."""
        march, settings = self.trajectory, self.settings
        return dict(
            vectors=layout,
            title=self.netlist.title,
            scheme="plus",
            discretization="midpoint",
            steps="variable",
            steps_taken=len(march.h),
            tries=march.tries,
            rejected=march.rejected,
            h_min=float(march.h.min()),
            h_max=float(march.h.max()),
            tstep=settings.step,
            tstop=settings.stop,
            tstart=settings.start,
            tmax=settings.max_step,
            reltol=settings.reltol,
            abstol=settings.abstol,
            vntol=settings.vntol,
            chgtol=settings.chgtol,
        )

    def save(self, path) -> Path:
        """Write :meth:`to_xarray` as NetCDF (atomically: a temporary file, then a rename)."""
        path = Path(path)
        if self.internal is None and self.times is None:
            return self.trajectory.save(path, dataset=self.to_xarray())
        if not path.parent.exists():
            raise ModelError(
                f"path={str(path)!r}: folder {str(path.parent)!r} does not exist; create it first."
            )
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        saved = self._saved()
        try:
            if len(saved) <= SEPARATE_MAX:  # the same file, without importing xarray
                waves = {name: self.waveforms[key] for name, key in saved.items()}
                attrs = self._variable_attrs("one variable per vector")
                attrs.update(self._measure_attrs())
                _netcdf.write(tmp, self.time, waves, attrs)
            else:
                self.to_xarray().to_netcdf(tmp, engine="h5netcdf")
            os.replace(tmp, path)
        finally:
            if tmp.exists():
                tmp.unlink()
        return path


#: up to this many saved vectors, one NetCDF variable each; more: one 2-d variable
SEPARATE_MAX = 256
#: a fixed-step run's file holds the trajectory's states up to this many coordinates
STATES_MAX = 256
#: the trajectory's per-state variables (O(coordinates · steps))
STATE_VARIABLES = ("q", "p", "p_nodal", "multipliers", "constraint_residual")


def _lookup(waves: dict, key: str) -> np.ndarray:
    want = key.replace(" ", "").lower()
    for name, values in waves.items():
        if name.lower() == want:
            return values
    raise KeyError(f"{key!r} is not a waveform of this circuit; there are {sorted(waves)}")


def run(
    source,
    *,
    discretization: str = "midpoint",
    dt=None,
    steps=None,
    internal: bool = False,
    params=None,
    reltol=None,
    abstol=None,
    vntol=None,
    chgtol=None,
    tmax=None,
    step_error=None,
    **simulate_kwargs,
) -> Result:
    """Read a netlist (path, text or :class:`Netlist`) and simulate its ``.tran``.

    Without ``dt``: SPICE's semantics (see the module doc), under the midpoint rule.
    ``internal=True`` reports the waveforms at the run's own nodes instead of the TSTEP
    grid (they are also in ``result.internal``).

    ``dt``: a fixed step, to TSTOP (``⌈TSTOP/dt⌉`` steps) unless ``steps`` is given;
    further keywords go to :func:`diracvi.simulate`. Midpoint is the default rule: the
    left-point rule cannot step a capacitor joined in a loop with voltage sources or
    other capacitors (its step is singular).

    ``params`` overrides ``.param`` values (see :func:`read`; traced values make a
    fixed-step run differentiable). Without ``UIC`` on ``.tran`` the run starts from the
    DC operating point (SPICE's rule; ``.ic`` values hold their nodes while it is
    solved), with ``UIC`` from the state the netlist gives (``.ic`` and ``IC=``, zero
    otherwise).

    ``reltol``, ``abstol``, ``vntol``, ``chgtol`` (SPICE's ``.options`` names) and
    ``tmax`` (``.tran``'s TMAX, seconds) replace the deck's own values for the variable
    steps, the deck left unedited: ``spice.run("deck.cir", reltol=1e-5, tmax=2e-11)``
    runs a deck whose own settings are loose as a fine reference would. Each must be a
    finite number > 0; a fixed step (``dt=``) has no tolerance and refuses them.

    ``step_error``: how a linear circuit's variable steps on the sparse maps are judged —
    ``"doubling"`` (each try one step against two of half its size: three solves a try)
    or ``"truncation"`` (one solve a step, its local truncation error from the recorded
    past; :mod:`diracvi.driver.sparse_truncation`); ``None`` is
    :data:`diracvi.driver.adaptive_sparse.DEFAULT_ERROR`. A circuit the compiled loop
    steps (nonlinear, switched, small) is judged by step doubling whatever is given.
    """
    overrides = dict(reltol=reltol, abstol=abstol, vntol=vntol, chgtol=chgtol, tmax=tmax)
    overrides = {k: v for k, v in overrides.items() if v is not None}
    if step_error is not None:
        if step_error not in ERRORS:
            raise ModelError(
                f"spice.run(step_error={step_error!r}): one of {ERRORS}, or None (the "
                f"default, {DEFAULT_ERROR!r})."
            )
        overrides["step_error"] = step_error
    thinned = {
        k: v
        for k, v in simulate_kwargs.items()
        if (k == "save_every" and v != 1) or (k == "save_states" and v is not True)
    }
    if thinned:  # refused here: waveforms() would fail after the whole run, naming neither
        options = ", ".join(f"{k}={v!r}" for k, v in thinned.items())
        raise ModelError(
            f"spice.run({options}): a netlist's waveforms are computed from every state. "
            "Fix: leave it out and thin the result (result['v(out)'][::2]), or step "
            "netlist.system with diracvi.simulate."
        )
    netlist = source if isinstance(source, Netlist) else read(source, params=params)
    if dt is None and steps is None:
        if any(isinstance(v, jax.core.Tracer) for v in (params or {}).values()):
            fixes = [f"pass dt= (e.g. the netlist's TSTEP {netlist.dt:g})"]
            if not netlist.uic:  # the operating point is refused under a transformation too
                fixes.append(
                    "add UIC to the .tran line (the DC operating point is not solved under "
                    "a transformation; the run starts from .ic and IC= values, else zero)"
                )
            raise ModelError(
                "params=: traced values (jax.grad, jit, vmap) need a fixed step, because the "
                f"variable steps are chosen on the host. Fix: {' and '.join(fixes)}."
            )
        return _variable(netlist, discretization, internal, simulate_kwargs, overrides)
    if overrides:
        given = ", ".join(f"{k}={v!r}" for k, v in overrides.items())
        raise ModelError(
            f"spice.run({given}): tolerances and TMAX steer the variable steps; a fixed "
            "step (dt= or steps=) has none. Fix: leave out dt= and steps= for SPICE's "
            "variable steps, or leave these out."
        )
    q0, p0 = netlist.initial_state()  # SPICE's: the operating point unless UIC
    h = dt if dt is not None else netlist.dt
    n = steps
    if n is None and netlist.stop is not None and h is not None:
        n = max(1, math.ceil(netlist.stop / h - 1e-9))  # .tran's TSTOP at the step used
    if h is None or n is None:
        raise ModelError(
            f"netlist {netlist.title!r} has no '.tran TSTEP TSTOP': add one or pass dt= and steps=."
        )
    from ..driver.simulate import simulate  # (here: a variable-step run plans no fixed step)

    if lines(netlist.system):
        return _with_lines(netlist, q0, p0, h, n, discretization, simulate_kwargs)
    traj = simulate(
        netlist.system,
        q0,
        p0,
        dt=h,
        steps=n,
        discretization=discretization,
        **simulate_kwargs,
    )
    return Result(netlist, traj, waveforms(netlist, traj))


def _with_lines(netlist, q0, p0, h, n, discretization, kwargs) -> Result:
    """A fixed-step run of a netlist with transmission lines (:mod:`diracvi.driver.delay`):
    the lines' waves before ``t0`` from the operating point, or from their ``IC=`` under
    ``UIC`` (``w = v + Z₀ i`` per port, as ngspice's ``traload.c`` starts them)."""
    if kwargs:
        raise ModelError(
            f"spice.run({', '.join(sorted(kwargs))}=…): a run with transmission lines takes "
            "no options of diracvi.simulate. Fix: leave them out."
        )
    waves = _line_waves(netlist)
    traj = simulate_lines(
        netlist.system, q0, p0, dt=h, steps=n, waves0=waves, discretization=discretization
    )
    if traj.status != 0:
        raise StepFailure(f"netlist {netlist.title!r}: {traj.message}", traj)
    return Result(netlist, traj, waveforms(netlist, traj))


def operating_point(source) -> OperatingPoint:
    """The DC operating point of a netlist (path, text or :class:`Netlist`): sources at
    t = 0, capacitors open, inductors shorted; ``.ic`` values hold their nodes (as SPICE
    does for a transient without UIC). ``op["v(out)"]``, ``op.q0``, ``op.p0``."""
    netlist = source if isinstance(source, Netlist) else read(source)
    try:
        return _operating_point(netlist, hold=netlist.ic, off=netlist.off)
    except ModelError as exc:
        raise ModelError(f"netlist {netlist.title!r}: {exc}") from None


def controls(netlist: Netlist, settings: TranSettings) -> Controls:
    """Step control for a netlist: ``reltol`` on every signal; branch charges against
    ``chgtol``, their currents against ``abstol``, node potentials (the KCL multipliers)
    against ``vntol``; any other coordinate (a diode's flux linkage ∫V dt) against
    ``vntol`` too (its velocity is a voltage); an inductor's flux (a branch charge's
    nodal momentum) against ``reltol`` of its own peak and its inductance times
    ``abstol``."""
    system = netlist.system
    charges = set(netlist.assembly.currents.values())
    is_charge = np.array([c in charges for c in system.coords])
    hmax = settings.max_step
    atol_q = np.where(is_charge, settings.chgtol, settings.vntol * hmax)
    atol_v = np.where(is_charge, settings.abstol, settings.vntol)
    # a voltage switch's sensing flux is an impulse in disguise (it alternates about its
    # momentum after a change of step size): its control is judged as the node
    # potentials it reads (atol_m), not as a coordinate
    sensing = events.sensing(system)
    atol_q[sensing], atol_v[sensing] = np.inf, np.inf
    # coordinates copying another's velocity are controlled through it (ControlledPart)
    mirrors = {f"{p.name}.{c}" for p in netlist.circuit.parts for c in getattr(p, "mirrors", ())}
    skip = np.array([c in mirrors for c in system.coords])
    atol_q, atol_v = np.where(skip, np.inf, atol_q), np.where(skip, np.inf, atol_v)
    span = settings.stop
    # SPICE's first step: a tenth of min(TSTEP, TSTOP/100) (the control then adapts it)
    h_first = min(settings.step, span / 100.0, hmax) / 10.0
    atol_m = np.full(system.m, settings.vntol)  # node potentials (and source voltages)
    # a branch charge's inertia is an inductance (mutual ones off the diagonal): its
    # nodal momentum the inductor's flux, judged as a state as SPICE judges it
    # (step_error.node_momentum_error). Not a junction's flux coordinate, whose inertia
    # is its junction capacitance: behind the junction's series resistance that mode is
    # stiff, the midpoint's amplification -1, its step-doubling difference does not fall
    # with the step (judged, ng_rtlinv's step fell to hmin at 0.16 µs)
    judged = np.flatnonzero(is_charge & ~skip & np.isfinite(atol_v))
    # probed on the system the march steps (packed: one trace per kind of part, where
    # part by part ng_mosamp's 27 MOSFETs were traced one by one, 5.6 → 0.5 CPU s; the
    # packed system is made once per system, and its coordinates are the same)
    mass = inertia(events.packed_unless_switched(system), netlist.q0, 0.0, judged)
    return Controls(
        settings.reltol, atol_q, atol_v, atol_m, hmax, 1e-13 * span, h_first,
        mass if np.any(mass > 0.0) else None,
        # the branch currents (and charges) judged no finer than the round-off of the
        # current laws driving them (driver/roundoff.py; a circuit without one: unused)
        roundoff=is_charge & ~skip & np.isfinite(atol_v),
    )  # fmt: skip


def _event_atol(netlist: Netlist, settings: TranSettings) -> np.ndarray:
    """Per switch, the absolute tolerance of its control: ``vntol`` for a voltage (S),
    ``abstol`` for a current (W)."""
    return np.asarray(
        [
            settings.vntol if relay.impulse else settings.abstol
            for _, relay in relays(netlist.system)
        ]
    )


#: Whether the compiled variable-step loop steps a nonlinear circuit packed (each kind of
#: part traced once, :func:`~diracvi.driver.events.packed_unless_switched`): on. A packed
#: run sums the groups in another order than the part-by-part one, so its step sizes move
#: by round-off and its waveforms differ within the step control's tolerance (1.4e-9 to
#: 4e-5 of peak measured); the 19 corpus decks that take it were re-run on it and keep
#: their statuses (docs/performance.md), and `ng_mosamp`'s 27 transistors compile in a
#: fraction of the time. ``False`` steps the part-by-part system (the tests compare the two).
PACKED_MARCH = True


#: tries allowed per period of the fastest source (:func:`tries_budget`): the FM deck
#: ``ng_v_i_sources_am_ffm`` (450 kHz at most, 28 800 such periods in its 64 ms) takes 133
#: steps a period at its own settings, its node potentials judged per try (3.82 million
#: steps, 2026-12-01); a thousand leaves it seven times that
TRIES_PER_CYCLE = 1000


def tries_budget(settings: TranSettings, cycles: float = 0.0) -> int:
    """How many step tries a variable-step run may take: 10 000, and 10 per TMAX of the
    run (a circuit whose error estimate stalls just below its tolerance at a tiny step —
    a ringing junction — would otherwise creep on for hours; the corpus's diode decks
    take 250 to 600 at their own .tran), and :data:`TRIES_PER_CYCLE` per period of its
    fastest source (``cycles``, :func:`._tran.source_cycles`: a source oscillating faster
    than TMAX sets the run's pace, not TMAX), times ``(1e-3/reltol)^(1/3)`` below SPICE's
    default reltol: the midpoint rule's local error is ``O(h³)``, so a tolerance
    tightened by ``k`` takes ``k^(1/3)`` times the steps (``ng_switch_osc`` at reltol
    1e-5 takes about 14 000 tries besides the aimed ones, its budget 10 500 without). The
    retries that place a switch's flip on its instant are not counted
    (:func:`~diracvi.driver.adaptive.adaptive`: a few per event, thousands in a switched
    ring oscillator). In the compiled loop the count is a base judged by the run's pace
    (:class:`~diracvi.driver.budget.TriesBudget`): a run whose last tries would reach its
    end within :data:`~diracvi.driver.budget.LIMIT` times the count goes on (a switched
    ring oscillator is paced by its events, not by TMAX: ``ng_switch_osc`` needs 1.47
    times its count), a stuck one stops at the count."""
    tighter = max(1.0, (1e-3 / settings.reltol) ** (1.0 / 3.0))
    paced = 10 * math.ceil(settings.stop / settings.max_step) + TRIES_PER_CYCLE * cycles
    return math.ceil(tighter * (10_000 + paced))


#: a stop is called a runaway when the largest node voltage at its end is this many
#: times the largest one over the first nine tenths of the run's time
RUNAWAY = 100.0


#: a run stopped on its budget of tries says the mean size of this many last steps
PACE_STEPS = 1000


def _runaway(netlist: Netlist, march) -> str | None:
    """What to say when a run stops because its solution runs away: the node voltages at
    the stop far above anything before (a finite-time blow-up such as ``dv/dt ∝ v³``,
    which no step follows; ngspice runs on into overflow there), or ``None``."""
    if march.mu is None or len(march.h) < 20 or march.mu.size > 5e7:
        return None  # (a streamed or huge run: no signals kept to judge by)
    signals = step_signals(netlist, march)
    columns = [j for j, name in enumerate(signals.names) if name.startswith("v(")]
    if not columns:
        return None
    v = np.abs(signals.values[:, columns])
    centres = march.t[:-1] + 0.5 * march.h  # (the steps crowd in at the stop: judge by time)
    before = centres < 0.9 * march.t[-1]
    if not before.any():
        return None
    early = float(np.max(v[before]))
    last = v[-1]
    j = int(np.argmax(last))
    if not np.isfinite(last[j]) or last[j] <= RUNAWAY * max(early, 1e-300):
        return None
    return (
        f"The solution runs away there: |{signals.names[columns[j]]}| = {last[j]:.3g} V at "
        f"the stop, {last[j] / early:.3g} times the largest node voltage of the run's first "
        "nine tenths (in time) — the circuit's equations blow up in finite time (as dv/dt ∝ v³ "
        "does), which no step size follows. Check the signs and values of its sources "
        "and nonlinear laws (a negative resistance without a limit)."
    )


def _variable(netlist: Netlist, discretization, internal: bool, kwargs, overrides) -> Result:
    if discretization != "midpoint":
        raise ModelError(
            f"discretization={discretization!r}: variable steps are built on the midpoint "
            "rule; pass dt= for a fixed step under another rule."
        )
    if kwargs:
        raise ModelError(
            f"{sorted(kwargs)}: options of a fixed-step run (diracvi.simulate); pass dt= "
            "with them, or leave them out for SPICE's variable steps."
        )
    overrides = dict(overrides)
    step_error = overrides.pop("step_error", DEFAULT_ERROR)
    settings = override(tran_settings(netlist), overrides)
    breaks = breakpoints(netlist.system, 0.0, settings.stop)
    found = lines(netlist.system)
    if found:  # (driver/sparse_lines.py: steps ≤ TD/2, corners one delay later)
        settings = _line_settings(netlist, settings, found, step_error)
        breaks = line_breakpoints(breaks, [f[4] for f in found], 0.0, settings.stop)
    bounds = np.concatenate([[0.0], breaks[(breaks > 0.0) & (breaks < settings.stop)]])
    grid = settings.output_times()
    # the sparse path's recorder: the grid formed while the run steps (._stream)
    least = math.floor(settings.stop / settings.max_step)  # (no step is longer than TMAX)
    stream = StreamRecord(
        netlist, np.append(bounds, settings.stop), grid, keep=internal, least=least
    )
    march = _march(netlist, settings, breaks, stream, step_error)
    if march.status != 0:
        at = march.t[-1]
        runaway = _runaway(netlist, march)
        fix = (
            f" {runaway}"
            if runaway
            else " Fix: a fixed step (dt=…), or looser .options reltol/abstol."
        )
        pace = ""
        if march.status == TOO_MANY and len(march.h):
            # how stuck it is: a creeping run's last steps against what is left
            last = float(np.mean(march.h[-PACE_STEPS:]))
            pace = (
                f" (its last {min(len(march.h), PACE_STEPS)} steps {last:.3g} s on average, "
                f"{(settings.stop - at) / last:.3g} more such steps to TSTOP)"
            )
        raise StepFailure(
            f"netlist {netlist.title!r}: the variable-step run stopped at t = {at:g} after "
            f"{len(march.h)} steps: {march.message}{pace}.{fix}",
            march,
        )
    start = _start_values(netlist)
    if stream.grid_values is not None and not stream.kept:
        # a large circuit: the saved vectors on the grid only, O(n) memory (._stream)
        waves = {name: stream.grid_values[:, j] for j, name in enumerate(stream.names)}
        return Result(netlist, march, _pin_start(waves, grid, start), grid, None, settings)
    if march.modes is not None and march.modes.shape[1]:
        # a switching instant is a corner too: the nodes where a switch's state changes
        changed = np.any(np.diff(march.modes, axis=0) != 0.0, axis=1)
        bounds = np.unique(np.concatenate([bounds, march.t[1:-1][changed]]))
    corners = force_corners(netlist.system)
    if corners is not None and getattr(march, "q", None) is not None:
        # so is a located corner of a part's law (driver/law_corners.py)
        at = corner_nodes(
            corners, march.t, march.q, march.h, settings.reltol,
            controls(netlist, settings).atol_v,
        )  # fmt: skip
        bounds = np.unique(np.concatenate([bounds, march.t[at]]))
    sampler = Sampler(march.t, march.h, np.append(bounds, settings.stop))
    signals = step_signals(netlist, march)

    def pinned(times):
        return lambda waves: _pin_start(waves, times, start)

    # the waveforms at the run's own nodes: computed when first asked for
    nodes = Sampled(signals, sampler, march.t, pinned(march.t))
    inner = Internal(march.t, march.h, nodes)
    centred = (sampler, signals, start)
    if internal:
        return Result(netlist, march, dict(nodes), march.t, inner, settings, centred)
    waves = signals.sample(sampler, grid)
    return Result(netlist, march, _pin_start(waves, grid, start), grid, inner, settings, centred)


def _line_settings(netlist: Netlist, settings: TranSettings, found, step_error):
    """The settings of a variable-step run with transmission lines: TMAX at most half
    the shortest delay (a doubled try's waves are then known before it is solved,
    :mod:`diracvi.driver.sparse_lines`); refused where the lines cannot be carried — the
    compiled loop (junctions, switches) and the truncation error control."""
    names = ", ".join(f[0] for f in found)
    least = min(f[4] for f in found)
    fix = f"Fix: a fixed step (dt=, --dt) no longer than the shortest delay, {least:g} s."
    if relays(netlist.system) or junctions(netlist.system) is not None:
        raise ModelError(
            f"netlist {netlist.title!r}: transmission lines ({names}) on variable steps are "
            "carried by the linear circuits' loop only; this circuit has junctions or "
            f"switches, whose loop does not carry their waves yet. {fix}"
        )
    if step_error != "doubling":
        raise ModelError(
            f"netlist {netlist.title!r}: transmission lines ({names}) are stepped with "
            f"step_error='doubling' only (their waves are recorded from each accepted "
            f"try's two halves), not {step_error!r}. Fix: leave step_error out."
        )
    limit = line_hmax([f[4] for f in found])
    if settings.max_step > limit:
        settings = replace(settings, tmax=limit)
    return settings


def _line_waves(netlist: Netlist) -> np.ndarray:
    """The lines' outgoing waves before ``t0`` (``(lines, 2)``): from the operating
    point, or from their ``IC=`` under ``UIC`` (``w = v + Z₀ i`` per port, as ngspice's
    ``traload.c`` starts them)."""
    if not netlist.uic:
        return netlist.operating_point().waves
    waves = []
    for name, *_ in lines(netlist.system):
        part = next(s for s in netlist.system.subsystems if s.name == name)
        v = dict(part.parameters)
        waves.append([v["v1"] + v["z0"] * v["i1"], v["v2"] + v["z0"] * v["i2"]])
    return np.asarray(waves, dtype=np.float64)


def _start_values(netlist: Netlist) -> dict[str, float]:
    """The waveforms' values at t = 0 as SPICE reports them: without ``UIC``, the DC
    operating point's node voltages and branch currents. Where a source's derivative
    jumps at t = 0 (a PULSE rising from TD = 0 through an inductor) the steps' values
    continue to the right limit, and the operating point is the left one; SPICE prints
    the operating point. With ``UIC`` (no operating point) nothing is pinned."""
    op = netlist.operating_point()
    if op is None:
        return {}
    display = netlist.display
    out = {f"v({node})": value for node, value in op.voltages.items()}
    for label, value in op.currents.items():
        out[f"i({display.get(label, label)})"] = value
    return differences(out, netlist.differences)


def _pin_start(waves: dict, times: np.ndarray, start: dict) -> dict:
    """``waves`` with their values at ``times == 0`` replaced by ``start``'s."""
    at0 = np.asarray(times) == 0.0
    if not start or not np.any(at0):
        return waves
    out = {}
    for key, values in waves.items():
        if key in start:
            values = np.array(values, dtype=np.float64)
            values[at0] = start[key]
        out[key] = values
    return out


#: a linear circuit of at least this many coordinates takes the sparse maps. Measured
#: (CPU seconds, fresh process with the disk cache warm, then a second run in it): a
#: series RLC with a pulse train (4 coordinates) 1.92 / 0.31 s sparse against 1.44 /
#: 0.045 s in the compiled loop (whose steps are unrounded: 844 against 1162); a
#: 10-stage ladder (31 coordinates) 1.80 / 0.57 s sparse against 2.46 / 0.93 s compiled,
#: and the compiled loop's dense Newton grows as n³ from there
SPARSE_MIN_COORDINATES = 16


def _march(
    netlist: Netlist,
    settings: TranSettings,
    breaks: np.ndarray,
    record=None,
    step_error: str = DEFAULT_ERROR,
):
    """The variable-step run: a linear circuit on the sparse step maps
    (:mod:`diracvi.driver.adaptive_sparse`: O(n) per step, and in memory with a
    streaming ``record``, :class:`._stream.StreamRecord`), any other —
    nonlinear, with switches, or refused by the sparse path — in the compiled loop
    (:mod:`diracvi.driver.adaptive`); ``march.solver`` says which ran."""
    system = netlist.system
    ctl = controls(netlist, settings)
    budget = tries_budget(settings, cycles=source_cycles(system, 0.0, settings.stop))
    has_junctions = junctions(system) is not None
    # transmission lines: their waves are carried by the sparse loop alone (at any size)
    with_lines = bool(lines(system))
    # junctions (diodes, transistors) are nonlinear: not worth the sparse path's probes
    linear_candidate = (
        isinstance(system, InterconnectedSystem)
        and (system.n >= SPARSE_MIN_COORDINATES or with_lines)
        and not relays(system)
        and not has_junctions
    )
    if linear_candidate:
        try:
            march, _ = adaptive_sparse(
                system._packed(), netlist.q0, netlist.p0, t0=0.0, t_stop=settings.stop,
                controls=ctl, breakpoints=breaks, max_tries=budget, record=record,
                error=step_error, waves0=_line_waves(netlist) if with_lines else None,
            )  # fmt: skip
            return march
        except NotSparseAffine as exc:
            if with_lines:  # (the compiled loop does not carry the lines' waves)
                least = min(f[4] for f in lines(system))
                raise ModelError(
                    f"netlist {netlist.title!r}: its transmission lines are carried on "
                    f"variable steps by the linear circuits' sparse loop only, which refused "
                    f"this circuit ({exc}). Fix: a fixed step (dt=, --dt) no longer than "
                    f"the shortest delay, {least:g} s."
                ) from None
            if record is not None:
                record.grid_values = None  # (its rows, if any, were not a finished run)
            # not linear (or not verified): the compiled loop steps it
    return adaptive(
        events.packed_unless_switched(system) if PACKED_MARCH else system,
        netlist.q0,
        netlist.p0,
        t0=0.0,
        t_stop=settings.stop,
        controls=ctl,
        breakpoints=breaks,
        event_atol=_event_atol(netlist, settings),
        modes=netlist.initial_modes(),
        # judged by the run's pace past its count (driver/budget.py): a ring oscillator's
        # switching events, not TMAX, pace it
        max_tries=TriesBudget(budget),
        pinned=_pinned(netlist),
        # the gap between tries is judged for a junction turning on (driver/adaptive.py);
        # without one, every corner is a breakpoint or a switching instant, which the
        # check skips anyway, and its second-order estimate held a switch ring at
        # reltol 1e-5 to a fifth of the steps its step error allows
        gap_check=has_junctions,
    )


def _pinned(netlist: Netlist) -> np.ndarray:
    """Per coordinate: a behavioural source's ``ddt`` position, re-pinned at each step's
    end by the variable-step loop (its line fixes only its midpoint:
    :mod:`diracvi.driver.pinned`)."""
    names = {f"{p.name}.{c}" for p in netlist.circuit.parts for c in getattr(p, "pinned", ())}
    return np.array([c in names for c in netlist.system.coords], dtype=bool)
