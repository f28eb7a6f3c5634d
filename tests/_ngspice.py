"""The validation circuits, ngspice batch runs, and their committed reference CSVs.

``python tests/_ngspice.py`` regenerates ``tests/data/ngspice/*.csv`` (needs ngspice):
each is an ngspice transient with a tiny maximum step (``TSTOP/40000``) and tight
tolerances, sampled on ``POINTS`` uniform times by linear interpolation (its error,
``(TSTOP/40000)²·|f''|/8``, is far below the comparison tolerance).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diracvi.spice._ngspice import CIRCUITS, available, ngspice  # noqa: F401  (re-exported)

DATA = Path(__file__).parent / "data" / "ngspice"
POINTS = 101


def reference(name: str):
    """A fine ngspice run of ``CIRCUITS[name]`` on ``POINTS`` uniform times."""
    netlist, probes, _ = CIRCUITS[name]
    stop = _stop(netlist)
    t, values = ngspice(netlist, probes, tmax=stop / 40000)
    grid = np.linspace(0.0, stop, POINTS)
    return grid, {p: np.interp(grid, t, v) for p, v in values.items()}


def _stop(netlist: str) -> float:
    from diracvi.spice import read

    return read(netlist).stop


def load(name: str):
    """The committed reference ``(t, {probe: values})`` of ``CIRCUITS[name]``."""
    data = np.loadtxt(DATA / f"{name}.csv", delimiter=",", skiprows=1, ndmin=2)
    header = (DATA / f"{name}.csv").read_text().splitlines()[0].split(",")
    return data[:, 0], {p: data[:, 1 + j] for j, p in enumerate(header[1:])}


def write(name: str) -> Path:
    """Regenerate ``tests/data/ngspice/<name>.csv`` from a fine ngspice run."""
    grid, values = reference(name)
    DATA.mkdir(parents=True, exist_ok=True)
    path = DATA / f"{name}.csv"
    cols = np.column_stack([grid, *values.values()])
    np.savetxt(
        path, cols, delimiter=",", fmt="%.10g", header=",".join(["time", *values]), comments=""
    )
    return path


if __name__ == "__main__":
    for circuit in CIRCUITS:
        print("wrote", write(circuit))
