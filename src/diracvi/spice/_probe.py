r"""SPICE names for a circuit trajectory: ``v(<node>)`` and ``i(<element>)`` over time.

Node potentials come from the KCL multipliers. The (+) equations put a step's whole
constraint impulse ``B(q_k)ᵀλ_k`` on the ``p_k`` line, so ``λ_k`` is the impulse
``−h φ(t_k)``: ``v(n)_k = −λ_k/h``, first order under the left-point rule and second
order at the nodes under midpoint for ``k ≥ 1``. At ``k = 0`` the midpoint impulse sees
only the half step after ``t₀`` (the given ``p₀`` carries no half step before it), and
there is no multiplier for the last node, so both ends are extrapolated (quadratically,
from their three neighbours).

Branch currents are ``q̇``: the step velocities ``(q_{k+1} − q_k)/h`` sit at the
half-nodes; their average gives the current at ``t_k`` (second order), the ends again
by quadratic extrapolation.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ._magnetic import potentials
from ._save import differences

# quadratic extrapolation to an end node: from nodes 1, 2, 3 steps in, and from the
# half nodes ½, 3/2, 5/2 (Lagrange weights at 0); third order where the ends are smooth
_FROM_NODES = np.array([3.0, -3.0, 1.0])
_FROM_HALVES = np.array([15.0, -10.0, 3.0]) / 8.0


def _end(values, weights: np.ndarray):
    """Extrapolate to the node before ``values[0]`` (fewer than 3 values: the nearest)."""
    if len(values) < 3:
        return values[0]
    return weights @ values[:3]


def waveforms(assembly, traj) -> dict[str, np.ndarray]:
    """``{"v(n1)": …, "i(R1)": …}`` on ``traj.t`` for a circuit built by
    :class:`~diracvi.components.Circuit` (or read by :func:`diracvi.spice.read`).

    ``assembly``: the :class:`~diracvi.components.Assembly` (or a
    :class:`~diracvi.spice.Netlist`); ``traj``: its trajectory (states saved, every step).
    A traced trajectory (inside ``jax.grad``) gives JAX arrays, differentiable.

    A trajectory of chosen columns (``simulate(..., save_only=names)``) gives the
    waveforms of those columns: ``v(node)`` where the node's KCL row
    (``assembly.kcl_rows[node]``) was kept, ``i(element)`` where its charge
    (``assembly.currents[element]``) was — the same values as from the whole run.
    """
    display = getattr(assembly, "display", {})  # a netlist's ngspice names of its parts
    mmf = getattr(assembly, "potentials", {})  # its MMF nodes (spice/_magnetic.py)
    vd = getattr(assembly, "differences", {})  # its .probe vd(…) vectors (spice/_save.py)
    assembly = getattr(assembly, "assembly", assembly)
    if traj.q is None or traj.save_every != 1:
        raise ValueError(
            "waveforms(...) needs every state: simulate with save_states=True, save_every=1."
        )
    xp = jnp if isinstance(traj.q, jax.core.Tracer) else np
    h = traj.dt if xp is jnp else float(traj.dt)
    steps = traj.multipliers.shape[0]
    midpoint = traj.discretization != "retraction"
    if midpoint and steps < 2 and assembly.nodes:
        # the first node voltage is extrapolated from the steps after it: there are none
        raise ModelError(
            f"waveforms(...) needs at least 2 steps to place the node voltages at t0 "
            f"under discretization={traj.discretization!r}, and this run has {steps} "
            f"(dt={float(traj.dt):g}). Fix: a smaller dt (at most half the horizon)."
        )
    # the rows by name once (traj.multiplier looks each up in the list: O(N²) overall)
    row = {name: j for j, name in enumerate(traj.constraint_names)}
    # (all of them for a whole run; a run of chosen columns has those it kept)
    partial = traj.energy is None
    index = {c: j for j, c in enumerate(traj.coords)}
    if xp is np:
        out = _host_signals(assembly, traj, h, midpoint, row, index, display)
    else:
        out = _traced_signals(assembly, traj, h, midpoint, row, index, display, partial)
    if partial:  # an MMF node's potential needs every current of its loop
        mmf = {
            node: terms
            for node, terms in mmf.items()
            if all(f"i({display.get(k, k)})" in out for k, _ in terms)
        }
    return differences(potentials(out, mmf, display), vd)


def _host_signals(assembly, traj, h, midpoint, row, index, display) -> dict:
    """The node voltages and branch currents of a host trajectory, every signal of a
    kind at once: the columns gathered into one ``(signals, times)`` array, the same
    formulas as :func:`_traced_signals` applied to all rows (a large circuit's thousands
    of signals one at a time were ~40 µs each, mostly strided column reads)."""
    out: dict[str, np.ndarray] = {}
    steps = traj.multipliers.shape[0]
    nodes = [n for n in assembly.nodes if assembly.kcl_rows[n] in row]
    if nodes:
        cols = np.array([row[assembly.kcl_rows[n]] for n in nodes], dtype=np.int64)
        inner = -np.asarray(traj.multipliers)[:, cols].T / h  # φ at t_0 … t_{steps-1}
        volts = np.empty((len(nodes), steps + 1))
        volts[:, 1:steps] = inner[:, 1:steps]
        volts[:, 0] = _ends(inner[:, 1:steps], _FROM_NODES) if midpoint else inner[:, 0]
        volts[:, steps] = _ends(volts[:, steps - 1 :: -1], _FROM_NODES)
        out.update(zip([f"v({n})" for n in nodes], volts, strict=True))
    labels = [(label, c) for label, c in assembly.currents.items() if c in index]
    if labels:
        cols = np.array([index[c] for _, c in labels], dtype=np.int64)
        vel = np.diff(np.asarray(traj.q)[:, cols].T, axis=1) / h  # at the half nodes
        cur = np.empty((len(labels), vel.shape[1] + 1))
        cur[:, 1:-1] = 0.5 * (vel[:, 1:] + vel[:, :-1])
        cur[:, 0] = _ends(vel, _FROM_HALVES)
        cur[:, -1] = _ends(vel[:, ::-1], _FROM_HALVES)
        names = [f"i({display.get(label, label)})" for label, _ in labels]
        out.update(zip(names, cur, strict=True))
    return out


def _ends(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """:func:`_end` of every row of ``values``: its extrapolation to the node before
    ``values[:, 0]``, each row's three products summed in :func:`_end`'s order."""
    if values.shape[1] < 3:
        return values[:, 0]
    return (weights[0] * values[:, 0] + weights[1] * values[:, 1]) + weights[2] * values[:, 2]


def _traced_signals(assembly, traj, h, midpoint, row, index, display, partial) -> dict:
    """The node voltages and branch currents one signal at a time, in JAX (a traced
    trajectory: differentiable)."""
    xp = jnp
    steps = traj.multipliers.shape[0]
    out: dict[str, np.ndarray] = {}
    for node in assembly.nodes:
        if partial and assembly.kcl_rows[node] not in row:
            continue
        lam = traj.multipliers[:, row[assembly.kcl_rows[node]]]
        inner = -lam / h  # φ at t_0 … t_{steps-1}
        first = _end(inner[1:steps], _FROM_NODES) if midpoint else inner[0]
        phi = xp.concatenate([xp.stack([first]), inner[1:steps]])
        out[f"v({node})"] = xp.concatenate([phi, xp.stack([_end(phi[::-1], _FROM_NODES)])])
    for label, coord in assembly.currents.items():
        if partial and coord not in index:
            continue
        q = traj.q[:, index[coord]]
        vel = xp.diff(q) / h  # at the half nodes
        mid = 0.5 * (vel[1:] + vel[:-1])
        ends = (_end(vel, _FROM_HALVES), _end(vel[::-1], _FROM_HALVES))
        cur = xp.concatenate([xp.stack([ends[0]]), mid, xp.stack([ends[1]])])
        out[f"i({display.get(label, label)})"] = cur
    return out


def to_dataset(assembly, traj):
    """The trajectory's dataset (:meth:`~diracvi.Trajectory.to_xarray`) with the
    waveforms added as data variables ``v(<node>)`` and ``i(<element>)`` over ``time``."""
    ds = traj.to_xarray()
    # all at once: one assignment per waveform copies the dataset each time (O(N²))
    return ds.assign({key: (("time",), v) for key, v in waveforms(assembly, traj).items()})
