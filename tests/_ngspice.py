"""The validation circuits, ngspice batch runs, and their committed reference CSVs.

``python tests/_ngspice.py`` regenerates ``tests/data/ngspice/*.csv`` (needs ngspice):
each is an ngspice transient with a tiny maximum step (``TSTOP/40000``) and tight
tolerances, sampled on ``POINTS`` uniform times by linear interpolation (its error,
``(TSTOP/40000)²·|f''|/8``, is far below the comparison tolerance).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from diracvi.spice._ngspice import CIRCUITS, available, batch, ngspice  # noqa: F401  (re-exported)

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


def fine_transient(netlist: str, probes, points: int = 20000):
    """ngspice's transient of ``netlist`` at fine settings (``OPTIONS``: reltol 1e-7,
    TMAX = TSTOP/``points``), refusing a run that stopped before TSTOP (ngspice gives up
    with "timestep too small" on some circuits and still writes what it has)."""
    stop = _stop(netlist)
    t, values = ngspice(netlist, probes, tmax=stop / points)
    if t[-1] < stop * (1 - 1e-9):
        raise RuntimeError(f"ngspice stopped at t = {t[-1]:g} of {stop:g}")
    return t, values


def _analysis(line: str) -> bool:
    """A ``.tran`` or ``.op`` line (not ``.options``, which stays in the deck)."""
    return line.lower().split()[:1] in ([".tran"], [".op"])


def operating_point(netlist: str, extra=(), behavior: str | None = None) -> dict:
    """ngspice's ``.op`` of ``netlist`` (its analyses replaced), 15 digits:
    ``{"v(node)": …, "i(source)": …}`` (names lower-case), and the device quantities
    ``extra`` (``"@d1[cd]"``) under their own names. ``behavior`` sets ngspice's
    compatibility mode (``set ngbehavior=…`` in a ``.spiceinit`` beside the deck; ``"psa"``
    reads PSpice's VSWITCH/ISWITCH models)."""
    import subprocess
    import tempfile

    body, _, _ = netlist.rpartition(".end")
    lines = [ln for ln in body.strip().splitlines() if not _analysis(ln)]
    deck = "\n".join(
        [
            *lines,
            ".options reltol=1e-12 abstol=1e-18 vntol=1e-15",
            ".control",
            "set numdgt=15",
            "op",
            "print all",
            *(f"print {x}" for x in extra),
            ".endc",
            ".end",
            "",
        ]
    )
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "deck.cir").write_text(deck)
        if behavior is not None:
            (Path(tmp) / ".spiceinit").write_text(f"set ngbehavior={behavior}\n")
        out = subprocess.run(
            ["ngspice", "-b", "deck.cir"], cwd=tmp, capture_output=True, text=True, timeout=120
        ).stdout
    values = {}
    for line in out.splitlines():
        name, eq, rest = line.partition("=")
        name = name.strip().lower()
        if not eq or not rest.split() or " " in name:
            continue
        try:
            x = float(rest.split()[0])
        except ValueError:
            continue
        key = f"i({name[: -len('#branch')]})" if name.endswith("#branch") else f"v({name})"
        key = name if name.startswith("@") else key
        values[key] = x
    if not values:
        raise RuntimeError(f"ngspice .op gave nothing:\n{out[-2000:]}")
    return values


def dc_sweep(netlist: str, sweep: str, probes):
    """ngspice's ``.dc`` of ``netlist`` (its analyses replaced by ``sweep``, e.g. ``"vd 0 5
    0.5 vg -3 0 0.5"``), 15 digits: ``{probe: values}`` over the sweep's points, the first
    source varying fastest (``"sweep"`` holds its values)."""
    body, _, _ = netlist.rpartition(".end")
    lines = [ln for ln in body.strip().splitlines() if not _analysis(ln)]
    options = ".options reltol=1e-12 abstol=1e-18 vntol=1e-15"
    data = batch(lines, options, f"dc {sweep}", probes, timeout=120)
    return {"sweep": data[:, 0], **{p: data[:, 1 + j] for j, p in enumerate(probes)}}


def netlist_part(netlist: str, name: str):
    """diracvi's part ``name`` of ``netlist`` as the reader builds it."""
    from diracvi import spice

    return next(p for p in spice.read(netlist).circuit.parts if p.name == name)


def device_sweep(netlist: str, part: str, vd, vg, probes, sign: float = 1.0):
    """``(out, part)``: ngspice's :func:`dc_sweep` of ``netlist`` over its sources ``vd``
    and ``vg``, each ``(start, stop, step)`` times ``sign`` (−1 mirrors the sweep for a
    p-type device), and diracvi's part named ``part`` of the same netlist
    (:func:`netlist_part`)."""
    sweep = " ".join(
        f"{source} {a * sign} {b * sign} {h * sign}"
        for source, (a, b, h) in (("vd", vd), ("vg", vg))
    )
    return dc_sweep(netlist, sweep, probes), netlist_part(netlist, part)
