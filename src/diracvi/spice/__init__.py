"""A SPICE netlist front end: ``read`` a netlist into a circuit of parts, ``run`` its ``.tran``.

from diracvi import spice
result = spice.run("rc.cir")                 # path or text; .tran gives dt and steps
result["v(out)"], result["i(R1)"], result.time
"""

from ._parse import Netlist, NetlistError, read
from ._probe import to_dataset, waveforms
from ._raw import write_raw
from ._run import Result, run

__all__ = [
    "Netlist",
    "NetlistError",
    "Result",
    "read",
    "run",
    "to_dataset",
    "waveforms",
    "write_raw",
]
