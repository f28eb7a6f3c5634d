"""Simulate a netlist: :func:`run` reads, steps and names the results."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..driver.simulate import simulate
from ..errors import ModelError
from ._parse import Netlist, read
from ._probe import to_dataset, waveforms


@dataclass(frozen=True)
class Result:
    """A netlist's transient: the trajectory and its SPICE-named waveforms.

    ``result["v(out)"]``, ``result["i(R1)"]`` are arrays over ``result.time``.
    """

    netlist: Netlist
    trajectory: object
    waveforms: dict

    @property
    def time(self) -> np.ndarray:
        """The time nodes ``t_k``."""
        return self.trajectory.t

    def __getitem__(self, key: str) -> np.ndarray:
        want = key.replace(" ", "").lower()
        for name, values in self.waveforms.items():
            if name.lower() == want:
                return values
        raise KeyError(
            f"{key!r} is not a waveform of this circuit; there are {sorted(self.waveforms)}"
        )

    def to_xarray(self):
        """The trajectory's dataset plus ``v(<node>)``/``i(<element>)`` over ``time``."""
        return to_dataset(self.netlist, self.trajectory)


def run(
    source, *, discretization: str = "midpoint", dt=None, steps=None, **simulate_kwargs
) -> Result:
    """Read a netlist (path, text or :class:`Netlist`) and simulate its ``.tran``.

    ``dt`` overrides ``.tran``'s TSTEP (the run still ends at TSTOP unless ``steps`` is
    given); further keywords go to :func:`diracvi.simulate`.
    Midpoint is the default rule: the left-point rule cannot step a capacitor joined in a
    loop with voltage sources or other capacitors (its step is singular).
    """
    netlist = source if isinstance(source, Netlist) else read(source)
    h = dt if dt is not None else netlist.dt
    n = steps
    if n is None and netlist.stop is not None and h is not None:
        n = max(1, math.ceil(netlist.stop / h - 1e-9))  # .tran's TSTOP at the step used
    if h is None or n is None:
        raise ModelError(
            f"netlist {netlist.title!r} has no '.tran TSTEP TSTOP': add one or pass dt= and steps=."
        )
    traj = simulate(
        netlist.system,
        netlist.q0,
        netlist.p0,
        dt=h,
        steps=n,
        discretization=discretization,
        **simulate_kwargs,
    )
    return Result(netlist, traj, waveforms(netlist, traj))
