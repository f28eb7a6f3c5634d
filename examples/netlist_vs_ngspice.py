"""A SPICE netlist simulated by diracvi next to ngspice: a half-wave rectifier (a Shockley
diode charging a smoothing capacitor) and a 3-stage RLC ladder.

The ngspice curves are the reference waveforms committed in ``tests/data/ngspice/`` (a
fine ngspice run: maximum step TSTOP/40000, reltol 1e-7), so this runs without ngspice;
with ngspice installed, ``python tests/_ngspice.py`` regenerates them.

Run: python examples/netlist_vs_ngspice.py [figure.png]
"""

# gallery: SPICE netlists against ngspice (rectifier, RLC ladder)

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from _gallery_common import figure_path

from diracvi import spice
from diracvi.spice._ngspice import CIRCUITS

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "ngspice"


def reference(name):
    path = DATA / f"{name}.csv"
    header = path.read_text().splitlines()[0].split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    return data[:, 0], dict(zip(header[1:], data[:, 1:].T, strict=True))


fig, axes = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
for ax, name, probes, dt in (
    (axes[0], "rectifier", ("v(out)",), 1e-5),  # (the tests' step is 2.5e-6, for i(V1))
    (axes[1], "ladder", ("v(b)", "v(d)"), 5e-3),
):
    netlist = CIRCUITS[name][0]
    print(netlist.splitlines()[0])
    result = spice.run(netlist, dt=dt)  # midpoint; .tran gives the horizon
    t_ref, ref = reference(name)
    for k, probe in enumerate(probes):
        ax.plot(result.time, result[probe], color=f"C{k}", lw=1.5, label=f"diracvi {probe}")
        ax.plot(t_ref, ref[probe], "o", color=f"C{k}", ms=3, mfc="none", label=f"ngspice {probe}")
        got = np.interp(t_ref, result.time, result[probe])
        err = np.max(np.abs(got - ref[probe])[1:]) / np.max(np.abs(ref[probe]))
        print(f"  {probe}: max |diracvi − ngspice| / peak = {err:.1e}  (h = {dt:g})")
    ax.set(xlabel="t [s]", ylabel="node voltage [V]", title=netlist.splitlines()[0])
    ax.legend(fontsize=8)
fig.savefig(figure_path("netlist_vs_ngspice.png"), dpi=100)
