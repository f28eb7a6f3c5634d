r"""How a run is stepped, decided once per (system, rule, scheme, dt, solver) and cached.

Every analysis that depends on the configuration and not on the call lives here: the
solver choice, the affine step map, the solvability of the step equations (the step
Jacobian ``J = ∂r/∂(q_other, μ)`` must be invertible), the initial-data checker and the
compiled chunks. ``simulate`` only checks its arguments and marches.

``solver=None`` chooses automatically: the affine step map when the step equations are
linear (checked numerically, see :mod:`diracvi.solvers.affine`), otherwise Newton. A
:class:`Plan` holds that choice, the fallback, and the compiled chunk programs, so a
repeated ``simulate`` call pays one dispatch and no re-analysis. Plans are keyed by the
system's identity and dropped when the system is garbage-collected.
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.diagnostics import GROUPED_MIN_SUBSYSTEMS
from ..discretization.equations import first_guess, residual, unknown_count
from ..errors import ModelError, UnsolvableStepError
from ..model.consistency import Checker
from ..model.interconnect import InterconnectedSystem
from ..runtime.compile import run_once_jit
from ..solvers.affine import SINGULAR, AffineSolver, AffineStepMap, build, build_stacked
from ..solvers.base import StepSolver
from ..solvers.newton import NewtonSolver
from ..solvers.partitioned import PartitionedSolver
from ..solvers.solvability import DENSE_CHECK_LIMIT, check_step_jacobian, singular_members
from ..solvers.sparse_affine import SPARSE_MOMENTUM_CHECK_LIMIT, SparseAffineSolver, sparse_map
from .chunk import CompiledChunk, SizedChunk, capacity
from .stepping import keeps_nodal

_CACHE: OrderedDict = OrderedDict()
_CACHE_SIZE = 32
_LAYOUTS: dict[int, tuple] = {}


def clear_cache() -> None:
    """Forget every plan and compiled chunk (the next call analyses and compiles anew)."""
    _CACHE.clear()
    _LAYOUTS.clear()


class Layout(NamedTuple):
    """The names and sizes of a system (properties that an interconnection recomputes),
    and whether any of its leaves is a JAX tracer (a model built inside a transformation)."""

    coords: tuple[str, ...]
    constraint_names: tuple[str, ...]
    name: str
    traced: bool = False

    @property
    def n(self) -> int:
        return len(self.coords)

    @property
    def m(self) -> int:
        return len(self.constraint_names)


def layout(system) -> Layout:
    hit = _LAYOUTS.get(id(system))
    if hit is not None and hit[0]() is system:
        return hit[1]
    traced = any(isinstance(leaf, jax.core.Tracer) for leaf in jax.tree.leaves(system))
    info = Layout(system.coords, system.constraint_names, getattr(system, "name", "system"), traced)
    key = id(system)
    _LAYOUTS[key] = (weakref.ref(system, lambda _, c=_LAYOUTS: c.pop(key, None)), info)
    return info


#: interconnections with at least this many unknowns are stepped by the partitioned
#: solver (O(n) per step) instead of a dense affine map or dense Newton (O(n²)–O(n³))
PARTITION_MIN_UNKNOWNS = 256


def default_solver(system, rule, scheme) -> StepSolver:
    """Dense Newton, or the partitioned solver for a large interconnection it applies to."""
    if system.n + system.m >= PARTITION_MIN_UNKNOWNS:
        try:
            PartitionedSolver.check(system, rule, scheme)
        except ModelError:
            return NewtonSolver()
        return PartitionedSolver()
    return NewtonSolver()


def unknown_names(system, scheme, rule=None):
    other = "q_{k+1}" if scheme == "plus" else "q_k"
    names = [f"{other}[{c}]" for c in system.coords] + [f"μ[{c}]" for c in system.constraint_names]
    stages = 0 if rule is None else rule.stages  # a staged rule's stages Q_j, then their ν_j
    for j in range(1, stages + 1):
        names += [f"Q{j}[{c}]" for c in system.coords]
    for j in range(1, stages + 1):
        names += [f"ν{j}[{c}]" for c in system.constraint_names]
    return names


def equation_names(system, rule=None):
    names = [f"momentum balance of {c}" for c in system.coords] + [
        f"constraint {c}" for c in system.constraint_names
    ]
    stages = 0 if rule is None else rule.stages
    for j in range(1, stages + 1):
        names += [f"stage {j} balance of {c}" for c in system.coords]
    for j in range(1, stages + 1):
        names += [f"stage {j} constraint {c}" for c in system.constraint_names]
    return names


@run_once_jit
def _step_jacobian(system, rule, scheme, q0, p0, h, tk):
    x0 = first_guess(system, rule, q0, q0, jnp.zeros(system.m))
    return jax.jacfwd(lambda x: residual(system, rule, scheme, h, q0, p0, x, tk))(x0)


def check_solvable(system, rule, scheme, q0, p0, h, t0=0.0, jacobian=None) -> None:
    """Raise :class:`UnsolvableStepError` if the first step's Jacobian is singular.

    Once per plan: the structural defects the check names (an unconnected massless port,
    a capacitor loop under the left-point rule) do not depend on the initial state; a
    Jacobian that turns singular later is reported by the failing step's status.
    ``jacobian``: that Jacobian, if already formed (the affine probes form it).
    """
    if unknown_count(system, rule) > DENSE_CHECK_LIMIT:
        return
    if jacobian is None:
        # tk as an array: a Python float would be static, one program per start time
        tk = np.float64(t0 if scheme == "plus" else t0 - float(h))
        jacobian = _step_jacobian(system, rule, scheme, q0, p0, h, tk)
    jac = np.asarray(jacobian)
    tk = np.float64(t0 if scheme == "plus" else t0 - float(h))

    def x0():  # the Jacobian's point, formed only if it looks singular (eager JAX ops
        # compile small programs: a warm process must trace nothing on a regular step)
        return first_guess(system, rule, q0, q0, jnp.zeros(system.m))

    def jacobian_at(x):  # a near-singularity may be state-dependent (junctions all off)
        return jax.jacfwd(lambda y: residual(system, rule, scheme, h, q0, p0, y, tk))(x)

    check_step_jacobian(
        jac,
        unknown_names=unknown_names(system, scheme, rule),
        equation_names=equation_names(system, rule),
        where=f"the first ({scheme}) step of {getattr(system, 'name', 'the system')!r}",
        jacobian_at=jacobian_at,
        x0=x0,
    )


class Plan:
    """The stepping method of one configuration and its compiled chunks."""

    def __init__(self, system, rule, scheme, h, solver, q0, p0, t0=0.0):
        self.system, self.rule, self.scheme, self.h = system, rule, scheme, h
        self.h_array = np.asarray(h, dtype=np.float64)
        self.step_map: AffineStepMap | None = None
        self.sparse = None  # the circuit-scale sparse affine map, when it applies
        self._packed = None
        first_jacobian = None  # J of the first step, if the affine probes formed it
        if isinstance(solver, StepSolver):
            self.fallback, self.affine_reason = solver, "a step solver was given"
        else:
            options = AffineSolver() if solver is None else solver
            self.fallback = (
                default_solver(system, rule, scheme) if solver is None else options.fallback
            )
            if isinstance(solver, SparseAffineSolver) or (
                solver is None and isinstance(self.fallback, PartitionedSolver)
            ):
                self.sparse, self.affine_reason = sparse_map(
                    self.stepped_system, rule, scheme, h, q0, p0, t0, options
                )
            if self.sparse is not None:
                pass
            elif solver is None and isinstance(self.fallback, PartitionedSolver):
                # a large interconnection: the partitioned solver factorizes once per chunk
                # for linear equations too, at O(n) per step against the dense map's O(n²)
                self.affine_reason = "a large interconnection is stepped by the partitioned solver"
            else:
                self.step_map, self.affine_reason, first_jacobian = build(
                    system, rule, scheme, h, q0, p0, options, t0
                )
            if self.step_map is not None:
                check_step_jacobian(
                    np.asarray(self.step_map.jacobian),
                    unknown_names=unknown_names(system, scheme, rule),
                    equation_names=equation_names(system, rule),
                    where=f"the ({scheme}) step of {getattr(system, 'name', 'the system')!r}",
                )
        # the linear fast path of the initial-data check is verified at q0 before use
        self.fallback.check(system, rule, scheme)  # a solver that cannot apply says why
        if self.step_map is None and self.sparse is None:  # (their builds checked J)
            check_solvable(system, rule, scheme, q0, p0, self.h_array, t0, first_jacobian)
        if self.sparse is None:
            self.checker = Checker(system, linear=True, q_probe=q0, t_probe=t0)
        else:
            # the packed system (its Legendre data traced once per kind of part); the
            # momentum check's dense projector is O(n³): as above MOMENTUM_CHECK_LIMIT,
            # a large circuit's momenta are not checked (ports are)
            self.checker = Checker(
                self.stepped_system, linear=True, q_probe=q0, t_probe=t0,
                momentum_limit=SPARSE_MOMENTUM_CHECK_LIMIT,
            )  # fmt: skip
        # whether a run that saves its states also stores the nodal momenta
        self.nodal_when_saved = keeps_nodal(system, rule, True)
        self._chunks: dict = {}
        self._fallback_name = repr(self.fallback)  # once: a Module's repr takes ~0.1 ms

    def describe(self, fallback_from: int | None = None, reason: str = "") -> str:
        if self.step_map is None:
            return self._fallback_name
        if fallback_from is None:
            return "affine step map"
        return f"affine step map, then {self._fallback_name} from step {fallback_from} ({reason})"

    @property
    def stepped_system(self):
        """The system the compiled chunks step: an interconnection of many subsystems
        packed (``InterconnectedSystem._packed``: alike subsystems' parameters
        stacked once per plan, so the program takes a few arrays per kind of subsystem,
        not a few per subsystem), any other system as it is."""
        if self._packed is None:
            system = self.system
            if (
                isinstance(system, InterconnectedSystem)
                and len(system.subsystems) >= GROUPED_MIN_SUBSYSTEMS
                and not layout(system).traced
            ):
                # through the class: a method read from a Module is bound as a PyTree
                # whose creation flattens the whole system (0.5 s at 10⁴ parts)
                system = InterconnectedSystem._packed(system)
            self._packed = system
        return self._packed

    def chunk(
        self, affine: bool, k: int, save_states: bool, blocks: int, batched=False, stages=False
    ):
        """The compiled chunk of ``blocks`` records of ``k`` steps. Stepped by a solver,
        unbatched: a :class:`SizedChunk` of the program compiled for :func:`capacity`
        blocks, which serves every run of its rung of lengths. The affine map's runs
        keep a program per length: a counted one evaluates its steps' products and
        verification over the whole capacity, and measured 25–50 % slower warm (the
        driven RLC's 1000 steps: 0.24–0.33 → 0.37–0.50 ms), while a linear model's
        program compiles in about a second."""
        if batched or affine:
            return self._compiled(affine, k, save_states, blocks, batched, stages)
        key = (affine, k, save_states, blocks, "sized", stages)
        sized = self._chunks.get(key)
        if sized is None:
            compiled = self._compiled(affine, k, save_states, capacity(blocks), False, stages)
            sized = self._chunks[key] = SizedChunk(compiled, blocks)
        return sized

    def _compiled(self, affine, k, save_states, blocks, batched, stages):
        key = (affine, k, save_states, blocks, batched, stages)
        if key not in self._chunks:
            method = self.step_map if affine else self.fallback
            system = self.system if affine else self.stepped_system
            # the initial-data check's linear test: an unbatched chunk judges its input by
            # it, for the warm path of simulate (see chunk.input_verdict)
            guard = self.checker.quick_test()
            self._chunks[key] = CompiledChunk(
                system,
                self.rule,
                self.scheme,
                method,
                k,
                save_states,
                blocks,
                batched,
                guard,
                keep_stages=stages,
                counted=not (batched or affine),
            )
        return self._chunks[key]


def get_plan(system, rule, scheme, h, solver, q0, p0, t0=0.0) -> Plan:
    try:
        key = (id(system), rule.name, scheme, h, solver)
        hash(key)
    except TypeError:  # an unhashable solver: no caching
        return Plan(system, rule, scheme, h, solver, q0, p0, t0)
    hit = _CACHE.get(key)
    if hit is not None and hit[0]() is system:
        _CACHE.move_to_end(key)
        return hit[1]
    plan = Plan(system, rule, scheme, h, solver, q0, p0, t0)
    _CACHE[key] = (weakref.ref(system, lambda _, c=_CACHE, key=key: c.pop(key, None)), plan)
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.popitem(last=False)
    return plan


class MemberPlan(NamedTuple):
    """How members of one structure are stepped, each as :class:`Plan` would step it.

    ``affine[i]``: member ``i`` is stepped by row ``i`` of ``step_map`` (an
    :class:`AffineStepMap` whose leaves are stacked over the members); the others by
    ``solver``. ``refused[i]``: the :class:`UnsolvableStepError` of a member whose affine
    step Jacobian is singular (its row of ``step_map`` is a placeholder; it is not to be
    stepped).
    """

    solver: StepSolver
    step_map: AffineStepMap | None
    affine: np.ndarray
    refused: dict


def plan_members(system, static, dynamic, rule, scheme, h, solver, q0s, p0s, t0=0.0):
    """The stepping method of every member of a sweep's group: :class:`Plan`'s choice,
    made for all members together.

    The members share ``static`` (their systems' non-array part, of which ``system`` is
    one instance) and differ in ``dynamic``, their array leaves stacked
    (``equinox.partition``); ``q0s``, ``p0s`` are (members, n). The affine step maps
    are built together (:func:`~diracvi.solvers.affine.build_stacked`: one vmapped
    program probes every member, the solves and block maps are stacked), and their
    Jacobians checked together (:func:`~diracvi.solvers.solvability.singular_members`,
    then :func:`check_step_jacobian` for a flagged member, as ``Plan`` does). The
    circuit-scale sparse map is ``simulate``'s alone: where ``Plan`` would form it, the
    members are stepped by the fallback solver.
    """
    count = len(q0s)
    nothing = np.zeros(count, bool)
    if isinstance(solver, StepSolver):
        return MemberPlan(solver, None, nothing, {})
    options = AffineSolver() if solver is None else solver
    fallback = default_solver(system, rule, scheme) if solver is None else options.fallback
    fallback.check(system, rule, scheme)  # a solver that cannot apply says why
    if isinstance(solver, SparseAffineSolver) or (
        solver is None and isinstance(fallback, PartitionedSolver)
    ):
        return MemberPlan(fallback, None, nothing, {})
    maps = build_stacked(system, static, dynamic, rule, scheme, h, q0s, p0s, options, t0)
    if maps.step_map is None:
        return MemberPlan(fallback, None, nothing, {})
    affine, refused = maps.affine, {}

    def refuse(i, jac, where) -> None:
        try:
            check_step_jacobian(
                np.asarray(jac),
                unknown_names=unknown_names(system, scheme, rule),
                equation_names=equation_names(system, rule),
                where=where,
            )
        except UnsolvableStepError as exc:
            refused[int(i)] = exc

    jacobians = np.asarray(maps.step_map.jacobian)
    for i in np.nonzero(affine & singular_members(jacobians))[0]:
        refuse(i, jacobians[i], f"the ({scheme}) step")
    if maps.first is not None:  # J_x could not be solved: Plan's check of the first step
        for i, reason in enumerate(maps.reasons):
            if reason == SINGULAR:
                refuse(i, maps.first[i], f"the first ({scheme}) step")
    for i in refused:
        affine[i] = False
    if not affine.any():  # every member refused: none is stepped by a map
        return MemberPlan(fallback, None, nothing, refused)
    return MemberPlan(fallback, maps.step_map, affine, refused)
