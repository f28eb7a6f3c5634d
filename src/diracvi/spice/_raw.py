r"""ngspice's raw file: :func:`write_raw` writes a transient as ngspice's ``-r`` does.

The format (ngspice's ``raw.c``): a text header ::

    Title: …
    Date: …
    Plotname: Transient Analysis
    Flags: real
    No. Variables: N
    No. Points: K
    Variables:
    \t0\ttime\ttime
    \t1\tv(out)\tvoltage
    …
    Binary:

then, point after point, the N values of each point as 8-byte floats (little-endian,
as ngspice writes them on this kind of machine); or ``Values:`` and one text line per
value (``ascii=True``). The vectors are the saved ones (``netlist.vectors``) under
ngspice's names, so a SPICE user's tools open the file as ngspice's own.
"""

from __future__ import annotations

import time as _time
from pathlib import Path

import numpy as np

from ..errors import ModelError


def write_raw(result, path, *, ascii: bool = False) -> Path:
    """Write ``result`` (a :class:`~diracvi.spice.Result`) to ``path`` as an ngspice raw
    file: time, then the saved vectors (see the module docstring). Returns the path."""
    path = Path(path)
    if not path.parent.exists():
        raise ModelError(
            f"write_raw(..., {str(path)!r}): folder {str(path.parent)!r} does not exist."
        )
    names = list(result.keys())
    columns = [np.asarray(result.time, dtype=float)]
    columns += [np.asarray(result[name], dtype=float) for name in names]
    data = np.column_stack(columns)
    kinds = ["time"] + ["current" if n.startswith("i(") else "voltage" for n in names]
    title = " ".join(str(result.netlist.title).split())
    header = [
        f"Title: {title}",
        f"Date: {_time.strftime('%a %b %d %H:%M:%S  %Y')}",
        "Plotname: Transient Analysis",
        "Flags: real",
        f"No. Variables: {data.shape[1]}",
        f"No. Points: {data.shape[0]}",
        "Variables:",
        *(
            f"\t{k}\t{name}\t{kind}"
            for k, (name, kind) in enumerate(zip(["time", *names], kinds, strict=True))
        ),
    ]
    with open(path, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii", errors="replace"))
        if ascii:
            f.write(b"Values:\n")
            for k, row in enumerate(data):
                f.write(f" {k}\t{row[0]:.15e}\n".encode())
                f.write("".join(f"\t{x:.15e}\n" for x in row[1:]).encode())
                f.write(b"\n")
        else:
            f.write(b"Binary:\n")
            f.write(data.astype("<f8").tobytes())
    return path
