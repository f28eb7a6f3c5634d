r"""SPICE's ``.tran`` settings and ``.options`` tolerances, and a netlist's breakpoints.

``.tran TSTEP TSTOP [TSTART [TMAX]] [UIC]``: TSTEP is the *output* interval, TSTOP the
end, TSTART the first output time (the run itself starts at 0), TMAX the largest step
(default ``min(TSTEP, (TSTOP − TSTART)/50)``, ngspice's rule). ``.options`` gives the
tolerances the step control meets (SPICE's names and defaults): ``reltol`` 1e-3,
``abstol`` 1e-12 A, ``vntol`` 1e-6 V, ``chgtol`` 1e-14 C, ``trtol`` 7 (read, and
reported; the step-doubling estimate needs no safety factor for an over-estimating
truncation error, which is what SPICE's ``trtol`` is).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._parse import NetlistError, _logical_lines, _split
from ._values import ExpressionError, evaluate, number

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
    """The :class:`TranSettings` of a read netlist (``.tran`` and ``.options`` lines of
    its text; ``netlist.start``/``netlist.tmax`` when the reader provides them)."""
    if netlist.dt is None or netlist.stop is None:
        raise NetlistError(
            f"netlist {netlist.title!r} has no '.tran TSTEP TSTOP': add one or pass dt=."
        )
    start = getattr(netlist, "start", None)
    tmax = getattr(netlist, "tmax", None)
    options: dict[str, float] = {}
    text = getattr(netlist, "text", "")
    lines = _logical_lines(text)[1] if text else []
    for line in lines:
        card = line.text.split()[0].lower()
        if card == ".tran" and (start is None or tmax is None):
            pos, _ = _split(line)
            args = [t for t in pos[1:] if t.lower() != "uic"]
            values = [_value(t, line, netlist.params, ".tran") for t in args[2:4]]
            start = values[0] if start is None and values else start
            tmax = values[1] if tmax is None and len(values) > 1 else tmax
        elif card in (".options", ".option", ".opt"):
            _, kw = _split(line)
            for key, token in kw.items():
                if key in DEFAULT_OPTIONS:
                    x = _value(token, line, netlist.params, f".options {key}")
                    if not x > 0.0:
                        raise line.fail(f".options {key}={token} must be a positive number")
                    options[key] = x
    start = 0.0 if start is None else float(start)
    if not start < netlist.stop:
        raise NetlistError(
            f"'.tran' TSTART={start:g} is not before TSTOP={netlist.stop:g}: output would be "
            "empty; give a TSTART below TSTOP."
        )
    tmax = None if tmax is None or tmax == 0.0 else float(tmax)
    return TranSettings(netlist.dt, netlist.stop, start, tmax, **options)


def _value(token, line, params, what) -> float:
    x = number(token)
    if x is not None:
        return x
    text = token[1:-1] if token[:1] in "{'" else token
    try:
        return evaluate(text, params)
    except ExpressionError as exc:
        raise line.fail(f"{what}: {exc}") from None


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
