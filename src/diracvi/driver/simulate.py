r"""``simulate``: march the (+) or (−) discrete Dirac equations with a compiled scan.

One time step solves the implicit step equations (see :mod:`diracvi.discretization.equations`) — by
the precomputed affine step map when they are linear, by a step solver otherwise — then
applies the explicit momentum update. A run is a few compiled chunks
(:mod:`diracvi.driver.stepping`); no Python code runs per step. A failed step freezes the
carry, so everything computed before it is returned intact.
"""

from __future__ import annotations

import math
import weakref
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..discretization.equations import SCHEMES
from ..discretization.rules import RULES, get_rule
from ..errors import ModelError, StepFailure
from ..model.system import DiracSystem
from ..model.validate import (
    CONCRETE_TYPES,
    check_choice,
    check_float,
    check_positive_float,
    check_positive_int,
    check_state,
)
from ..runtime.config import ensure_float64
from ..runtime.store import StoredJit
from ..solvers import StepSolver
from ..solvers.affine import AffineSolver
from ..status import SolveStatus
from . import checkpoint as _checkpoint
from . import delay, events
from .plan import Layout, get_plan, layout
from .record import March, narrowed, run_fields, select_columns, whole_run
from .sparse_run import run_sparse
from .traced import ADJOINTS, check_traced_options, is_traced, simulate_traced
from .trajectory import Trajectory


def simulate(
    system: DiracSystem,
    q0,
    p0,
    *,
    dt,
    steps,
    scheme: str = "plus",
    discretization: str = "retraction",
    t0: float = 0.0,
    solver=None,
    save_every: int = 1,
    save_states: bool = True,
    throw: bool = True,
    checkpoint=None,
    checkpoint_every: int | None = None,
    project_initial: bool = False,
    adjoint: str = "checkpoint",
    keep_stages: bool = False,
    save_only=None,
) -> Trajectory:
    r"""Integrate a Lagrange–Dirac system with a discrete Dirac variational integrator.

    ``scheme="plus"`` marches the (+) equations forward from ``(q0, p0)`` at time
    ``t0``; ``scheme="minus"`` marches the (−) equations backward from it, so ``t``
    decreases. ``discretization`` picks the quadrature rule (``"retraction"``, order 1,
    the paper's; ``"midpoint"``, order 2; or ``"lobatto"``, order 4, Lobatto IIID with
    three stages per step). Step ``j`` covers ``[t_j, t_j + h]`` with
    ``t_j = t0 + j·h`` (``t0 − (j+1)·h`` backward); a driven model (``L``, ``F``, ``A``,
    ``b`` or ``g`` taking ``t``) is evaluated at the rule's time node in it.

    ``p0`` is the momentum at ``t0``. ``traj.p`` holds the scheme's momenta, which under
    the midpoint rule lag the true ones by half of each step's constraint impulse;
    ``traj.p_nodal`` holds momenta at the nodes to the rule's order (see
    :class:`Trajectory`).

    ``solver=None`` chooses the stepping method: the precomputed affine step map when
    the step equations are linear (verified on every step, with a fallback to Newton),
    Newton otherwise. Pass ``dv.NewtonSolver(...)``, ``dv.AffineSolver(...)`` or another
    step solver to choose; ``traj.solver`` says what ran.

    ``save_every=k`` keeps every k-th state (``steps`` must be a multiple of k);
    ``save_states=False`` keeps only the diagnostics (energy, constraint violation,
    iterations per saved interval) and the final state, so a long run of a large model
    needs O(n + steps/k) memory.

    ``keep_stages=True`` (a staged rule such as ``"lobatto"``, every state saved) also
    keeps each step's internal stages and stage multipliers, ``traj.stages`` and
    ``traj.stage_multipliers``: what the stage-by-stage Dirac diagnostic
    ``traj.dirac_residual(system)`` checks (``docs/dirac-structures.md``). Off by
    default: ``s·(n + m)`` more numbers per step.

    ``save_only=names`` (coordinate names from ``system.coords`` and constraint-row
    names from ``system.constraint_names``) keeps of each saved state only ``q`` of the
    named coordinates and ``μ`` of the named rows (``traj.q``, ``traj.multipliers``,
    columns in the order named, ``traj.coords`` / ``traj.constraint_names`` their
    names) and the final state; ``p``, ``p_nodal``, ``constraint_residual``, ``energy``
    and ``constraint_violation`` are ``None``. The values are those of the same run
    without it, bit for bit. On a large linear interconnection (the sparse path) the
    other columns and the per-step energies are never formed: a 1000-stage ladder's
    node voltages alone cost a third of its whole trajectory's time
    (``docs/performance.md``); other paths form every state and cut it. Off
    (``None``) by default: the whole trajectory. A host run's option (not with
    ``save_states=False``, ``keep_stages=True``, ``checkpoint=`` or under a JAX
    transformation).

    Returns a :class:`Trajectory`. If a step fails, raises :class:`StepFailure` carrying the
    partial trajectory (or returns it with ``status != 0`` when ``throw=False``).

    Inconsistent initial data (joined ports at different positions, momenta a degenerate
    Lagrangian does not allow) raise an ``InconsistentInitialDataWarning`` giving the size
    of the violation; ``project_initial=True`` starts from the nearest consistent state.

    ``checkpoint=PATH`` writes the run to PATH (NetCDF, atomically) after every
    ``checkpoint_every`` steps; calling ``simulate`` again with the same arguments resumes
    from the last completed chunk, and the result is bitwise identical to an
    uninterrupted run.

    **Differentiable**: called inside ``jax.jit``, ``jax.grad``, ``jax.jvp``/``jax.jacfwd``
    or ``jax.vmap`` (or with traced ``q0``, ``p0``, ``t0`` or system parameters), the run
    is one pure JAX function and the result a :class:`Trajectory` of JAX arrays (a
    PyTree). Each step is differentiated by the implicit function theorem; ``adjoint``
    chooses the memory of reverse mode: ``"checkpoint"`` (default: each step's solution is
    stored and its linearization recomputed in the backward pass, never its Newton solve)
    or ``"full"`` (every step's intermediates stored).
    ``checkpoint=`` and ``project_initial=True`` are host-only and refused there;
    ``throw=True`` makes a failed step a runtime error (``equinox.error_if``),
    ``throw=False`` reports it in ``traj.status``. See ``docs/gradients.md``.
    """
    key = None
    if save_only is not None:
        check_save_only(save_states, keep_stages, checkpoint)
        save_only = tuple(save_only) if not isinstance(save_only, str) else save_only
    if keep_stages:
        check_keep_stages(discretization, save_every, save_states, checkpoint)
    elif checkpoint is None and solver is None:
        # a warm call of a configuration that ran whole before (see _WarmRun)
        key = (
            id(system),
            type(dt),
            dt,
            type(steps),
            steps,
            scheme,
            discretization,
            type(save_every),
            save_every,
            type(save_states),
            save_states,
            adjoint,
            save_only,
        )
        try:
            warm = _WARM.get(key)
        except TypeError:  # an unhashable argument: the full path says what is wrong
            warm = key = None
        if warm is not None:
            traj = warm(system, q0, p0, t0)
            if traj is not None:
                if save_only is None:
                    return traj
                return narrowed(traj, select_columns(save_only, traj.coords, traj.constraint_names))
    adjoint = check_choice("adjoint", adjoint, ADJOINTS)
    run = check_run(system, scheme, discretization, dt, steps, save_every, solver)
    # the system's own leaves are looked at once per system (its layout), not per call;
    # arguments of plain NumPy / Python types cannot hold a tracer (only the active
    # transformation is then looked up)
    if run.shape.traced or is_traced(*(x for x in (q0, p0, t0) if type(x) not in CONCRETE_TYPES)):
        check_traced_options(checkpoint, project_initial)
        if save_only is not None:
            raise ModelError(
                "save_only= is a host run's option (it cuts the saved arrays on the host); "
                "under jax.jit/grad/vmap pass save_only=None and index traj.q yourself."
            )
        if keep_stages:
            raise ModelError(
                "keep_stages=True is a host run's option (its stages go to the host for the "
                "Dirac diagnostic); under jax.jit/grad/vmap pass keep_stages=False."
            )
        return simulate_traced(
            system,
            q0,
            p0,
            t0,
            run,
            solver,
            save_states=save_states,
            throw=bool(throw),
            adjoint=adjoint,
        )
    h, steps, k, shape = run.h, run.steps, run.save_every, run.shape
    q0 = check_state("q0", q0, shape.n, shape.coords)
    p0 = check_state("p0", p0, shape.n, shape.coords)
    t0 = check_float("t0", t0)
    plan = prepared_plan(system, run, solver, q0, p0, t0)
    # consistent data of a linear model pass with one precomputed product; anything
    # else (and every inconsistent state) goes through the full check
    if not plan.checker.accepts(q0, p0):
        q0, p0 = plan.checker.check(q0, p0, project_initial=bool(project_initial), t0=t0)
    save_states = bool(save_states)
    keep_stages = bool(keep_stages)
    selection = None
    if save_only is not None:
        selection = select_columns(save_only, shape.coords, shape.constraint_names)
    # a large linear interconnection (the sparse path keeps no stages)
    if plan.sparse is not None and checkpoint is None and not keep_stages:
        traj = run_sparse(plan, run, q0, p0, t0, save_states, selection)
        if traj is not None:
            return traj
    first = None
    if checkpoint is None:
        # the whole run is one compiled chunk; a run that took every step is returned
        # directly (the march below handles a failure or an affine fallback)
        affine = plan.step_map is not None
        chunk = plan.chunk(affine, k, save_states, steps // k, stages=keep_stages)
        carry = (q0, p0, q0, np.zeros(shape.m))
        x = chunk.flat_input(h, (t0, 0.0), carry)
        flat = chunk.run(x)
        if flat[chunk.layout.code] == 0:
            fields = run_fields(plan, run)
            if key is not None:
                _remember(key, system, plan, run, chunk, fields)
            traj = whole_run(fields, run, t0, chunk.layout, flat, x)
            return traj if selection is None else narrowed(traj, selection)
        first = affine, chunk.layout.unpack(flat)
    traj = _march(
        plan,
        run,
        system,
        q0,
        p0,
        t0,
        save_states,
        solver,
        checkpoint,
        checkpoint_every,
        first,
        keep_stages,
    )
    if selection is not None:
        traj = narrowed(traj, selection)
    if traj.status and throw:
        raise StepFailure(traj.message, traj)
    return traj


class _WarmRun:
    """A warm call's whole path, for one configuration that ran whole before.

    Everything that depends only on the configuration — the system, scheme, rule, dt,
    steps and saving were accepted, the plan was analysed, the compiled chunk exists, the
    Trajectory's names and labels are known — was settled by that first call; left per
    call are the checks of the values passed now: ``q0``, ``p0`` float64 vectors of the
    right length, ``t0`` a finite float, float64 on and no transformation active (here),
    and the data finite and consistent (inside the chunk's program: its
    :func:`~diracvi.driver.chunk.input_verdict`, one number read back). Anything else
    (another type, a non-finite or inconsistent state, a step that failed or left the
    affine map) returns ``None``, and ``simulate`` takes its full path, which raises and
    warns as always.

    The plan is held weakly: once it leaves the plan cache this path is dead too.
    """

    __slots__ = (
        "_dispatch",
        "_fields",
        "_head",
        "_layout",
        "_plan",
        "_run",
        "_shape",
        "_system",
        "_tail",
        "_verdict",
    )

    def __init__(self, system, plan, run, chunk, fields):
        self._system, self._plan = weakref.ref(system), weakref.ref(plan)
        self._dispatch, self._layout = chunk.dispatch, chunk.layout
        self._head = np.array([run.h, 0.0, 0.0])  # (h, t0, index of the first step)
        # μ of the step before the first (zeros), then the chunk's count of blocks
        self._tail = np.concatenate((np.zeros(run.shape.m), chunk.tail))
        self._shape = (run.shape.n,)
        self._verdict = chunk.layout.verdict
        self._fields, self._run = fields, run

    def __call__(self, system, q0, p0, t0):
        if self._system() is not system or self._plan() is None:
            return None
        ensure_float64()
        if type(t0) is not float or not math.isfinite(t0) or is_traced():
            return None
        shape = self._shape
        # native float64 only (its dtype is a singleton; anything else: the full path)
        if not (
            type(q0) is np.ndarray
            and type(p0) is np.ndarray
            and q0.dtype is _FLOAT64
            and p0.dtype is _FLOAT64
            and q0.shape == shape
            and p0.shape == shape
        ):
            return None
        x = np.concatenate((self._head, q0, p0, q0, self._tail))
        x[1] = t0
        flat = np.asarray(self._dispatch(x))
        # data not finite or inconsistent, or a step that failed: the full path decides
        # (and warns or raises); a NaN verdict fails this test too
        if not flat[self._verdict] <= 1.0:
            return None
        return whole_run(self._fields, self._run, t0, self._layout, flat, x)


_FLOAT64 = np.dtype(np.float64)

#: warm-call paths by (system id, the call's configuration); see _WarmRun
_WARM: dict = {}
_WARM_LIMIT = 64


def _remember(key, system, plan, run, chunk, fields) -> None:
    """Keep the warm path of a whole run that took every step under ``key`` (the call's
    arguments as given). Only for a chunk that judges its own input (a model whose
    initial-data check is one linear test, see :func:`~diracvi.driver.chunk.input_verdict`);
    others keep the full check every call."""
    if chunk.layout.verdict is None or run.shape.traced:
        return
    if len(_WARM) >= _WARM_LIMIT:
        _WARM.clear()
    _WARM[key] = _WarmRun(system, plan, run, chunk, fields)


def _march(
    plan,
    run,
    system,
    q0,
    p0,
    t0,
    save_states,
    solver,
    checkpoint,
    checkpoint_every,
    first,
    keep_stages=False,
) -> Trajectory:
    """Run chunk after chunk: checkpoints, a failed step, the affine map's fallback.
    ``first``: ``(affine, chunk output)`` of the whole run's chunk, already computed."""
    scheme, discretization, h, steps, k, shape = run
    nodal = save_states and plan.nodal_when_saved
    march = March(shape, q0, p0, k, save_states, nodal, keep_stages)
    path, key, chunk = None, None, steps
    if checkpoint is not None:
        chunk = steps if checkpoint_every is None else check_checkpoint_every(checkpoint_every, k)
        path = Path(checkpoint)
        key = _checkpoint.fingerprint(
            system,
            q0,
            p0,
            dt=h,
            steps=steps,
            scheme=scheme,
            discretization=discretization,
            solver=solver,
            chunk=chunk,
            save=(k, save_states),
            t0=t0,
        )
        saved = _checkpoint.read(path, key)
        if saved is not None:
            march.resume(*saved)

    sign = 1.0 if scheme == "plus" else -1.0

    def describe():
        return plan.describe(march.fallback_from, march.fallback_reason)

    while march.done < steps and march.status == 0:
        length = min(chunk - march.done % chunk, steps - march.done)
        affine = plan.step_map is not None and march.fallback_from is None
        if first is not None and first[0] == affine:
            carry, fail, saved = first[1]
        else:
            clock = np.array([t0, march.done], dtype=np.float64)
            chunk_of = plan.chunk(affine, k, march.save_states, length // k, stages=keep_stages)
            carry, fail, saved = chunk_of(plan.h_array, clock, march.carry)
        first = None
        if affine and int(fail[0]) == SolveStatus.AFFINE_REJECTED:
            # the equations are not affine after all: redo this chunk with the fallback
            at = march.done + int(np.argmin(np.asarray(saved["n_good"]) == k)) * k
            march.fallback_from = march.done
            march.fallback_reason = (
                f"the affine step was off by {float(fail[2]):.1e} relative near step {at}"
            )
            continue
        march.extend(carry, fail, saved)
        if path is not None:
            attrs = {}
            if march.fallback_from is not None:
                attrs = {
                    "fallback_from": march.fallback_from,
                    "fallback_reason": march.fallback_reason,
                }
            _checkpoint.write(
                march.trajectory(t0, sign, h, scheme, discretization, steps, describe()),
                path,
                key,
                in_progress=march.status == 0 and march.done < steps,
                extra=attrs,
            )
    return march.trajectory(t0, sign, h, scheme, discretization, steps, describe())


#: classes found to be DiracSystems (an isinstance check of a Module class costs ~1 µs)
_SYSTEM_TYPES: set[type] = set()


def _is_system(system) -> bool:
    if isinstance(system, DiracSystem):
        _SYSTEM_TYPES.add(type(system))
        return True
    return False


class RunArguments(NamedTuple):
    scheme: str
    discretization: str
    h: float
    steps: int
    save_every: int
    shape: Layout


def check_run(system, scheme, discretization, dt, steps, save_every, solver) -> RunArguments:
    """The arguments ``simulate`` and ``simulate_ensemble`` share, checked."""
    ensure_float64()
    if type(system) not in _SYSTEM_TYPES and not _is_system(system):
        raise ModelError(
            f"system={system!r} is not a diracvi system: build one with "
            "dv.LagrangeDiracSystem(...) or dv.interconnect(...)."
        )
    scheme = check_choice("scheme", scheme, SCHEMES)
    discretization = check_choice("discretization", discretization, tuple(RULES))
    if events.relays(system):
        raise ModelError(
            "the system has switches (discrete states, "
            f"{len(events.relays(system))}): a fixed-step run would hold each switch in "
            "its initial state; run it with variable steps, which carry the states and "
            "locate the switching instants (diracvi.spice.run without dt, or "
            "diracvi.driver.adaptive.adaptive)."
        )
    found = delay.lines(system)
    if found:
        raise ModelError(
            f"the system has lossless transmission lines ({', '.join(f[0] for f in found)}): "
            "a plain fixed-step run would hold their incident waves at 0. Fix: "
            "diracvi.driver.delay.simulate_lines(system, q0, p0, dt=…, steps=…, waves0=…), "
            "or diracvi.spice.run(deck, dt=…) for a netlist."
        )
    h = check_positive_float("dt", dt)
    steps = check_positive_int("steps", steps)
    k = check_save_every(steps, save_every)
    check_solver(solver)
    return RunArguments(scheme, discretization, h, steps, k, layout(system))


def prepared_plan(system, run: RunArguments, solver, q0, p0, t0=0.0):
    """The cached plan of this configuration (analysed on first use, see :mod:`._plan`)."""
    return get_plan(system, get_rule(run.discretization), run.scheme, run.h, solver, q0, p0, t0)


def check_save_every(steps: int, save_every) -> int:
    k = check_positive_int("save_every", save_every)
    if steps % k:
        raise ModelError(
            f"save_every={k} does not divide steps={steps}: saved states are every k-th "
            f"step and the last one is the end of the run; choose steps={steps - steps % k + k} "
            f"or a save_every that divides {steps}."
        )
    return k


def check_keep_stages(discretization, save_every, save_states, checkpoint) -> None:
    """``keep_stages=True`` needs a staged rule, every state and no checkpoint file."""
    rule = get_rule(discretization) if discretization in RULES else None
    if rule is not None and not rule.stages:
        raise ModelError(
            f"keep_stages=True: discretization={discretization!r} has no internal stages "
            "(its Dirac diagnostic needs none); pass keep_stages=False, or a staged rule "
            "such as discretization='lobatto'."
        )
    if save_every != 1 or not save_states:
        raise ModelError(
            f"keep_stages=True keeps every step's stages beside its states, but this run "
            f"has save_every={save_every!r}, save_states={save_states!r}: pass save_every=1 "
            "and save_states=True, or keep_stages=False."
        )
    if checkpoint is not None:
        raise ModelError(
            "keep_stages=True is not written to checkpoint files: pass checkpoint=None, or "
            "keep_stages=False (a resumed lobatto run is checked by re-solving its stages)."
        )


def check_save_only(save_states, keep_stages, checkpoint) -> None:
    """``save_only=`` keeps chosen columns of every saved state: states saved, no stages,
    no checkpoint file (which holds a whole run to resume from)."""
    if save_states is not True:
        raise ModelError(
            f"save_only= keeps columns of the saved states, but save_states={save_states!r}: "
            "pass save_states=True (the default) with it, or leave save_only out."
        )
    if keep_stages:
        raise ModelError(
            "save_only= and keep_stages=True: the stages are kept beside whole states. Fix: "
            "pass one of them."
        )
    if checkpoint is not None:
        raise ModelError(
            "save_only= with checkpoint=: a checkpoint file holds the whole run to resume "
            "from. Fix: leave save_only out, or checkpoint=None."
        )


def check_checkpoint_every(checkpoint_every, k: int) -> int:
    every = check_positive_int("checkpoint_every", checkpoint_every)
    if every % k:
        raise ModelError(
            f"checkpoint_every={every} is not a multiple of save_every={k}: a checkpoint "
            f"must end on a saved state; use checkpoint_every={every - every % k + k}."
        )
    return every


def check_solver(solver) -> None:
    if solver is None or isinstance(solver, StepSolver | AffineSolver):
        return
    raise ModelError(
        f"solver={solver!r} is not a diracvi solver: pass None (automatic), "
        "dv.NewtonSolver(...), dv.AffineSolver(...) or dv.PartitionedSolver(...)."
    )


def momenta(system: DiracSystem, q, v, t=0.0):
    r"""Consistent momenta ``p = ∂L/∂v(q, v, t)`` (the continuous Legendre transform)."""
    ensure_float64()
    q = check_state("q", q, system.n, system.coords)
    v = check_state("v", v, system.n, system.coords)
    # t as an array: a Python float would be a static argument, one program per time
    return np.asarray(_momentum(system, q, v, np.float64(check_float("t", t))))


def _momentum_of(system, q, v, t):
    # the system is an argument, not part of a jitted bound method: its parameters
    # (lifted constants included) are arrays, which a static function cannot hash
    return system.momentum(q, v, t)


#: compiled with XLA's defaults, kept in the program store: building a model in a new
#: process (its initial momenta) traces nothing either
_momentum = StoredJit(_momentum_of, "diracvi.driver.simulate._momentum", dict)
