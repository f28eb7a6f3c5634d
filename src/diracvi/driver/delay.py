r"""Fixed steps of a circuit with lossless transmission lines: the history they read.

A line (:mod:`diracvi.components.tline`) is two resistive-like ports whose sources are
the other port's outgoing wave ``w = v + Z₀ i`` one delay earlier,
``e₁(t) = w₂(t − T_D)``, ``e₂(t) = w₁(t − T_D)``. This driver carries those waves.

**What is recorded.** Under the midpoint rule a step's port law is
``V = Z₀ Δq/h + e`` at the step's centre ``t_{k+½}`` (the force is evaluated there), so
each step records, per port, its outgoing wave at its centre,
``w_{k+½} = V + Z₀ i = 2 Z₀ Δq/h + e_{k+½}`` — second order in ``h`` like the step.

**What is read.** Step ``k`` needs ``e`` at ``t_{k+½} − T_D``, i.e. at the centre index
``k − T_D/h``: the waves of the centres on either side, linearly interpolated. ngspice
interpolates its node values quadratically (three points, ``traload.c``); here the
recorded values are second-order centre values, and a line through two of them is
second order too and cannot overshoot at a corner of the wave (a PULSE's edge), which a
parabola through three does. With ``h ≤ T_D`` both centres precede the step (the later
one is at most ``k − 1``), so ``e`` is known before the step is solved and the step is
an ordinary discrete Dirac step of a circuit with resistors ``Z₀`` and sources ``e``;
a step longer than ``T_D`` would need its own unknowns' waves and is refused. (ngspice
does not refuse it: past its last stored point its parabola through the last three
extrapolates, ``traload.c``; ``tratrunc.c`` shortens a step only to land one delay
after a point where a port wave's slope changed.) Before ``t0`` each port's wave is its initial one
(``w = v + Z₀ i`` from the DC operating point, or from ``IC=`` under ``UIC``).

**The buffer.** The fixed step reads back at most ``T_D/h + 1`` centres, so a ring of
``⌊max T_D/h⌋ + 2`` waves per port is all the run keeps (``MAX_BUFFER`` refuses a
delay of more steps than that, naming the line and the fix).

The run is one ``lax.scan`` of Newton steps (:class:`~diracvi.solvers.NewtonSolver`),
each on the system with the lines' :class:`~diracvi.components.tline.Incident` leaves
set to the step's ``e`` (one compiled program for every value, as the switches' states
are set in :mod:`diracvi.driver.events`).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..components.tline import Incident
from ..discretization.diagnostics import step_diagnostics
from ..discretization.equations import StepEquations, nodal_momentum
from ..discretization.rules import get_rule
from ..errors import ModelError
from ..runtime.config import ensure_float64
from ..solvers.newton import NewtonSolver
from ..status import SolveStatus
from .leaves import LeavesOf
from .stepping import _newton_step
from .trajectory import Trajectory

#: the most centres a line's ring may hold (``T_D/h`` beyond this is refused)
MAX_BUFFER = 1 << 22


def _is_incident(x) -> bool:
    return isinstance(x, Incident)


#: the lines' :class:`Incident` leaves of a model, in PyTree order (remembered per model
#: object: a model is immutable)
incidents = LeavesOf(_is_incident, interactions=False)


def lines(system) -> tuple[tuple[str, int, int, float, float], ...]:
    """``(name, index of q1, index of q2, Z₀, T_D)`` per line, in the order of
    :func:`incidents`."""
    if not incidents(system):
        return ()
    subsystems = getattr(system, "subsystems", None)
    found = []
    for sub in subsystems if subsystems is not None else (system,):
        prefix = f"{sub.name}." if subsystems is not None else ""
        for inc in incidents.own(sub):
            i1, i2 = (system.coords.index(prefix + c) for c in inc.coordinates)
            found.append((sub.name, i1, i2, inc.z0, inc.delay))
    return tuple(found)


def refuse_variable_steps(system, where: str) -> None:
    """Raise a :class:`~diracvi.errors.ModelError` naming the fix if ``system`` has lines:
    the compiled variable-step loop does not carry their waves (it would hold them at 0;
    the sparse loop does, :mod:`.sparse_lines`)."""
    if incidents(system):
        raise ModelError(
            f"{where}: the system has lossless transmission lines, whose waves this "
            "variable-step loop (the compiled one, for circuits with junctions or "
            "switches) does not carry yet; the linear circuits' loop does "
            "(diracvi.driver.adaptive_sparse with waves0=). Fix: a fixed step no longer "
            "than the shortest delay (diracvi.spice.run(deck, dt=…), "
            "diracvi.driver.delay.simulate_lines)."
        )


def with_incident(system, e):
    """``system`` with its lines' incident sources set to ``e`` (shape ``(lines, 2)``;
    traceable)."""
    found = incidents(system)
    if not found:
        return system
    return eqx.tree_at(
        lambda s: [x.e for x in incidents(s)], system, [e[j] for j in range(len(found))]
    )


def simulate_lines(system, q0, p0, *, dt, steps, waves0, discretization="midpoint", t0=0.0):
    """A fixed-step run of ``system`` (which has lines) from ``(q0, p0)`` at ``t0``:
    ``steps`` steps of ``dt``. ``waves0``: per line, the outgoing waves ``(w₁, w₂)`` of its
    ports before ``t0`` (shape ``(lines, 2)``).

    Returns a :class:`~diracvi.Trajectory` with the lines' record added as
    ``trajectory.line_record = {"names", "z0", "delay", "e", "i"}``: each step's incident
    sources and port currents ``Δq/h``, shape ``(steps, lines, 2)``."""
    ensure_float64()
    found = lines(system)
    if not found:
        raise ModelError("simulate_lines: the system has no transmission lines.")
    h = float(dt)
    if not (math.isfinite(h) and h > 0):
        raise ModelError(f"dt={dt!r}: a finite number of seconds > 0.")
    if discretization != "midpoint":
        raise ModelError(
            f"discretization={discretization!r}: a run with transmission lines records and "
            "reads their waves at the step centres, where the midpoint rule evaluates the "
            "ports' force. Fix: discretization='midpoint' (the default)."
        )
    n_steps = int(steps)
    names = [f[0] for f in found]
    idx = np.array([[f[1], f[2]] for f in found], dtype=np.int64)
    z0 = np.array([f[3] for f in found], dtype=np.float64)
    delay = np.array([f[4] for f in found], dtype=np.float64)
    ratio = delay / h
    for name, r, td in zip(names, ratio, delay, strict=True):
        if r < 1.0 - 1e-9:
            raise ModelError(
                f"transmission line {name!r}: its delay TD = {td:g} s is shorter than the "
                f"step dt = {h:g} s, and a step longer than TD would need its own waves. "
                f"Fix: dt ≤ {td:g}."
            )
        if r > MAX_BUFFER:
            raise ModelError(
                f"transmission line {name!r}: TD/dt = {r:.3g} steps of history exceed the "
                f"{MAX_BUFFER} a line may keep. Fix: a larger dt (TD/{MAX_BUFFER} at least)."
            )
    ring = math.floor(float(ratio.max()) + 1e-9) + 2
    w0 = jnp.asarray(np.broadcast_to(np.asarray(waves0, np.float64), (len(found), 2)))
    rule = get_rule(discretization)
    solver = NewtonSolver()
    q0 = jnp.asarray(q0, jnp.float64)
    p0 = jnp.asarray(p0, jnp.float64)
    zeros = jnp.zeros((len(found), 2))
    rows = jnp.arange(len(found))
    idx_j, z0_j, ratio_j = jnp.asarray(idx), jnp.asarray(z0), jnp.asarray(ratio)

    def run(q0, p0, w0):
        base = with_incident(system, zeros)
        eqs0 = StepEquations(base, rule, "plus", h, q0, p0, t0)
        mu0 = jnp.zeros(system.m)

        def step(carry, k):
            q, p, q_prev, mu_prev, buf, state, failed = carry
            s = k - ratio_j  # the centre index of t_{k+½} − T_D, per line
            j = jnp.floor(s + 1e-9)
            f = jnp.clip(s - j, 0.0, 1.0)

            def at(jj):  # (lines, 2): a recorded centre, or the waves before t0
                jj = jnp.minimum(jj, k - 1).astype(jnp.int64)  # never an unwritten one
                vals = buf[jnp.mod(jj, ring), rows]
                return jnp.where((jj >= 0)[:, None], vals, w0)

            w = (1.0 - f)[:, None] * at(j) + f[:, None] * at(j + 1)
            e = w[:, ::-1]  # e₁ = w₂(t − T_D), e₂ = w₁(t − T_D)
            # an ordinary Newton step of the circuit with the lines' sources set to e
            (q1, p1, q0_, mu1, state1, failed1), out = _newton_step(
                with_incident(system, e), rule, "plus", solver, h,
                (q, p, q_prev, mu_prev, state, failed), t0 + k * h,
            )  # fmt: skip
            s1, s2, mu, its, _, status = out
            i = (s1[idx_j] - q[idx_j]) / h
            buf = buf.at[jnp.mod(k, ring)].set(2.0 * z0_j[:, None] * i + e)
            new = (q1, p1, q0_, mu1, buf, state1, failed1)
            return new, (s1, s2, mu[: system.m], e, i, its, status)

        buf0 = jnp.zeros((ring, len(found), 2))
        init = (q0, p0, q0, mu0, buf0, solver.init(eqs0), jnp.asarray(False))
        _, out = jax.lax.scan(step, init, jnp.arange(n_steps))
        q1s, p1s, mus, es, cur, its, status = out
        diagnostics = step_diagnostics(base, rule, "plus", h)
        q_from = jnp.concatenate([q0[None], q1s[:-1]])
        times = t0 + jnp.arange(n_steps) * h

        def one(a, b, mu, p1, tk, first):
            energy, con = diagnostics(a, b, tk, None)
            return energy, con, nodal_momentum(base, rule, "plus", h, a, mu, p1, tk, first)

        index = jnp.arange(n_steps)
        energy, con, p_node = jax.vmap(one)(q_from, q1s, mus, p1s, times, index == 0)
        return q1s, p1s, mus, es, cur, its, status, energy, con, p_node

    out = jax.jit(run)(q0, p0, w0)
    q1s, p1s, mus, es, cur, its, status, energy, con, p_node = (np.asarray(a) for a in out)
    bad = np.flatnonzero(status != 0)
    taken = n_steps if bad.size == 0 else int(bad[0])
    code = 0 if bad.size == 0 else int(status[taken])
    message = "success"
    if code:
        message = SolveStatus(code).explain(
            step=taken,
            t=t0 + taken * h,
            iterations=int(its[taken]),
            res_norm=float("nan"),
            coords=system.coords,
            q=q1s[taken],
        )
    q = np.concatenate([np.asarray(q0)[None], q1s[:taken]])
    p = np.concatenate([np.asarray(p0)[None], p1s[:taken]])
    traj = Trajectory(
        t=t0 + np.arange(taken + 1) * h,
        q=q,
        p=p,
        p_nodal=np.concatenate([np.asarray(p0)[None], p_node[:taken]]),
        multipliers=mus[:taken],
        energy=energy[:taken],
        constraint_residual=con[:taken],
        newton_iterations=its[:taken],
        coords=system.coords,
        constraint_names=system.constraint_names,
        dt=h,
        scheme="plus",
        discretization=discretization,
        system_name=getattr(system, "name", "system"),
        status=code,
        message=message,
        steps_requested=n_steps,
        solver=f"{solver!r} with {len(found)} transmission line(s)",
    )
    traj.line_record = {
        "names": tuple(names),
        "z0": z0,
        "delay": delay,
        "e": es[:taken],
        "i": cur[:taken],
    }
    return traj


__all__ = [
    "MAX_BUFFER",
    "incidents",
    "lines",
    "refuse_variable_steps",
    "simulate_lines",
    "with_incident",
]
