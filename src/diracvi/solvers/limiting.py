r"""Junction-voltage limiting between Newton iterates (SPICE's ``pnjlim``).

An exponential junction ``i = I_S e^{V/(N V_T)}`` turns Newton's linearization into a
poor guide far from the solution: from an iterate where the diode is off, the tangent
line asks for a voltage far beyond the knee, where the exponential is astronomically
large, and the next iterates cycle. SPICE limits how far a junction voltage may move in
one iterate (Nagel's ``pnjlim``): above ``V_crit = nV_T ln(nV_T/(√2 I_S))`` a forward
step ``ΔV`` larger than ``2 nV_T`` is replaced by ``nV_T ln(1 + ΔV/nV_T)`` (the voltage
at which the exponential has moved as much as its tangent asked for), and a reverse step
may not go below ``−V_old − 1`` (``2V_old − 1`` from a reverse voltage). Limiting only
changes the path of the iteration, never its fixed point: the converged step solves the
same equations, and its derivative (implicit function theorem) does not see it.

**How a part declares its junctions** (the solver knows no diode by name): a system may
carry ``junctions`` — a static tuple of coordinate indices whose *velocity* is a junction
voltage (the diode's flux linkage ``w``, whose velocity is ``V_j``) — and
``junction_limits``, an array of shape ``(len(junctions), 3)`` with rows
``(nV_T, V_crit, BV)`` (``BV = inf`` without breakdown), or ``(len(junctions), 5)`` with
two more columns: the junction's polarity ``s`` (its forward voltage is ``s`` times the
coordinate's velocity: a PMOS's bulk junctions are ``s = −1``) and the forward voltage
the operating point's Newton starts it from (SPICE's ``MODEINITJCT``: ``V_crit`` for a
diode, −1 V for a MOSFET's reverse-biased bulk junctions). An interconnection gathers its
members' junctions (:func:`junctions` pads three columns with ``s = 1``, start
``V_crit``, when another member has five).

The discrete velocity of a step is ``v_k = (q_{k+1} − q_k)/h`` under every rule here,
so the junction voltage of an iterate is read from the unknown end ``q_other`` as
``s (q_other − q)/h`` (``s = +1`` for the (+) scheme, ``−1`` for (−)).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def pnjlim(v_new, v_old, nvt, vcrit, xp=jnp):
    """SPICE's ``pnjlim``: the limited junction voltage of a Newton iterate (``xp``:
    ``jax.numpy`` inside a compiled step, ``numpy`` in a host loop)."""
    big = (v_new > vcrit) & (xp.abs(v_new - v_old) > 2.0 * nvt)
    arg = 1.0 + (v_new - v_old) / nvt
    safe_arg = xp.where(arg > 0.0, arg, 1.0)
    from_on = xp.where(arg > 0.0, v_old + nvt * xp.log(safe_arg), vcrit)
    from_off = nvt * xp.log(xp.maximum(v_new, nvt) / nvt)
    forward = xp.where(v_old > 0.0, from_on, from_off)
    floor = xp.where(v_old > 0.0, -v_old - 1.0, 2.0 * v_old - 1.0)
    reverse = xp.where(v_new < 0.0, xp.maximum(v_new, floor), v_new)
    return xp.where(big, forward, reverse)


def limit_junction(v_new, v_old, nvt, vcrit, bv, xp=jnp):
    """``pnjlim`` of the forward junction and, past ``−BV + 10 nV_T``, of the breakdown
    junction (its voltage mirrored about ``−BV``), as ngspice's diode does."""
    forward = pnjlim(v_new, v_old, nvt, vcrit, xp)
    finite_bv = xp.isfinite(bv)
    bv_ = xp.where(finite_bv, bv, 0.0)
    mirrored = -(pnjlim(-(v_new + bv_), -(v_old + bv_), nvt, vcrit, xp) + bv_)
    in_breakdown = finite_bv & (v_new < xp.minimum(0.0, -bv_ + 10.0 * nvt))
    return xp.where(in_breakdown, mirrored, forward)


def limit_rows(v_new, v_old, limits, xp=jnp):
    """:func:`limit_junction` of the coordinates' velocities with :func:`junctions`'s
    ``limits``: with five columns each junction's forward voltage is its polarity times
    the velocity; three columns are the plain case (the same program as before the
    polarity existed)."""
    if limits.shape[1] == 3:
        return limit_junction(v_new, v_old, limits[:, 0], limits[:, 1], limits[:, 2], xp)
    s = limits[:, 3]
    lim = limit_junction(s * v_new, s * v_old, limits[:, 0], limits[:, 1], limits[:, 2], xp)
    return s * lim


def _five(limits, xp=jnp):
    """``(nV_T, V_crit, BV, s, start)`` rows of a part's three- or five-column table."""
    limits = xp.asarray(limits, dtype=float)
    if limits.shape[1] == 5:
        return limits
    return xp.concatenate([limits, xp.ones_like(limits[:, :1]), limits[:, 1:2]], axis=1)


def _tables(limits) -> list:
    """The parts' tables as they are if one is traced (inside a compiled step whose system
    is an argument), else as NumPy arrays: gathered on the host, each eager
    ``jax.numpy`` operation would compile a program per shape once per process (the
    operating point and the march ask for the junctions before their programs)."""
    if any(isinstance(x, jax.core.Tracer) for x in limits):
        return [jnp.asarray(x) for x in limits]
    return [np.asarray(x, dtype=np.float64) for x in limits]


def _xp(tables: list):
    return np if all(isinstance(x, np.ndarray) for x in tables) else jnp


def start_voltages(limits):
    """The forward voltages the operating point starts each junction from (velocities:
    polarity times the start), ``V_crit`` for a three-column table."""
    if limits.shape[1] == 3:
        return limits[:, 1]
    return limits[:, 3] * limits[:, 4]


def junctions(system):
    """``(indices, limits)`` of every junction coordinate of ``system`` (an
    interconnection gathers its members'), or ``None`` when it has none; ``limits`` has
    three columns, or five, ``(nV_T, V_crit, BV, polarity, start)``, when any part
    declares those (module docstring)."""
    # the methods are read from the class: read from a Module instance, equinox binds
    # them as PyTrees, checking every leaf of the system (≈ 0.5 s for a 3001-part netlist)
    members = getattr(type(system), "_members", None)
    if members is None:
        found = tuple(getattr(system, "junctions", ()) or ())
        if not found:
            return None
        return np.asarray(found, dtype=np.int64), _tables([system.junction_limits])[0]
    kinds = type(system)._kinds(system)
    if not any(getattr(k, "junctions", ()) for k in kinds):
        return None
    if getattr(system, "_packing", None) is not None:
        return _packed_junctions(system, kinds)
    index, limits = [], []
    for offset, sub in zip(system._offsets[:-1], members(system), strict=True):
        own = getattr(sub, "junctions", ()) or ()
        if own:
            index += [int(offset) + int(j) for j in own]
            limits.append(sub.junction_limits)
    limits = _tables(limits)
    xp = _xp(limits)
    if any(x.shape[1] == 5 for x in limits):
        limits = [_five(x, xp) for x in limits]
    return np.asarray(index, dtype=np.int64), xp.concatenate(limits, axis=0)


def _packed_junctions(system, kinds):
    """:func:`junctions` of a packed interconnection, group by group: a group's tables
    are its stacked ``junction_limits`` (G, J, columns) read as G·J rows, its indices the
    members' offsets plus the kind's own junctions. Slicing each member out of the stacks
    instead put every parameter of every part into the step program (a chain of N
    inverters: ~100 slices per transistor, the program growing with N). The rows are put
    back in subsystem order (one constant gather), as the unpacked system lists them."""
    packing = system._packing
    offsets = np.asarray(system._offsets[:-1], dtype=np.int64)
    index, limits = [], []
    for g, (kind, members) in enumerate(zip(kinds, packing.tables.members, strict=True)):
        own = np.asarray(getattr(kind, "junctions", ()) or (), dtype=np.int64)
        if not own.size:
            continue
        index.append((offsets[members][:, None] + own[None, :]).reshape(-1))
        stacked = getattr(packing.stacks[g], "junction_limits", None)
        if stacked is None:  # not an array leaf: one table shared by the whole group
            (shared,) = _tables([packing.tables.rests[g].junction_limits])
            stacked = _xp([shared]).broadcast_to(shared, (len(members), *shared.shape))
        (stacked,) = _tables([stacked])
        limits.append(stacked.reshape(-1, stacked.shape[-1]))
    xp = _xp(limits)
    if any(x.shape[1] == 5 for x in limits):
        limits = [_five(x, xp) for x in limits]
    index = np.concatenate(index)
    order = np.argsort(index, kind="stable")
    limits = xp.concatenate(limits, axis=0)
    if not np.array_equal(order, np.arange(len(order))):
        limits = limits[order]
    return index[order], limits


def junction_limiter(eqs):
    """``limit(x, x_new)`` for the step equations ``eqs``, or ``None`` without junctions."""
    found = junctions(eqs.system)
    if found is None:
        return None
    index, limits = found
    if not isinstance(limits, np.ndarray):  # (NumPy tables carry no derivative)
        limits = jax.lax.stop_gradient(limits)
    sign = 1.0 if eqs.scheme == "plus" else -1.0
    known = eqs.q[index]

    def limit(x, x_new):
        v_old = sign * (x[index] - known) / eqs.h
        v_new = sign * (x_new[index] - known) / eqs.h
        v = limit_rows(v_new, v_old, limits)
        return x_new.at[index].set(known + sign * eqs.h * v)

    return limit
