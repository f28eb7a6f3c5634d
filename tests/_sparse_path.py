"""The sparse linear path run directly, as ``spice.run`` runs it (shared by
``test_adaptive_sparse.py`` and ``test_truncation_error.py``)."""

from __future__ import annotations

from diracvi import spice
from diracvi.driver import adaptive_sparse as sparse
from diracvi.spice import _run
from diracvi.spice._tran import breakpoints, tran_settings

#: a series RLC driven by a pulse train: twelve source corners in its run
PULSE_DECK = """Series RLC driven by a pulse train
V1 in 0 PULSE(0 1 10n 5n 5n 100n 300n)
R1 in a 10
L1 a b 1u
C1 b 0 1n
.tran 5n 1u uic
.end
"""


def sparse_run(text, stop=None, error=sparse.DEFAULT_ERROR):
    """``(netlist, settings, breakpoints, AdaptiveRun, SparseRun)`` of the sparse path
    with the error control ``error``, to the deck's TSTOP or to ``stop``."""
    netlist = spice.read(text)
    settings = tran_settings(netlist)
    t_stop = settings.stop if stop is None else stop
    breaks = breakpoints(netlist.system, 0.0, t_stop)
    march, info = sparse.adaptive_sparse(
        netlist.system._packed(), netlist.q0, netlist.p0, t0=0.0, t_stop=t_stop,
        controls=_run.controls(netlist, settings), breakpoints=breaks, error=error,
    )  # fmt: skip
    return netlist, settings, breaks, march, info
