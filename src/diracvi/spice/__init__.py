"""A SPICE netlist front end: ``read`` a netlist into a circuit of parts, ``run`` its ``.tran``.

from diracvi import spice
result = spice.run("rc.cir")                 # path or text; SPICE's .tran semantics
result["v(out)"], result["i(R1)"], result.time   # every TSTEP from TSTART
spice.run("rc.cir", dt=1e-6)                 # a fixed step to TSTOP
"""

from ._parse import Netlist, NetlistError, read
from ._probe import to_dataset, waveforms
from ._raw import write_raw
from ._run import Result, operating_point, run

__all__ = [
    "Netlist",
    "NetlistError",
    "Result",
    "operating_point",
    "read",
    "run",
    "to_dataset",
    "waveforms",
    "write_raw",
]
