"""RLC ladder netlists of any size (issue 30's scaling circuit), shared by the circuit
benchmark, ``benchmarks/ladder_profile.py`` and the tests.

Stage ``k`` is ``R_k n_{k−1} m_k``, ``L_k m_k n_k``, ``C_k n_k 0``; a sine source drives
``n0``. ``uic``: every inductor current and capacitor voltage starts at zero, the state
ngspice starts from too, so both integrate the same initial value problem.
"""

from __future__ import annotations


def ladder(stages: int, steps: int = 2000, dt: float = 1e-6, freq: float = 10e3) -> str:
    """The netlist text of a ladder of ``stages`` stages, ``.tran dt steps·dt uic``."""
    lines = [f"RLC ladder of {stages} stages", f"V1 n0 0 SIN(0 1 {freq!r})"]
    for k in range(1, stages + 1):
        lines += [f"R{k} n{k - 1} m{k} 1", f"L{k} m{k} n{k} 1u", f"C{k} n{k} 0 1u"]
    lines += [f".tran {dt!r} {dt * steps!r} uic", ".end", ""]
    return "\n".join(lines)
