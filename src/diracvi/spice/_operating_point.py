r"""The DC operating point of a circuit: the static solution a transient starts from.

At a static state every acceleration vanishes and every position that enters the
equations stands still. With ``p = ∂L/∂v(q, v)`` the Euler–Lagrange equations of a
circuit's Lagrange–Dirac system then read, at ``t = t₀`` (sources at their initial values),

    (∂p/∂q) v − ∂L/∂q(q, v) − F(q, v, t₀) − C(q, t₀)ᵀ μ = 0      (n equations)
    C(q, t₀) v + b(q, t₀) = 0                                    (every one-form: KCL, sources)
    v_j = 0   for each coordinate j the equations depend on      (capacitor charges …)

in the unknowns ``v`` (the branch currents), ``μ`` (the constraint multipliers: the KCL
ones are the node potentials ``φ``) and the charges ``q_j`` of the position-dependent
coordinates. This is SPICE's DC analysis: a capacitor (``∂L/∂q = −q/C``) carries no
current and takes the charge ``C V``; an inductor (``L = ½ l v²``) has ``V = 0`` and any
current; a resistor and a source are their forces; a diode's flux-linkage velocity is its
junction voltage, its charge velocity the static current ``i_D(V_j)`` (its junction charge
is constant). The coordinates the equations do not depend on (every branch charge but a
capacitor's, a diode's flux) keep their values.

Newton's method solves it, with the junction voltages limited as in a transient step
(:mod:`diracvi.solvers.limiting`). When plain Newton fails, SPICE's homotopies follow:
**gmin stepping** (a conductance ``G`` from every node to ground, ``G = 10⁻³ … 10⁻¹²``,
then 0, each solve starting from the last; a failed solve retreats to a smaller factor,
as ngspice's dynamic gmin stepping does) and **source stepping** (the equations'
source terms — their value at the zero state — scaled by ``s`` from 0 to 1).

``.ic`` node values *hold* their nodes during the operating point (SPICE without UIC):
each held node gets one more unknown, the current that holds it, and the equation
``φ_n = V_ic``; the transient then starts free from that state.

**Switches** (S, W) are resistors whose value is a discrete state. As in ngspice, each
starts in its given state (``ON``, else open); the point is solved, each switch's law is
applied to its control value there, and the point is solved again until no switch
changes (a control inside a hysteresis window keeps the given state).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..driver import delay, events
from ..errors import ModelError
from ..runtime.compile import run_once_jit, stored_loop_jit
from ..solvers.limiting import junctions, limit_rows, start_voltages
from . import _op_jacobian
from ._magnetic import mmf_values


@dataclass(frozen=True)
class OperatingPoint:
    """A DC operating point.

    Attributes:
        q0, p0: the consistent initial state for a transient (capacitor charges at the
            node voltages, inductor and junction currents, junction charges).
        voltages: node -> potential ``φ`` (SPICE's ``v(node)``).
        currents: element label -> branch current (SPICE's ``i(name)``).
        method: ``"newton"``, ``"gmin stepping"`` or ``"source stepping"``.
        iterations: Newton iterations in all.
    """

    q0: np.ndarray
    p0: np.ndarray
    voltages: dict
    currents: dict
    method: str
    iterations: int
    #: the switches' states at the point (1.0 closed), in the order of
    #: :func:`diracvi.driver.events.relays`; empty without switches
    modes: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    #: the transmission lines' outgoing waves ``(w₁, w₂) = v + Z₀ i`` of their ports at
    #: the point, in the order of :func:`diracvi.driver.delay.lines` (empty without lines)
    waves: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 2)))
    #: every coordinate's velocity at the point (branch currents, sensed voltages)
    velocities: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0), repr=False)

    def __getitem__(self, key: str) -> float:
        want = key.replace(" ", "").lower()
        for table in (self.voltages, self.currents):
            for name, value in table.items():
                label = f"v({name})" if table is self.voltages else f"i({name})"
                if label.lower() == want:
                    return value
        raise KeyError(f"{key!r} is not a node voltage or branch current of this circuit")


def _static(system, t, q, v, mu):
    """The static equations' two blocks at ``(q, v, μ)``: the balance of the n
    Euler–Lagrange lines and the one-forms' velocity rows (module docstring)."""
    dp_v = jax.jvp(lambda qq: system.momentum(qq, v, t), (q,), (v,))[1]
    dl_dq = jax.grad(system.lagrangian, argnums=0)(q, v, t)
    force = system.force(q, v, t) if system.has_force else 0.0 * v
    balance = dp_v - dl_dq - force - system.multiplier_force(q, mu, t)
    forms = system.constraint_forms(q, t)
    offset = system.constraint_offset(q, t)
    velocity = forms @ v + (0.0 if offset is None else offset)
    return balance, velocity


def _held_rows(stepped, t, kcl, held, held_values, source, gmin, v, mu, q, hold_i):
    """The static equations at ``(v, μ, q)`` with the held nodes' currents ``hold_i``: the
    balance, the one-forms' rows with ``gmin·μ`` on the KCL rows (the gmin homotopy) and
    the held nodes' currents added, and the held rows ``φ_n − s·V_ic``."""
    balance, velocity = _static(stepped, t, q, v, mu)
    velocity = velocity.at[kcl].add(gmin * mu[kcl])
    velocity = velocity.at[held].add(hold_i)
    fixed = mu[held] - source * held_values
    return jnp.concatenate([balance, velocity, fixed])


def _linearized_fn(system, t, kcl, held, held_values, modes, v, mu, q, hold_i, source, gmin):
    """The static equations at ``(v, μ, q)`` with the held nodes' currents ``hold_i`` and
    the homotopies' ``source`` and ``gmin`` — the balance, the one-forms' rows and the
    held rows ``φ_n − s·V_ic`` — their Jacobians in ``v``, ``μ``, every ``q`` and
    ``hold_i``, and ``p = ∂L/∂v``: one program for the dependence probe (the nonzero
    ``q`` columns) and every Newton iterate (which keeps only those columns)."""
    stepped = events.with_modes(system, modes)

    def equations(v, mu, q, hold_i):
        r = _held_rows(stepped, t, kcl, held, held_values, source, gmin, v, mu, q, hold_i)
        return r, r

    jac, r = jax.jacfwd(equations, argnums=(0, 1, 2, 3), has_aux=True)(v, mu, q, hold_i)
    return r, *jac, stepped.momentum(q, v, t)


# run once or a few times per circuit: compiled without optimization and kept in the
# on-disk store, so a later process loads it untraced (the eager JAX calls it replaces
# compiled a program per operation: ~120 for an RC circuit)
_linearized = run_once_jit(_linearized_fn, "diracvi.spice._operating_point._linearized")
#: the same program with XLA's optimization (the variable-step loop's options; under
#: DIRACVI_FAST_COMPILE=1 the run-once ones, so the same program as above): a point
#: that takes many Newton iterates (gmin or source stepping: 184 on ten level-1
#: inverters) runs it ~10× faster (17.4 → 1.8 ms a call there) for ~1.1 s more to
#: compile (0.53 → 1.67 s). Its numbers differ from the unoptimized program's by an ulp
#: in some entries (175 of 187 calls there, ≤ 2e-16 relative), so which program a call
#: takes must not depend on what the store holds: see ``_Equations._tier``
_linearized_optimized = stored_loop_jit(
    _linearized_fn, "diracvi.spice._operating_point._linearized"
)
#: calls of the unoptimized program after which a point switches to the optimized one.
#: At 17 ms a call against 1.1 s more to compile, the switch pays after ~70 calls;
#: waiting for half that bounds what is lost either way (a point found by plain Newton,
#: in fewer calls, never compiles the optimized one)
OPTIMIZE_AFTER = 32


def _compressed_fn(system, t, kcl, held, held_values, modes, v, mu, q, hold_i, source, gmin, seeds,
                   cotangents):  # fmt: skip
    """The static equations of :func:`_linearized_fn` at ``(v, μ, q, i_hold)``, their
    Jacobian read as :mod:`._op_jacobian` plans: the products ``J s`` for the ``seeds``
    (each a tuple of tangents in ``v``, ``μ``, ``q``, ``i_hold``, stacked) and the rows
    ``cᵀ J`` for the ``cotangents`` (stacked), and ``p = ∂L/∂v``."""
    stepped = events.with_modes(system, modes)

    def equations(v, mu, q, hold_i):
        return _held_rows(stepped, t, kcl, held, held_values, source, gmin, v, mu, q, hold_i)

    r, jvp = jax.linearize(equations, v, mu, q, hold_i)
    jvps = jax.vmap(jvp)(*seeds)
    vjps = jax.vmap(jax.linear_transpose(jvp, v, mu, q, hold_i))(cotangents)
    return r, jvps, vjps, stepped.momentum(q, v, t)


_compressed = run_once_jit(_compressed_fn, "diracvi.spice._operating_point._compressed")


class _Equations:
    """The static equations of ``assembly.system`` at ``t₀`` as functions of ``x``."""

    def __init__(self, assembly, t0: float, hold: dict):
        system = assembly.system
        if any(system.holonomic_mask):
            raise ModelError(
                "operating point: the system has holonomic (position) constraints; the DC "
                "analysis handles circuits (one-forms only). Start it from a given state."
            )
        self.assembly, self.system, self.t0 = assembly, system, np.float64(t0)
        # the equations' program traces each kind of part once (not once per part)
        self.stepped = events.packed_unless_switched(system)
        self.n, self.m = system.n, system.m
        self.q0 = np.asarray(assembly.q0, dtype=np.float64)
        rows = {name: j for j, name in enumerate(system.constraint_names)}
        self.kcl = np.asarray(
            [rows[assembly.kcl_rows[node]] for node in assembly.nodes], dtype=np.int64
        )
        unknown_nodes = sorted(set(hold) - set(assembly.nodes))
        if unknown_nodes:
            raise ModelError(
                f"operating point: .ic names nodes {unknown_nodes} that are not in the circuit "
                f"(nodes: {list(assembly.nodes)})."
            )
        self.held = np.asarray([rows[assembly.kcl_rows[node]] for node in hold], dtype=np.int64)
        self.held_values = np.asarray(list(hold.values()), dtype=np.float64)
        self.calls = 0  # of the static equations' program (._tier)
        self.dep, probes = self._dependent()
        # the Jacobian read through its pattern where that pays (._op_jacobian)
        self.plan = self._plan(probes)
        self.size = self.n + self.m + len(self.dep) + len(self.held)
        found = junctions(self.stepped)
        self.junction_index, self.junction_limits = (
            (np.zeros(0, np.int64), np.zeros((0, 3))) if found is None else
            (found[0], np.asarray(found[1], dtype=np.float64))
        )  # fmt: skip

    def split(self, x):
        n, m, k = self.n, self.m, len(self.dep)
        return x[:n], x[n : n + m], x[n + m : n + m + k], x[n + m + k :]

    def _program(self, modes, v, mu, q, hold_i, source, gmin):
        data = (self.kcl, self.held, self.held_values, np.asarray(modes, np.float64))
        args = (
            self.stepped, self.t0, *data,
            *(np.asarray(a, np.float64) for a in (v, mu, q, hold_i)),
            np.float64(source), np.float64(gmin),
        )  # fmt: skip
        try:
            out = self._tier()(*args)
            return tuple(np.asarray(a) for a in out)
        except jax.errors.JaxRuntimeError as err:
            if "RESOURCE_EXHAUSTED" not in str(err):
                raise
            # the static equations' Jacobian is formed dense, (n + m) × (2n + m): a
            # circuit of ~10⁴ coordinates asks tens of GB (a held-out deck, Xyce's
            # sram.cir, n = 17 472: 61 GB), which the machine refuses
            rows, cols = self.n + self.m + len(self.held), 2 * self.n + self.m + len(self.held)
            raise ModelError(
                f"operating point: out of memory forming the DC analysis's dense Jacobian "
                f"({rows} × {cols}, {8 * rows * cols / 1e9:.1f} GB for the result alone; the "
                f"circuit has {self.n} coordinates and {self.m} constraints). Fix: give the "
                ".tran line UIC (with .ic for the node voltages it should start from) to skip "
                "the DC analysis."
            ) from None

    def _tier(self):
        """The program to call: the optimized one once :data:`OPTIMIZE_AFTER` calls were
        made on the unoptimized one — by the count alone, not by which program is already
        compiled or stored, so that a deck's operating point has the same bits in a first
        process and a later one (the two programs differ by ulps)."""
        self.calls += 1
        return _linearized_optimized if self.calls > OPTIMIZE_AFTER else _linearized

    def _plan(self, probes):
        """The compressed Jacobian's plan (:mod:`._op_jacobian`) from the circuit's
        structure, or ``None`` (dense): also where an entry seen at a probe falls outside
        that structure (a coupling the structure does not know of)."""
        if not probes:
            return None
        mask = _op_jacobian.structural(self.system, self.dep, self.held)
        if mask is None or np.any(_op_jacobian.pattern(probes) & ~mask):
            return None
        return _op_jacobian.plan(mask)

    def _dependent(self):
        """The coordinates whose value enters the static equations (a capacitor's charge):
        nonzero columns of their Jacobian in ``q`` at a generic probe; and, for a circuit
        of :data:`._op_jacobian.MIN_SIZE` unknowns or more, the Jacobian in ``x`` (the
        program's rows) at that probe, to check the structure's pattern (else ``[]``)."""
        modes = events.initial_modes(self.system)
        hold_i = np.zeros(len(self.held))
        rng = np.random.default_rng(0)
        v = rng.standard_normal(self.n)
        mu = rng.standard_normal(self.m)
        q = self.q0 + rng.standard_normal(self.n) * 1e-3
        _, j_v, j_mu, j_q, j_h, _ = self._program(modes, v, mu, q, hold_i, 1.0, 0.0)
        rows = self.n + self.m  # the balance and the one-forms (held rows: φ's)
        dep = np.nonzero(np.any(np.abs(j_q[:rows]) > 0.0, axis=0))[0]
        if self.n + self.m + len(dep) + len(self.held) < _op_jacobian.MIN_SIZE:
            return dep, []
        return dep, [np.concatenate([j_v, j_mu, j_q[:, dep], j_h], axis=1)]

    def linearized(self, modes):
        """``x, source, gmin ↦ (r, ∂r/∂x, q, p)`` as NumPy arrays, the switches in the
        states ``modes`` (data: one compilation serves every state tried):

            r = (balance, one-form rows, v_dep, held rows),  x = (v, μ, q_dep, hold_i)."""
        n, m, dep = self.n, self.m, self.dep
        rows = n + m
        pick = np.zeros((len(dep), n))  # the rows v_j = 0 of the position-dependent j
        pick[np.arange(len(dep)), dep] = 1.0

        if self.plan is not None:
            return self._compressed_call(modes)

        def call(x, source, gmin):
            v, mu, qd, hold_i = self.split(np.asarray(x, np.float64))
            q = self.q0.copy()
            q[dep] = qd
            r, j_v, j_mu, j_q, j_h, p = self._program(modes, v, mu, q, hold_i, source, gmin)
            r = np.concatenate([r[:rows], v[dep], r[rows:]])
            jac = np.block(
                [
                    [j_v[:rows], j_mu[:rows], j_q[:rows][:, dep], j_h[:rows]],
                    [pick, np.zeros((len(dep), m + len(dep) + len(self.held)))],
                    [j_v[rows:], j_mu[rows:], j_q[rows:][:, dep], j_h[rows:]],
                ]
            )
            return r, jac, q, p

        return call

    def _compressed_call(self, modes):
        """:meth:`linearized` with the Jacobian read as :mod:`._op_jacobian` plans and
        assembled sparse (CSC)."""
        n, m, dep, found = self.n, self.m, self.dep, self.plan
        d, h = len(dep), len(self.held)
        rows = n + m
        seeds = found.seeds()
        seeds_q = np.zeros((len(seeds), n))
        seeds_q[:, dep] = seeds[:, n + m : n + m + d]
        tangents = (seeds[:, :n], seeds[:, n : n + m], seeds_q, seeds[:, n + m + d :])
        cotangents = found.cotangents()
        # the program's rows (balance, one-forms, held) → the Jacobian's, the rows
        # v_j = 0 of the position-dependent j between the one-forms and the held rows
        place = np.concatenate([np.arange(rows), rows + d + np.arange(h)])
        pick = (rows + np.arange(d), dep, np.ones(d))
        data = (self.kcl, self.held, self.held_values, np.asarray(modes, np.float64))
        from scipy import sparse  # (scipy is imported at first use)

        def call(x, source, gmin):
            v, mu, qd, hold_i = self.split(np.asarray(x, np.float64))
            q = self.q0.copy()
            q[dep] = qd
            r, jvps, vjps, p = _compressed(
                self.stepped, self.t0, *data,
                *(np.asarray(a, np.float64) for a in (v, mu, q, hold_i)),
                np.float64(source), np.float64(gmin), tangents, cotangents,
            )  # fmt: skip
            r = np.asarray(r)
            vjps = [np.asarray(a) for a in vjps]
            vjps = np.concatenate([vjps[0], vjps[1], vjps[2][:, dep], vjps[3]], axis=1)
            i, j, values = found.assemble(np.asarray(jvps), vjps)
            i = np.concatenate([place[i], pick[0]])
            j = np.concatenate([j, pick[1]])
            values = np.concatenate([values, pick[2]])
            jac = sparse.csc_matrix((values, (i, j)), shape=(self.size, self.size))
            return np.concatenate([r[:rows], v[dep], r[rows:]]), jac, q, np.asarray(p)

        return call

    def start(self, off):
        """The first iterate: every junction at its declared start as SPICE seeds it
        (``V_crit`` forward, a MOSFET's bulk junctions −1 V), except those of the parts
        named in ``off`` (``True``: all), which start at 0 V."""
        x = np.zeros(self.size)
        x[self.n + self.m : self.n + self.m + len(self.dep)] = self.q0[self.dep]
        if len(self.junction_index):
            coords = self.system.coords
            seeded = np.asarray(
                [
                    not (off is True or coords[j].rsplit(".", 1)[0] in (off or ()))
                    for j in self.junction_index
                ]
            )
            start = start_voltages(self.junction_limits)
            x[self.junction_index] = np.where(seeded, start, 0.0)
        return x

    def limit(self, x_old, x_new):
        if not len(self.junction_index):
            return x_new
        j = self.junction_index
        v = limit_rows(x_new[j], x_old[j], self.junction_limits, xp=np)
        x_new = x_new.copy()
        x_new[j] = v
        return x_new


def _newton(eqs, linearized, x, max_iterations=100):
    """Newton with junction limiting; ``(x, converged, iterations)``."""
    polish = 0
    for it in range(1, max_iterations + 1):
        r, jac = linearized(x)
        dense = isinstance(jac, np.ndarray)  # else a large circuit's CSC (._op_jacobian)
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(jac if dense else jac.data))):
            return x, False, it
        try:
            if dense:
                dx = np.linalg.solve(jac, -r)
            else:
                from scipy.sparse.linalg import splu  # (scipy is imported at first use)

                dx = splu(jac).solve(-r)
        except (np.linalg.LinAlgError, RuntimeError):  # (SuperLU: "exactly singular")
            return x, False, it
        if not np.all(np.isfinite(dx)):
            return x, False, it
        x_new = eqs.limit(x, x + dx)
        small = np.max(np.abs(dx)) <= 1e-13 * max(np.max(np.abs(np.asarray(x_new))), 1e-300)
        x = x_new
        if small:  # then two more iterations: quadratic convergence takes every entry
            polish += 1  # to round-off, whatever its size against the largest
            if polish > 2:
                return x, True, it
    return x, False, max_iterations


METHODS = ("newton", "gmin stepping", "source stepping")


def operating_point(
    assembly, *, t0: float = 0.0, hold=None, off=False, methods=METHODS
) -> OperatingPoint:
    """The DC operating point of a circuit (see the module docstring).

    Args:
        assembly: a built circuit (:class:`~diracvi.components.Assembly`, or a
            :class:`~diracvi.spice.Netlist`).
        t0: the time at which the sources are evaluated.
        hold: ``{node: voltage}`` held during the solve (SPICE's ``.ic`` without UIC).
        off: the names of parts whose junctions start off (0 V) instead of at
            ``V_crit`` (SPICE's ``OFF``), or ``True`` for all.
        methods: the methods tried, in order (default SPICE's: Newton, gmin stepping,
            source stepping); a subset forces one (each reaches the same point).

    Raises:
        ModelError: when no method converges, or the static equations are singular (a
            node reached only through capacitors, a loop of inductors and voltage sources).
    """
    mmf = getattr(assembly, "potentials", {})  # a netlist's MMF nodes (._magnetic)
    assembly = getattr(assembly, "assembly", assembly)
    if any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(assembly.system)):
        raise ModelError("operating point: not available under jax transformations; use UIC.")
    if delay.lines(assembly.system):
        return _with_lines(assembly, mmf, t0=t0, hold=hold, off=off, methods=methods)
    return _point(assembly, mmf, t0=t0, hold=hold, off=off, methods=methods)


def _point(assembly, mmf, *, t0, hold, off, methods) -> OperatingPoint:
    """:func:`operating_point` of a built assembly, its lines' sources (if any) as set."""
    found = events.relays(assembly.system)
    modes = events.initial_modes(assembly.system)
    eqs = _Equations(assembly, t0, dict(hold or {}))
    iterations = 0
    for _ in range(2 * len(found) + 2):  # each switch flips at most twice on the way
        op, v = _solve(eqs, eqs.linearized(modes), off, methods)
        iterations += op.iterations
        u = events.static_controls(assembly.system, v)
        new = np.array([float(r.next(modes[j], u[j])) for j, (_, r) in enumerate(found)])
        if np.array_equal(new, modes):
            voltages = {**op.voltages, **mmf_values(op.currents, mmf)}
            return dataclasses.replace(op, voltages=voltages, iterations=iterations, modes=modes)
        modes = new
    raise ModelError(
        "operating point: the switches do not settle (each state found makes another "
        "switch flip); give the initial state with UIC (.tran … uic) and ON/OFF flags."
    )


def _with_lines(assembly, mmf, **options) -> OperatingPoint:
    r"""The operating point of a circuit with lossless lines. At DC a line's ports obey
    ``v₁ − Z₀ i₁ = v₂ + Z₀ i₂`` and ``v₂ − Z₀ i₂ = v₁ + Z₀ i₁`` (ngspice's ``traload.c``
    in DC mode): each port is ``Z₀`` in series with ``e₁ = w₂ = v₂ + Z₀ i₂``, the other
    port's wave *now*. With ``e`` given, the circuit is an ordinary one (the lines' ports
    are ``Z₀`` and a source); ``e`` is then the root of ``R(e) = e − (w₂(e), w₁(e))``,
    ``w = 2 Z₀ i + e``, found by Newton with a difference Jacobian (``R`` is affine in
    ``e`` for a linear circuit: one Newton step). The point at ``e = 0`` is tried first:
    a circuit whose lines carry no DC current is done in one solve."""
    system = assembly.system
    found = delay.lines(system)
    idx = np.array([[f[1], f[2]] for f in found], dtype=np.int64)
    z0 = np.array([f[3] for f in found], dtype=np.float64)[:, None]

    def at(e):
        fixed = dataclasses.replace(assembly, system=delay.with_incident(system, jnp.asarray(e)))
        fixed.__dict__.pop("p0", None)  # (a cached property of the copied assembly)
        op = _point(fixed, mmf, **options)
        i = op.velocities[idx]
        w = 2.0 * z0 * i + e
        return op, w, (e - w[:, ::-1]).ravel()

    e = np.zeros((len(found), 2))
    op, w, r = at(e)
    scale = lambda w: 1e-9 * (1.0 + np.max(np.abs(w)))  # noqa: E731
    iterations = op.iterations
    for _ in range(8):
        if np.max(np.abs(r)) <= scale(w):
            break
        jac = np.empty((r.size, r.size))
        step = 1e-3 * (1.0 + np.max(np.abs(e)))
        for j in range(r.size):
            bumped = e.ravel().copy()
            bumped[j] += step
            jac[:, j] = (at(bumped.reshape(e.shape))[2] - r) / step
        e = e - np.linalg.solve(jac, r).reshape(e.shape)
        op, w, r = at(e)
        iterations += op.iterations
    else:
        raise ModelError(
            "operating point: the transmission lines' DC waves do not settle "
            f"(residual {np.max(np.abs(r)):.3g} V); give the initial state with UIC "
            "(.tran … uic) and the lines' IC=v1,i1,v2,i2."
        )
    return dataclasses.replace(op, iterations=iterations, waves=w)


def _singular(jac) -> bool:
    """Whether ``jac`` is singular once its rows and columns are scaled to unit largest
    entry: the unknowns differ in units by many orders (a MOSFET's Meyer coordinates hold
    ``τ·V`` with ``τ = 10⁻¹²``, their rows read ``y/τ``), and an unscaled rank test calls
    a matrix whose singular values span 10²⁷ singular when it is not."""
    a = np.asarray(jac if isinstance(jac, np.ndarray) else jac.toarray(), dtype=np.float64)
    for axis in (1, 0):
        peak = np.max(np.abs(a), axis=axis, keepdims=True)
        a = a / np.where(peak > 0.0, peak, 1.0)
    return np.linalg.matrix_rank(a) < a.shape[0]


def _gmin_stepping(solve, x0, target=1e-12, factor=10.0):
    """ngspice's dynamic gmin stepping (``cktop.c: dynamic_gmin``): ``G`` from every node
    to ground, from 10⁻³ S down by ``factor`` to ``target``, then 0; each solve starts from
    the last converged point. A failed solve retreats to the last good ``G`` and divides
    it by a smaller factor (``factor ← factor^¼``, until it is below 1.00005); easy solves
    let the factor grow back (to at most 10). ``solve(x, source, gmin) -> (x, ok)``."""
    good, g_good, top, g = x0, None, factor, 1e-2 / factor
    while True:
        x, ok = solve(good, 1.0, g)
        if ok:
            good, g_good = x, g
            if g <= target:
                return solve(good, 1.0, 0.0)
            factor = min(factor * np.sqrt(factor), top)
            g = target if g < factor * target else g / factor
        else:
            if factor < 1.00005:
                return good, False
            factor = np.sqrt(np.sqrt(factor))
            g = (1e-2 if g_good is None else g_good) / factor


def _solve(eqs, linearized, off, methods):
    """The point with the switches in one state: ``(OperatingPoint, branch velocities)``."""
    assembly = eqs.assembly
    zero = linearized(np.zeros(eqs.size), 1.0, 0.0)[0]
    x0 = eqs.start(off)
    total = 0

    def solve(x, source, gmin, iterations=100):
        nonlocal total
        shift = (1.0 - source) * zero  # source stepping: the source terms scaled by s

        def shifted(y):
            r, jac, _, _ = linearized(y, source, gmin)
            return r - shift, jac

        x, ok, it = _newton(eqs, shifted, x, iterations)
        total += it
        return x, ok

    unknown = sorted(set(methods) - set(METHODS))
    if unknown or not methods:
        raise ModelError(f"operating point: methods={methods!r}; choose from {METHODS}.")
    ok, method = False, None
    if "newton" in methods:
        x, ok = solve(x0, 1.0, 0.0)
        method = "newton"
    if not ok and "gmin stepping" in methods:
        method = "gmin stepping"
        # each step gets ngspice's ITL2 (50 iterations), its first solve ITL1 (100)
        x, ok = _gmin_stepping(lambda y, s, g: solve(y, s, g, 50 if g else 100), x0)
    if not ok and "source stepping" in methods:  # the increment shrinks on failure
        method = "source stepping"
        x, s, step = np.zeros(eqs.size), 0.0, 0.1
        ok = True
        while s < 1.0:
            trial = min(1.0, s + step)
            x_try, good = solve(x, trial, 0.0)
            if good:
                x, s, step = x_try, trial, min(2.0 * step, 0.5)
            else:
                step /= 4.0
                if step < 1e-6:
                    ok = False
                    break
    if not ok:
        singular = _singular(linearized(x0, 1.0, 0.0)[1])
        why = (
            "its equations are singular: a node reached only through capacitors or current "
            "sources, or a loop of inductors and voltage sources, has no DC solution"
            if singular
            else "Newton, gmin stepping and source stepping all failed"
        )
        raise ModelError(
            f"operating point of {getattr(assembly.system, 'name', 'the circuit')!r}: {why}. "
            "Fix: add a DC path (a large resistor to ground), or give the initial state "
            "with UIC (.tran … uic) and .ic / IC=."
        )
    v, mu, _, _ = eqs.split(x)
    _, _, q0, p0 = linearized(x, 1.0, 0.0)
    voltages = {node: float(mu[j]) for node, j in zip(assembly.nodes, eqs.kcl, strict=True)}
    index = {c: j for j, c in enumerate(assembly.system.coords)}
    currents = {label: float(v[index[c]]) for label, c in assembly.currents.items()}
    op = OperatingPoint(q0, p0, voltages, currents, method, total, velocities=np.asarray(v))
    return op, np.asarray(v)
