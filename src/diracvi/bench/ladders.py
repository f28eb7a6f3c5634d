"""RLC ladder netlists of any size (issue 30's scaling circuit), shared by the circuit
benchmark, ``benchmarks/ladder_profile.py`` and the tests.

Stage ``k`` is ``R_k n_{k−1} m_k`` (10 Ω), ``L_k m_k n_k`` (1 mH), ``C_k n_k 0`` (1 µF); a
1 kHz sine source drives ``n0``. A stage's resonance (5 kHz) and the source are resolved
by the 1 µs step (``h ω ≈ 0.03``), so the midpoint rule's error is far below 1e-3 of the
peak. ``uic``: every inductor current and capacitor voltage starts at zero (or at ``v0``
on the first capacitor), the state ngspice starts from too, so both integrate the same
initial value problem.
"""

from __future__ import annotations


def ladder(
    stages: int,
    steps: int = 2000,
    dt: float = 1e-6,
    freq: float = 1e3,
    source: bool = True,
    v0: float = 0.0,
) -> str:
    """The netlist text of a ladder of ``stages`` stages, ``.tran dt steps·dt uic``;
    ``source=False``: ``n0`` grounded through a resistor instead (an autonomous circuit,
    started from ``v0`` on the first capacitor)."""
    head = f"V1 n0 0 SIN(0 1 {freq!r})" if source else "R0 n0 0 10"
    lines = [f"RLC ladder of {stages} stages", head]
    for k in range(1, stages + 1):
        ic = f" IC={v0!r}" if k == 1 and v0 else ""
        lines += [f"R{k} n{k - 1} m{k} 10", f"L{k} m{k} n{k} 1m", f"C{k} n{k} 0 1u{ic}"]
    lines += [f".tran {dt!r} {dt * steps!r} uic", ".end", ""]
    return "\n".join(lines)
