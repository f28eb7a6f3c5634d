"""Simulate a netlist: :func:`run` reads, steps and names the results."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._errors import ModelError
from .._simulate import simulate
from ._parse import Netlist, read
from ._probe import to_dataset, waveforms


@dataclass(frozen=True, eq=False)
class Result(Mapping):
    """A netlist's transient: the trajectory and its SPICE-named waveforms.

    A read-only mapping over the saved vectors (``netlist.vectors``: the ``.save``
    lines, else node voltages and voltage-source and inductor currents), named as
    ngspice names them: ``result["v(out)"]``, ``result["i(v1)"]`` over ``result.time``;
    ``keys()``, ``items()``, ``len``. Any other waveform of the circuit can still be
    asked for by name (``result["i(R1)"]``, ``"i(R1)" in result``); names are
    case-insensitive.
    """

    netlist: Netlist
    trajectory: object
    waveforms: dict

    @property
    def time(self) -> np.ndarray:
        """The time nodes ``t_k``."""
        return self.trajectory.t

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
        raise KeyError(
            f"{key!r} is not a waveform of this circuit; the saved ones are "
            f"{list(self._saved())}, others {sorted(self.waveforms)}"
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
            f"{len(t) - 1} steps of {float(self.trajectory.dt):g} s; vectors {shown}>"
        )

    __str__ = __repr__

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
