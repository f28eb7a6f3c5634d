r"""SPICE's ``.tran`` settings and ``.options`` tolerances, and a netlist's breakpoints.

``.tran TSTEP TSTOP [TSTART [TMAX]] [UIC]``: TSTEP is the *output* interval, TSTOP the
end, TSTART the first output time (the run itself starts at 0), TMAX the largest step
(default ``min(TSTEP, (TSTOP − TSTART)/50)``, ngspice's rule). ``.options`` gives the
tolerances the step control meets (SPICE's names and defaults): ``reltol`` 1e-3,
``abstol`` 1e-12 A, ``vntol`` 1e-6 V, ``chgtol`` 1e-14 C, ``trtol`` 7 (read, and
reported; the step-doubling estimate needs no safety factor for an over-estimating
truncation error, which is what SPICE's ``trtol`` is).

A caller may tighten (or loosen) a deck without editing it: :func:`override` replaces
``reltol``, ``abstol``, ``vntol``, ``chgtol`` and TMAX by the values given
(``spice.run(deck, reltol=1e-5, tmax=1e-9)``, ``diracvi run deck.cir --reltol 1e-5``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from numbers import Real

import numpy as np

from ..errors import ModelError
from ._lines import NetlistError

#: SPICE's defaults of the tolerances used here
DEFAULT_OPTIONS = {"reltol": 1e-3, "abstol": 1e-12, "vntol": 1e-6, "chgtol": 1e-14, "trtol": 7.0}


@dataclass(frozen=True)
class TranSettings:
    """What a netlist's ``.tran`` and ``.options`` ask of a transient run."""

    step: float
    stop: float
    start: float = 0.0
    tmax: float | None = None
    reltol: float = DEFAULT_OPTIONS["reltol"]
    abstol: float = DEFAULT_OPTIONS["abstol"]
    vntol: float = DEFAULT_OPTIONS["vntol"]
    chgtol: float = DEFAULT_OPTIONS["chgtol"]
    trtol: float = DEFAULT_OPTIONS["trtol"]

    @property
    def max_step(self) -> float:
        """TMAX, or ngspice's default ``min(TSTEP, (TSTOP − TSTART)/50)``."""
        if self.tmax is not None and self.tmax > 0.0:
            return self.tmax
        return min(self.step, (self.stop - self.start) / 50.0)

    def output_times(self) -> np.ndarray:
        """``TSTART, TSTART + TSTEP, …`` up to TSTOP, TSTOP included."""
        count = int(np.floor((self.stop - self.start) / self.step * (1.0 + 1e-12)))
        grid = self.start + self.step * np.arange(count + 1)
        if self.stop - grid[-1] > 1e-9 * self.step:
            grid = np.append(grid, self.stop)
        grid[-1] = min(grid[-1], self.stop)
        return grid


def tran_settings(netlist) -> TranSettings:
    """The :class:`TranSettings` of a read netlist: ``.tran``'s TSTART/TMAX
    (``netlist.start``, ``netlist.tmax``) and the ``.options`` tolerances
    (``netlist.options``, checked by the reader to be positive numbers)."""
    if netlist.dt is None or netlist.stop is None:
        raise NetlistError(
            f"netlist {netlist.title!r} has no '.tran TSTEP TSTOP': add one or pass dt=."
        )
    options = {k: float(v) for k, v in netlist.options.items() if k in DEFAULT_OPTIONS}
    tmax = None if netlist.tmax is None or netlist.tmax == 0.0 else float(netlist.tmax)
    return TranSettings(netlist.dt, netlist.stop, float(netlist.start), tmax, **options)


#: what :func:`override` replaces, by SPICE's names (``tmax`` is ``.tran``'s TMAX)
OVERRIDES = ("reltol", "abstol", "vntol", "chgtol", "tmax")


def override(settings: TranSettings, values: dict) -> TranSettings:
    """``settings`` with the tolerances and TMAX of ``values`` (SPICE's names, see
    :data:`OVERRIDES`; ``None`` keeps the deck's) in place of the deck's ``.options`` and
    ``.tran`` TMAX. Each must be a finite number > 0 (the same check the reader makes of
    ``.options``): anything else is refused naming the argument, its value and the fix."""
    given = {}
    for key, value in values.items():
        if value is None:
            continue
        if key not in OVERRIDES:
            raise ModelError(f"{key}=: not a run setting; the ones taken are {OVERRIDES}.")
        ok = isinstance(value, Real) and not isinstance(value, bool)
        if not ok or not math.isfinite(value) or value <= 0.0:
            example = "1e-9 (seconds)" if key == "tmax" else "1e-5"
            raise ModelError(
                f"{key}={value!r}: must be a finite number > 0 (SPICE's "
                f"{'.tran TMAX' if key == 'tmax' else '.options ' + key}); e.g. {key}={example}."
            )
        given[key] = float(value)
    return replace(settings, **given) if given else settings


def source_cycles(system, t_start: float, t_stop: float) -> float:
    """The most periods any source of a circuit runs through in ``[t_start, t_stop]`` at
    its fastest instantaneous frequency (:meth:`~diracvi.components.Waveform.cycles`): an
    FM source of ``FC + MDI·FS`` = 450 kHz over 64 ms, 28 800."""
    parts = getattr(system, "subsystems", (system,))
    return max(
        (wave.cycles(t_start, t_stop) for part in parts for wave in getattr(part, "waveforms", ())),
        default=0.0,
    )


def breakpoints(system, t_start: float, t_stop: float) -> np.ndarray:
    """Every source corner in ``[t_start, t_stop]`` of a circuit's parts (the
    :meth:`~diracvi.components.Waveform.breakpoints` of each part's waveforms), sorted,
    with points closer than ``1e-9 (t_stop − t_start)`` merged (SPICE's smallest
    breakpoint spacing plays the same part)."""
    parts = getattr(system, "subsystems", (system,))
    times = sorted(
        t
        for part in parts
        for wave in getattr(part, "waveforms", ())
        for t in wave.breakpoints(t_start, t_stop)
    )
    merged: list[float] = []
    close = 1e-9 * (t_stop - t_start)
    for t in times:
        if not merged or t - merged[-1] > close:
            merged.append(t)
    return np.asarray(merged, dtype=np.float64)
