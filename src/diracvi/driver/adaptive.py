r"""Variable steps: the (+) midpoint equations marched with a step chosen per step.

Each step is an ordinary discrete Dirac step of its own size ``h_k`` — the same
:class:`~diracvi.discretization.equations.StepEquations` a fixed-step run solves, here by Newton —
so the constraints hold to round-off and the discrete power balance holds step by step,
whatever the sequence of sizes. What a variable step gives up is the fixed step's
symplectic long-time energy behaviour (a varying step is not one symplectic map).

**Error control by step doubling.** From ``(q, p)`` at ``t`` one step of size ``H``
gives ``q_c``, two steps of ``H/2`` give ``q_f``. For a rule of order 2 the local error
of the fine result is ``≈ (q_f − q_c)/3`` (Richardson). It is judged per coordinate on
the positions and on the mean velocity over the step,

    e_q,j = |q_f − q_c|_j / (3 (s·rtol·Q_j + atol_q,j)),
    e_v,j = min( |q_f − q_c|_j / (3 H (s·rtol·V_j + atol_v,j)),  e_q,j ),

with ``Q_j``, ``V_j`` the largest ``|q_j|``, ``|v_j|`` met so far (the signal's running
peak, so a waveform passing through zero is not stepped ever finer there; restarted
at each breakpoint, below) and ``s`` =
:data:`SAFETY` (local errors add up over many steps); and per constraint on the
step-centred multiplier ``φ = −c/h`` (a circuit's node potential; ``c_k = 2μ_k − c_{k−1}``
is the step's own impulse, see :mod:`diracvi.spice._resample`), the coarse step's against
the mean of the two fine ones, with ``atol_m``, per try (as a state: below). A rate
(``e_v``) is judged at the run's resolution TMAX = ``hmax``: a step shorter than ``hmax``
has its rate error held to ``hmax/H`` times the tolerance, i.e. the rate's mean over
``hmax`` to the tolerance (``e ← e·min(1, H/hmax)``). A stiff mode ringing under the
midpoint rule (amplification → −1, e.g. a junction capacitance behind its series
resistance, excited where a diode switches) moves the end state by an amount that does not
shrink with ``H``; judged as a plain rate it grew as ``1/H`` and drove the step to
``hmin``. (The rates were once held only to the charge tolerance over the step, ``e_v ≤
e_q``, SPICE's ``max(current tol, charge tol / h)``: with a branch charge's running peak
``Q ≫ V·hmax`` that left a diode's current at its knee ~10⁻² of its peak off at the steps
the knee takes.) The node potentials are not held to their mean over TMAX: they are what a
circuit reports, and a potential's error that lasts over many short steps is not averaged
away, it adds up (``n = hmax/H`` steps each ``e·H/hmax`` of the tolerance make ``e``).
Held so (as the sparse host loop still holds them), the comparator of ``xy_sandler22``'s
555 timer, whose 100 kΩ output node ramps for ~0.3 µs after the trigger's edge on steps of
0.5-5 ns (TMAX 1 µs), rose 35 µV (5e-5 of its peak) early, and the flip-flop it sets fell
13 ps early: 1.1e-3 of ``v(x2.27)``'s peak; judged per try, 7.0e-4 for 1.5 times the
steps. A potential alternating from centre to centre (over the last try's two centres and
this one's, as the gap check leaves it out below) is the stiff junction mode above, and
stays held to TMAX, as does every potential on the first try after a corner (no centres of
its law before it): judged per try everywhere, that deck's step fell below ``hmin`` at
616.5 µs. (The junction voltages, the rates of their flux coordinates, stay held to TMAX
too: judged per try they drove its step to ``hmin`` after the trigger's edge.)
The impulses ``c_k = 2μ_k − c_{k−1}`` the potentials are read from carry an alternation
``ε(−1)^k`` that no step damps and that is not in the state (the μ's are free of it; it is
born where a corner or a step's Newton leaves ``c`` off its smooth value): it moves the
coarse potential by ``ε/H`` and not the fine ones' mean, a floor that grows as the step
shrinks, which a potential judged per try does not survive. So a retry fits ``ε`` from the
rejected try of its start and itself (the multipliers' counterpart of
:func:`~.step_error.alternating_from_retry`: :func:`~.step_error.impulse_alternation`) and
reads its coarse potential without it. (``es_cmos_nand``: a BSIM3 part's source node at
0.5 mV, rising in the 83.1 ms switching, carried ``ε`` ≈ 8e-14 V·s, 1.3 tolerances at a
19 ns try; the trend before hid the alternation from the ringing rule, and its retries went
down to ``hmin``, 2000 tolerances at 44 fs.) Not in a circuit with switches, whose
tries are judged as above (with it, under the budget of :mod:`.budget`,
``ng_switch_osc`` took 26 762 steps against 26 284 and read 0.357712 of peak against
0.357706; ``ng_switches`` the same).
The coordinates :class:`Controls` gives an ``inertia`` (a circuit's inductors,
as :func:`diracvi.spice.run` sets them) have their nodal momentum
``p̂ = p − ½A(q)ᵀc`` judged too, as a state like the positions, against its own
running peak ``P_j`` (at least ``M_jj`` times its velocity's: a coupled winding's flux
is mostly the other winding's current's),
``|p̂_f − p̂_c|_j / (3 (s·rtol·max(P_j, M_jj V_j) + M_jj atol_v,j))``: the positions' local error
``(H³/12) d³q/dt³`` vanishes twice a period of a ringing, where the momentum's peaks
(:func:`~.step_error.node_momentum_error`). ``e = max_j`` of all of them; ``e ≤ 1``
accepts the two fine steps (they are what is recorded: every recorded step is a plain
Dirac step, no extrapolated value), ``e > 1`` retries from the same state with a smaller
``H``; either way the next ``H`` is ``H·clip(0.9 e^{−1/3}, 0.2, 2)``, at most ``2·hmax``
(so that no recorded step is longer than ``hmax``). That law assumes ``e ∝ H³``; an
alternation ``δ(−1)^k`` the midpoint rule does not damp (a loop of capacitors and voltage
sources) adds ``2δ`` to ``q_f − q_c`` at every ``H``, a floor. So the period-2 part is
fitted from the last try's nodes and this one's (:func:`~.step_error.alternating`), and an
accepted try whose error without it is below half its error is sized by that smaller
error (``ng_inv_vdmos``: the floor at 0.73–0.8 held its step at 7e-14 s).
In a circuit with switches every try with ``δ`` fitted is judged — accepted and sized —
by the error without it, and where the nodes before the start are on another law (the
try after a switching instant) ``δ`` is fitted from a rejected try of the same start
instead (:func:`~.step_error.alternating_from_retry`). There the floor is several
tolerances (the 7-stage ring of ``tests/test_switches.py`` at reltol 1e-5: ``δ`` ≈ 8e-19
C, 7.7 tolerances, through the whole run), so a try after a flip, its estimate
unfitted, was rejected from 1.5 ps down to 0.1 fs (13 tries per flip on average, up to
80), and between flips a try whose floor took its error over 1 was rejected (in
``ng_switch_osc``, error 1.06 against 0.69 without the floor: its retry passed, two tries
a step). ``δ`` is not taken out of the recorded nodes, in any circuit: the mode lives on in
the momenta (the next try fits the same amplitude; a branch charge's gauge ``G`` is 0, so
a move of its nodes does not reach them), and moving a try's ends to the alternation's
centre only moved the centre the next try alternates about. Where the floor test passed
every other try — the steps growing by 2 after a source's corner — that was a ratchet of
``δ`` per two tries: ``es_cmos_nand``'s gate charges drifted 1.1e-12 C by 100 ms
(``q_v2`` 5.3e-13 C apart at 40 and 80 ms, the same inputs), their ``±2δ`` on the 9 ns
steps after each corner read as 5.5e-7 A against ngspice's pA. The output is read past
the alternation instead (:mod:`diracvi.spice._smooth`).
Not built: a non-switched circuit's retry judged by its rest with ``δ`` fitted from the
rejected try, and ``δ`` taken out of the carried momenta too (the second fine step's
discrete momentum at the moved nodes). Tried on the all-default BSIM4 decks, whose floor is
this mode in the branch charges (capMod 2's bulk-charge corner at ``V_DS = 0``), it took
them further but not through: the gap check then read the same alternation on the try's
centres as solved (docs/circuits.md, "The mode damped, tried").

**The gap between tries.** The output is a quadratic through the step centres
(:mod:`diracvi.spice._resample`); step doubling checks it inside a try (the coarse
centre against the fine ones' mean is the linear interpolant's error there), not
between the last try's second centre ``x₋₁`` and this try's first ``x₁``. There a diode
turning on is an exponential rising from below every tolerance — invisible to the last
try — to its full current, and a try ``H`` long before it leaves a gap the interpolant
overshoots (the bridge rectifier's source current: ~10⁻³ of its peak, at centres
correct to 10⁻⁵). So an accepted try also estimates the interpolant's error in the two
gaps its first centre closes (:func:`gap_error`: the quadratic the output draws there
against the straight line), judged as an output, at ``rtol`` of the signal's running
peak (the deck's own tolerance, with no share: an interpolation error is not carried
to the next step). Above it, this try's share of the gap (``H/4``) is cut first: it is
retried shorter by ``clip(0.9 e^{−1/3}, 0.2, 0.5)``, but not below twice the last
try's steps (``H = 2h₋₁``: the centres evenly spaced); then the *last* try's share
(``h₋₁/2``): that try is taken again from its own start, shorter by the same factor.
A signal alternating from centre to centre is left out of the check: that is a stiff
junction mode ringing under the midpoint rule, whose amplitude grows as the step
shrinks (cut for it, the eSim clipper's 1N4148 drove the step to ``hmin``); riding on a
trend, only the curvature common to the two quadratics is judged
(:func:`~.step_error.gap_error`). Both only where it is one alternation on both sides of
the gap: the differences within the last try and within this one agreeing, once scaled by
their tries' steps. A corner of a device law between the last try's two centres, followed
by the small alternation it excites (one large difference, then small ones of alternating
sign), is judged plainly: left out, ``ng_mosamp``'s Meyer ``C_gb`` reaching ``C_ox`` at
5.0024 µs was read by no check, and the output's interpolant across it, between centres
3.2 ps apart, was 1.85e-3 of ``i(vb)``'s peak off (4.6e-4 judged, for 1.3 times the
steps). The next try is sized for the checks ahead as well as
for the step error: the spacing a check allows is ``0.9 e_gap^{−1/2}`` times the larger
one it judged (the error goes as the spacing squared), and ``H'`` is held to it both in
the gap it closes, ``(H + H')/4``, and between its own centres, ``H'/2``. (Sized by the
step error alone, a try at an inverter chain's edge grew twofold, failed the check, was
cut and took the last try back with it: 89 % of the rejected tries of the 2-stage chain
of ``tests/test_alike_transistors.py``, 94 % of the 4-stage one's.) A retaken
try is not retaken a second time, no gap is judged across a breakpoint or a switching
instant (the interpolant does not cross those), and no try is retaken from a compiled
call's earlier buffer. (The sparse host
loop for linear circuits, :mod:`~diracvi.driver.adaptive_sparse`, has no junction to
turn on and no such check; nor has a run with ``gap_check=False``, as
:func:`diracvi.spice.run` steps a circuit without junctions: linear between the corners
the check skips, where its estimate — the *linear* interpolant's error, ``O(h²)``, not
the drawn quadratic's ``O(h³)`` — sized the steps at a tight tolerance instead of the
step error: ``ng_switch_osc`` at reltol 1e-5 stopped on its tries budget at 2.6 ns.)

**The end of a try.** Step doubling samples every law at step centres only, the
coarse step's and the fine ones'; a junction that turns on after the last of them (the
fine step's ``t + 3H/4``) is off at all three, and the try is accepted with the charge it
should have passed missing. So each junction's law is also evaluated at the state the
two fine steps extrapolate to at the try's end and compared with the line through its
two centre values (:mod:`.junction_end`): for a smooth law that mismatch is nine times the
fine steps' rate error, and it is judged as one, beside the step error (accepting and
sizing alike). A half-wave rectifier on a pulse train had its try 510 → 520 µs accepted
with the diode off at every centre (it turns on at 517.8 µs): 0.23 of its peak off,
5.0e-5 with the end judged.
A behavioural law's corners (its ``abs``, comparisons) are blind spots of the same kind,
where the law's other piece is missed and the output's interpolant crosses a kink; they
are located as switching instants (:mod:`.law_corners`: a parabola of each corner's
argument through the three centres, a crossing inside the try retried aimed at it).

**The coarse step's Newton.** The coarse step is never recorded: it is read only
through the step-doubling difference (``q₂ − q_c`` for the positions and their rates,
``φ_c = −(2μ_c − c₋₁)/H`` for the multipliers) and as the fine steps' starting guesses.
An error ``η`` left in ``q_c,j`` moves ``e_q,j`` by ``η/(3 tol_q,j)`` and ``e_v,j`` by
``η/(3H tol_v,j)``; one left in ``μ_c,i`` moves ``e_m,i`` by ``2η/(3H tol_m,i)``. So its
Newton stops once every update is within :data:`COARSE_SHARE` (1e-2) of
``3 min(tol_q,j, H tol_v,j)`` and ``1.5 H tol_m,i`` (the tolerances of the estimate with the
running peaks at the try's start), taken on an update that contracted by ``θ ≤ 1/4``
against the one before it in the same solve, so that it bounds the error it leaves
(:func:`~diracvi.solvers.newton._within`; ``tests/test_newton_stopping.py``): the
estimate then moves by at most about 0.01 of a tolerance (before Newton's contracting
phase an update bounds nothing: a diode turning on within a step, solved from the last
state, stopped 1.5 times its bound off; the loop's coarse guess is an extrapolation);
the recorded fine steps are solved to Newton's own tolerance. Where the nodal momenta are
judged (inductors: ``p_c`` reads ``q_c`` through the inductance matrix, coupled windings
each other's, and ``μ_c`` through ``A(q)ᵀc``; not bounded here) and in a circuit with
switches (whose event location reads ``q_c``) the coarse step is solved to round-off as
before. The fine steps stop by the ordinary test or, with the
loop's default solver, when the next chord update predicted from the observed
contraction would pass it (``NewtonSolver.predict_stop``). On the bridge rectifier of
:mod:`diracvi.spice._ngspice` the iterations fell 26 407 → 22 933 (coarse) → 18 416
(predicted stop), with the same steps and tries and the errors to three digits (not
bitwise: each solve ends elsewhere within its tolerance).

**Algebraic momenta.** The momenta of coordinates with no velocity in ``L`` and no
constraint row (a diode's flux without junction charge) are held at their exact value 0
after each step: their round-off would alternate undamped (:mod:`.algebraic`). The
``pinned`` positions (a ``ddt``'s ``y``, whose line fixes only its midpoint) are re-pinned
at each step's end from the last three steps' means (:mod:`.pinned`).

**Breakpoints.** A step never crosses one of the given times: it is shortened to end
exactly on it (and the last two steps before it share the remaining interval evenly, so
no sliver step is left). There the running peaks ``Q``, ``V`` and the multipliers'
restart from the state at the breakpoint, as at the run's start: a source corner starts
a new transient, judged on its own scale rather than on an earlier excursion's. A
thyristor fired by a gate pulse (the eSim SCR decks: an ``aswitch`` whose control node,
a gate current into ``C ∥ R``, builds up 0 → 0.6 V before it fires and then runs to
100–190 V) had its later build-ups judged against the first firing's peaks, 170–300
times looser than the first build-up, and fired 6–13 ns late on an edge ~30 ns wide,
the first 0.4–0.6 ns from the fine ngspice reference; restarted, every firing is as
close as the first, for 2–3.7 times the steps (and the fullwave deck at reltol 1e-5
now ends on its tries budget at 18 ms). Restarting ``Q`` and the multipliers' alone cost
less (3764 → 4170 steps) but took ~1.5 ps steps after the 12 ms corner, where the
fullwave deck's ``i(v1)`` read 0.66 A against the reference's ~0 (0.34 of its peak; not
traced further). The inductors' nodal-momentum peaks ``P`` are not restarted, nor are
the sparse host loops' (linear circuits).

**Events.** A circuit with switches carries their discrete states ``σ`` from step to
step; a try over which a switch would flip is accepted only once its end lies within
the event tolerance of the switching instant, and retried at the estimated instant
otherwise (:mod:`diracvi.driver.events`). Each recorded step's ``σ`` is kept.

The whole loop — tries, rejections, breakpoints, recording — is one compiled
``lax.while_loop`` whose step sizes are data: a run at another tolerance, another
``hmax``, other breakpoints (up to the padded count) or another state reuses the
program. :data:`TRACES` counts its traces (one per system and buffer size).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.rules import get_rule
from ..errors import ModelError
from ..model.roundoff import force_corners
from ..runtime.compile import stored_loop_jit
from ..runtime.config import ensure_float64
from ..solvers.bordered import newton_for
from ..solvers.newton import NewtonSolver
from . import events
from .algebraic import algebraic_mask
from .budget import TriesBudget
from .delay import refuse_variable_steps
from .junction_end import end_error, pairs
from .law_corners import locate
from .rebase import rebase_map
from .roundoff import current_floor, floors
from .step_error import (
    _ORDER,
    SAFETY,
    alternating,
    alternating_from_retry,
    estimate,
    gap_error,
    growth,
    impulse_alternation,
)
from .tries import one_step, three_steps

#: how many times the adaptive program has been traced (tests: a new step size, a new
#: tolerance or a new start does not trace again)
TRACES = {"count": 0}

#: statuses of an adaptive run
OK, TOO_SMALL, FAILED_SOLVE, TOO_MANY = 0, 1, 2, 3
MESSAGES = {
    OK: "ok",
    TOO_SMALL: "the step fell below hmin: the error cannot be met (a discontinuity, or "
    "tolerances below round-off)",
    FAILED_SOLVE: "a step's equations could not be solved even at the smallest step",
    TOO_MANY: "the run took more step tries than its budget (max_tries): the error "
    "estimate stalls at a tiny step (a ringing junction, or tolerances below round-off)",
}

#: the loop's state at a try's start, kept to take an accepted try again (gap_error)
_UNDO = ("t", "q", "p", "v_last", "u_prev", "mu_last", "h_last", "c_last", "phi_prev", "e_last")

#: the coarse step's Newton stops within this share of what the step-doubling estimate
#: can notice (module doc): the estimate moves by at most this many tolerances
COARSE_SHARE = 0.01

#: names this path in ``AdaptiveRun.solver``
DESCRIBE = "variable steps, Newton in one compiled loop (dense or band-plus-border Jacobians)"


class Controls(NamedTuple):
    """Tolerances and limits of an adaptive run (all times in the model's units)."""

    rtol: float
    atol_q: np.ndarray  # per coordinate, on positions
    atol_v: np.ndarray  # per coordinate, on the mean velocity over a step
    atol_m: np.ndarray  # per constraint, on the step-centred multiplier (a node potential)
    hmax: float
    hmin: float
    h_first: float
    #: per coordinate, the inertia ``M_jj`` whose nodal momentum is judged as a state
    #: (:func:`~.step_error.node_momentum_error`; 0: not judged); None: none is
    inertia: np.ndarray | None = None
    #: per coordinate, whether its current (and charge) is judged no finer than the
    #: round-off the circuit's current laws compute to (:mod:`.roundoff`: a circuit's
    #: branch charges); None: none is
    roundoff: np.ndarray | None = None


class AdaptiveRun(NamedTuple):
    """The recorded steps of an adaptive run: nodes ``t`` (N+1), sizes ``h`` (N),
    states ``q``, ``p`` (N+1, n) — the scheme's momenta, as in ``Trajectory.p`` —
    multipliers ``mu`` (N, m) of each step; ``tries``/``rejected`` counts; ``status``
    (0 ok, see :data:`MESSAGES`)."""

    t: np.ndarray
    h: np.ndarray
    q: np.ndarray
    p: np.ndarray
    mu: np.ndarray
    tries: int
    rejected: int
    status: int
    #: (N, number of switches): the switch states each step was taken with
    modes: np.ndarray | None = None
    #: which path stepped the run (as ``Trajectory.solver``)
    solver: str = DESCRIBE
    #: Newton iterations over all tries (three solves per try); 0 where not counted
    iterations: int = 0
    #: of the tries, those retried at a switching instant (not counted against max_tries)
    aimed: int = 0

    @property
    def message(self) -> str:
        return MESSAGES[self.status]


#: values per packed group: XLA fuses the selects of a group into its concatenation only
#: up to a few operands (with all ~40 floats in one group each select stayed its own
#: operation); 4, 8, 12, 16: 95, 83, 103, 106 operations in the bridge's loop body
_GROUP = 8

#: the loop's recording buffers, carried as they are (written in place, a block a try)
_BUFFERS = ("T", "H", "Q", "P", "MU", "S")


class _Carry:
    """The loop's small carried values packed into a few flat arrays (by dtype, at most
    :data:`_GROUP` values each).

    The body selects ~45 values between a try's outcome and the state it started from
    (``jnp.where(accept, new, old)``). Carried as ~55 separate loop values, each select
    was its own operation and each value its own copy at the loop's edge: 126 operations
    in the bridge rectifier's loop body, of which 28 copies. Packed, the body reads each
    value as a slice of its group (fused into whatever reads it) and writes each group
    once, its selects fused into its concatenation: 83 operations. The arithmetic is the
    same; only XLA's fusions move (where it contracts a multiply and an add inside one,
    a last bit can move: ng_schmitt, 1 ulp in one coordinate's recorded values). The
    buffers (:data:`_BUFFERS`) stay apart: they are written in place, a block a try."""

    def __init__(self, template):
        self.layout = {}  # key → (group, dtype, offset, shape)
        sizes, counts = {}, {}
        for key, value in template.items():
            if key in _BUFFERS:
                continue
            dtype, shape = jnp.result_type(value), jnp.shape(value)
            counts[dtype.name] = counts.get(dtype.name, 0) + 1
            group = f"{dtype.name}_{(counts[dtype.name] - 1) // _GROUP}"
            self.layout[key] = (group, dtype, sizes.get(group, 0), shape)
            sizes[group] = sizes.get(group, 0) + int(np.prod(shape, dtype=int))
        self.groups = tuple(sizes)

    def pack(self, values):
        """``{group: flat array}`` and the buffers as they are."""
        parts = {group: [] for group in self.groups}
        for key, (group, dtype, _, _) in self.layout.items():
            parts[group].append(jnp.ravel(jnp.asarray(values[key], dtype)))
        packed = {group: jnp.concatenate(parts[group]) for group in self.groups}
        return {**packed, **{key: values[key] for key in _BUFFERS}}

    def unpack(self, packed):
        """The values by name again (slices of their groups)."""
        out = {key: packed[key] for key in _BUFFERS}
        for key, (group, _, offset, shape) in self.layout.items():
            size = int(np.prod(shape, dtype=int))
            out[key] = packed[group][offset : offset + size].reshape(shape)
        return out


def _inertia(controls: Controls, n: int):
    """``controls.inertia`` as the loop takes it: None where no momentum is judged."""
    if controls.inertia is None:
        return None
    mass = np.broadcast_to(np.asarray(controls.inertia, np.float64), (n,)).copy()
    return mass if np.any(mass > 0.0) else None


def _roundoff(controls: Controls, system, n: int):
    """``controls.roundoff`` as the loop takes it: None where no coordinate takes the
    laws' round-off floor or no part has a law's bound (:mod:`.roundoff`)."""
    if controls.roundoff is None or current_floor(system) is None:
        return None
    mask = np.broadcast_to(np.asarray(controls.roundoff, bool), (n,)).copy()
    return mask if np.any(mask) else None


def _march(system, rule, solver, capacity, x):
    """The compiled loop: ``x`` holds the state and controls (see :func:`adaptive`)."""
    TRACES["count"] += 1
    n, m = system.n, system.m
    dtype = x["q"].dtype
    rtol, atol_q, atol_v = x["rtol"], x["atol_q"], x["atol_v"]
    hmax, hmin, t_stop, breaks = x["hmax"], x["hmin"], x["t_stop"], x["breaks"]
    found = events.relays(system)
    judge_p = x["inertia"] is not None  # (a structure: known when traced)
    # the junctions and the velocities their laws set, for the check at a try's end
    # (.junction_end; read at the call's start: a diode's pairing is constant)
    end_pair = pairs(system, x["q"], x["t"])
    # the laws' round-off floor of the currents (.roundoff): None without a law's bound
    law_floor = current_floor(system) if x["roundoff"] is not None else None
    # the corners of the parts' laws, located as switching instants (.law_corners)
    corner_fn = force_corners(system)

    def step(modes, h, t, q, p, dq, mu, atol=None):
        stepped = events.with_modes(system, modes)
        q1, p1, mu1, ok, its = one_step(stepped, rule, solver, h, t, q, p, q + dq, mu, atol)
        # the momenta of algebraic coordinates held at their exact value 0 (their
        # round-off would alternate undamped: driver/algebraic.py)
        return q1, jnp.where(x["algebraic"], 0.0, p1), mu1, ok, its

    def coarse_accuracy(c, h_try):
        # the coarse step is read only through the step-doubling difference (module
        # doc, "The coarse step's Newton"): each unknown solved to COARSE_SHARE of the
        # smallest change of it that moves the estimate by one tolerance, with the
        # running peaks at the try's start (this try's can only raise them)
        share = x["safety"] * rtol
        order = 2.0**_ORDER - 1.0
        tol_q = jnp.minimum(share * c["q_peak"] + atol_q, h_try * (share * c["v_peak"] + atol_v))
        bound_q = COARSE_SHARE * order * tol_q
        bound_m = COARSE_SHARE * 0.5 * order * h_try * (share * c["m_peak"] + x["atol_m"])
        return jnp.concatenate([bound_q, bound_m])

    def cond(packed):
        c = carry.unpack(packed)
        return (c["status"] == OK) & (c["t"] < t_stop) & (c["i"] + 2 <= capacity)

    def body(packed):
        c = carry.unpack(packed)
        t, h = c["t"], c["h"]
        # the try in the gauge of its start: growing coordinates from zero, the carried
        # momentum p̃ that gauge's own (.rebase); q_abs = base + q (rounded) is recorded
        q_abs, p = c["q"], c["p"]
        base = jnp.where(x["rebase"], q_abs, 0.0)
        q = q_abs - base
        target = jnp.minimum(breaks[c["ib"]], t_stop)
        rem = target - t
        # a try of H records two steps of H/2: each recorded step is at most hmax
        h0 = jnp.minimum(h, 2.0 * hmax)
        land = rem <= h0 * (1.0 + 1e-9)
        h_try = jnp.where(land, rem, jnp.where(rem < 2.0 * h0, 0.5 * rem, h0))
        # a retry aimed at a switching instant is taken as aimed (unless a breakpoint
        # comes first)
        h_try = jnp.where(c["aimed"] & ~land, h0, h_try)
        modes = c["modes"]
        # a first guess from the last velocity (linear models converge in one update),
        # carried on along the line through the last try's two mean velocities (at
        # t − 3h/2 and t − h/2) to the coarse step's centre t + H/2 unless a corner ended
        # that try
        h_last = c["h_last"]
        slope = (c["v_last"] - c["u_prev"]) / h_last
        predict = not found  # not in a circuit with switches (tries.three_steps)
        carry_on = c["gap_ok"] & predict
        vel = c["v_last"] + jnp.where(carry_on, slope * (0.5 * h_try + 0.5 * h_last), 0.0)
        mu_g = c["mu_last"] * (h_try / c["h_last"])
        half = 0.5 * h_try
        # the pinned coordinates' history: the last try's two halves, unless a corner
        # (a breakpoint, a switching instant) ended it (.pinned)
        pin = (x["pinned"], (c["y_mean2"], c["y_mean1"]), c["h_last"], c["gap_ok"])
        back = (c["v_last"], 0.5 * h_last)  # the last mean velocity, at t − h_last/2
        (qc, q1, q2), (pc, p1, p2), (mu_c, mu1, mu2), oks, its, means = three_steps(
            step, modes, h_try, t, q, p, vel, mu_g, pin, last=back, predict=predict,
            coarse_atol=None if found or judge_p else coarse_accuracy(c, h_try),
        )  # fmt: skip
        ok = oks[0] & oks[1] & oks[2]
        c_prev = c["c_last"]
        # no current judged below the round-off its laws compute to (.roundoff): the
        # absolute tolerances of this try
        tol_q, tol_v = atol_q, atol_v
        if law_floor is not None:
            nodes = (t, q_abs, base + qc, base + q1, base + q2)
            tol_q, tol_v = floors(atol_q, atol_v, x["roundoff"], law_floor(nodes, h_try), h_try)
        # the period-2 part at the start (a neutral mode, not truncation error:
        # step_error.alternating), fitted over the last try too unless a corner ended it
        last = (c["u_prev"] * h_last, c["v_last"] * h_last)
        delta = jnp.where(c["gap_ok"], alternating(jnp, last, (q1 - q, q2 - q1), h_last, half), 0.0)
        # in a switched circuit, a retry from the start of a rejected try fits it from the
        # two tries instead (step_error.alternating_from_retry): after a switching instant
        # the nodes before the start are on another law, and the fit above is off
        switched = bool(found)
        retried = c["rej_ok"] & ((h_try / c["rej_h"]) ** 3 <= 0.75) & switched
        d_raw = q2 - qc
        delta = jnp.where(
            retried, alternating_from_retry(c["rej_d"], d_raw, c["rej_h"], h_try), delta
        )
        momenta = None
        if judge_p:
            # the nodal momenta, their lag the impulse A(q)ᵀc (step_error.estimate),
            # absolute for their peak (p = p_try + G·base)
            def impulse(c):
                return events.with_modes(system, modes).multiplier_force(q_abs, c, t)

            shift_p = x["gauge"] @ base
            momenta = (pc + shift_p, p2 + shift_p, impulse, x["inertia"])
        # the node potentials judged per try (the module doc), except where one alternates
        # from centre to centre — a stiff junction mode ringing under the midpoint rule,
        # whose amplitude no shorter step lowers (as the gap check leaves it out) — or the
        # try follows a corner (no centres of this law before it): there held to TMAX
        phi_a = -(2.0 * mu1 - c_prev) / half
        phi_b = -(2.0 * mu2 - (2.0 * mu1 - c_prev)) / half
        phi_0 = -c["c_last"] / h_last
        d1, d2, d3 = phi_0 - c["phi_prev"], phi_a - phi_0, phi_b - phi_a
        rings = ~c["gap_ok"] | ((d1 * d2 < 0.0) & (d2 * d3 < 0.0))
        # the carried impulse's period-2 part ε (c_k = 2μ_k − c_{k−1}: a mode no step
        # damps, not in the state), fitted from a rejected try of this start and this one
        # (step_error.impulse_alternation) and left out of the coarse potential: judged
        # per try, ε/H read as an error that grows as the step shrinks (es_cmos_nand: ε ≈
        # 8e-14 V·s at a BSIM3 source node, its retries from 19 ns down to hmin)
        # (not in a circuit with switches: measured there, ng_switch_osc took 26 762 steps
        # against 26 284 and read a little worse, so that path is left as it was)
        m_raw = c_prev + 2.0 * (mu2 - mu_c)
        eps_c = None
        if not switched:
            fitted_m = c["rej_ok"] & ((h_try / c["rej_h"]) ** 3 <= 0.75)
            eps_c = jnp.where(
                fitted_m, impulse_alternation(c["rej_m"], m_raw, c["rej_h"], h_try), 0.0
            )
        est = estimate(
            jnp, q, (qc, q1, q2), (mu_c, mu1, mu2), c_prev, h_try,
            (c["q_peak"], c["v_peak"], c["m_peak"]) + ((c["p_peak"],) if judge_p else ()),
            (x["safety"], rtol, tol_q, tol_v, x["atol_m"]), hmax, base, delta,
            momenta, potentials_over_tmax=rings, c_alternation=eps_c,
        )  # fmt: skip
        err, q_peak, v_peak, m_peak, c2, smooth, p_peak = est
        v2 = (q2 - q1) / half
        ok = ok & jnp.isfinite(err)
        modes_new, located, h_event, e_new = events.decide(
            found, modes, (q, q1, q2, qc), (p, p1, p2, pc), c["e_last"], h_try, x["event_tol"],
            hmin,
        )  # fmt: skip
        landed = False
        if corner_fn is not None:
            # a law's corner crossed inside the try: retried aimed at it (.law_corners)
            nodes = (t, q_abs, base + qc, base + q1, base + q2)
            at_corner, h_corner, landed = locate(corner_fn, nodes, h_try, rtol, x["atol_v"], hmin)
            located = located & at_corner
            h_event = jnp.minimum(h_event, h_corner)
        # a try whose error is mostly the period-2 part, which no shorter step lowers
        # (step_error.estimate), is sized by the rest (only where it holds the step back:
        # below 0.091 the growth is at its cap, 2), and accepted on the whole; in a
        # switched circuit every try with the part fitted is judged by the rest (the
        # module doc)
        plain_floor = (err <= 1.0) & (err > 0.091) & (smooth < 0.5 * err)
        floor = jnp.where(switched, c["gap_ok"] | retried, plain_floor)
        judged = jnp.where(floor, smooth, err)
        if end_pair is not None:
            # each junction's law at the try's end, where no centre samples it: a diode
            # turning on after the last centre (.junction_end)
            e_end = end_error(
                events.with_modes(system, modes).force, (t, q_abs, base + q1, base + q2),
                h_try, hmax, end_pair,
                x["safety"] * rtol * v_peak + tol_v,
            )  # fmt: skip
            judged = jnp.maximum(judged, e_end)
        aim = ok & (judged <= 1.0) & ~located  # retried at the switching instant
        passes = ok & (judged <= 1.0) & located
        # the interpolant between the last try's second centre and this try's first (the
        # gap no estimate above sees, see the module doc): too coarse there, this try is
        # retried shorter, or the last one taken again (once: a ringing junction's
        # alternation does not shrink with the step)
        xs = (t - 1.5 * h_last, t - 0.5 * h_last, t + 0.25 * h_try, t + 0.75 * h_try)
        phi_last = -c["c_last"] / h_last
        phi1, phi2 = -(2.0 * mu1 - c_prev) / half, -c2 / half
        gap_v = gap_error(xs, (c["u_prev"], c["v_last"], (q1 - q) / half, v2))
        gap_m = gap_error(xs, (c["phi_prev"], phi_last, phi1, phi2))
        e_gap_v = gap_v / (rtol * v_peak + tol_v)
        e_gap_m = gap_m / (rtol * m_peak + x["atol_m"])
        e_gap = jnp.max(jnp.concatenate([e_gap_v, e_gap_m]), initial=0.0)
        coarse = passes & x["gap_check"] & c["gap_ok"] & ~c["aimed"] & ~(e_gap <= 1.0)
        # this try's own share of the gap first (down to the last try's spacing), then
        # the last try's
        own = coarse & (h_try > 2.0 * h_last * (1.0 + 1e-9))
        back = coarse & ~own & c["back_ok"] & (c["i"] >= 2)
        accept = passes & ~own & ~back
        grow = growth(jnp, judged)
        # the two steps are kept as solved, the period-2 part too: it lives on in the
        # momenta (a branch charge's gauge G is 0), so moving the nodes to its centre
        # only shifted the centre the next try alternates about — by δ a fix, a
        # ratchet (the module doc, "A floor no step lowers"); the output is read past it
        # (spice/_smooth.py)
        h_next = jnp.where(ok, h_try * grow, 0.25 * h_try)
        # a step shortened to land on a breakpoint says little about the next one
        h_next = jnp.where(accept & (h_try < h0), jnp.maximum(h_next, h0), h_next)
        # the gap checks ahead held in view (the module doc). Each judges two spacings of
        # the output's centres: the last try's own two (``h₋₁``, its steps) and the gap
        # this try's first centre closes (``h₋₁/2 + H/4``), with an error ∝ the spacing
        # squared (a second difference times it, step_error.gap_error). So the spacing
        # this check allows is ``s = 0.9 e_gap^{-1/2}`` times the larger one it judged (as
        # the growth law sizes a try from the step error), and the next try ``H'`` is held
        # to it in both checks it meets: ``(H + H')/4 ≤ s`` (the next one's gap) and
        # ``H'/2 ≤ s`` (its own two centres, in the check after)
        plain = ~land & jnp.all(modes_new == modes) & ~landed
        sized = accept & plain & x["gap_check"] & c["gap_ok"] & ~c["aimed"]
        spacing = jnp.maximum(h_last, 0.5 * h_last + 0.25 * h_try)
        allowed = 0.9 * spacing * jnp.maximum(e_gap, 1e-12) ** -0.5
        h_gap = jnp.minimum(2.0 * allowed, 4.0 * allowed - h_try)
        h_next = jnp.where(sized, jnp.minimum(h_next, jnp.maximum(h_gap, 0.2 * h_try)), h_next)
        h_next = jnp.where(aim, h_event, h_next)
        shrink = jnp.clip(0.9 * jnp.maximum(e_gap, 1.0) ** (-1.0 / (_ORDER + 1)), 0.2, 0.5)
        h_next = jnp.where(own, jnp.maximum(h_try * shrink, 2.0 * h_last), h_next)
        i = c["i"]
        t_new = jnp.where(land, target, t + h_try)

        def put(buf, row, first, second):
            # the two rows written whether or not the try is accepted: rows past the
            # record's count are not read (a rejected try's are overwritten by the next),
            # and an unconditional write of a block is done in place where a
            # read-select-write of each row made XLA copy the whole buffer every try
            block = jnp.stack([first, second]).astype(buf.dtype)
            return jax.lax.dynamic_update_slice_in_dim(buf, block, row, axis=0)

        new = dict(c)
        new["T"] = put(c["T"], i + 1, t + half, t_new)
        new["H"] = put(c["H"], i, half, half)
        new["Q"] = put(c["Q"], i + 1, base + q1, base + q2)
        shift = x["gauge"] @ base  # the recorded momenta: p = p_try + G·base
        new["P"] = put(c["P"], i + 1, p1 + shift, p2 + shift)
        new["MU"] = put(c["MU"], i, mu1, mu2)
        new["S"] = put(c["S"], i, modes, modes)
        new["modes"] = jnp.where(accept, modes_new, modes)
        new["e_last"] = jnp.where(accept, e_new, c["e_last"])
        new["aimed"] = aim
        new["i"] = jnp.where(accept, i + 2, i)
        new["t"] = jnp.where(accept, t_new, t)
        new["q"] = jnp.where(accept, base + q2, q_abs)
        # the new start's gauge momentum, from the increments alone: p̃ = p₂ − G·Δq
        new["p"] = jnp.where(accept, p2 - x["gauge"] @ q2, p)
        new["v_last"] = jnp.where(accept, v2, c["v_last"])
        new["u_prev"] = jnp.where(accept, (q1 - q) / half, c["u_prev"])
        new["phi_prev"] = jnp.where(accept, phi1, c["phi_prev"])
        new["mu_last"] = jnp.where(accept, mu2, c["mu_last"])
        new["y_mean2"] = jnp.where(accept, means[1], c["y_mean2"])
        new["y_mean1"] = jnp.where(accept, means[2], c["y_mean1"])
        new["h_last"] = jnp.where(accept, half, c["h_last"])
        new["q_peak"] = jnp.where(accept, q_peak, c["q_peak"])
        new["v_peak"] = jnp.where(accept, v_peak, c["v_peak"])
        new["m_peak"] = jnp.where(accept, m_peak, c["m_peak"])
        if judge_p:
            new["p_peak"] = jnp.where(accept, p_peak, c["p_peak"])
        new["c_last"] = jnp.where(accept, c2, c["c_last"])
        passed = accept & land & (target == breaks[c["ib"]])
        new["ib"] = jnp.where(passed, c["ib"] + 1, c["ib"])
        # the running peaks restart at a source corner from the state there, as at the
        # run's start (the module doc's "Breakpoints"): the transient a corner starts is
        # judged on its own scale, not on an earlier excursion's
        new["q_peak"] = jnp.where(passed, jnp.abs(base + q2), new["q_peak"])
        new["v_peak"] = jnp.where(passed, jnp.abs(v2), new["v_peak"])
        new["m_peak"] = jnp.where(passed, jnp.abs(phi2), new["m_peak"])
        new["h"] = jnp.minimum(h_next, 2.0 * hmax)
        # a try that may be taken again: not itself a repeat, not ending on a breakpoint
        # or at a switching instant (the interpolant does not cross those)
        new["gap_ok"] = jnp.where(accept, plain, c["gap_ok"])
        new["back_ok"] = jnp.where(accept, plain & ~c["redone"], c["back_ok"])
        new["redone"] = jnp.where(accept, False, c["redone"])
        for key in _UNDO:
            new["was_" + key] = jnp.where(accept, c[key], c["was_" + key])
        new["was_h"] = jnp.where(accept, h_try, c["was_h"])
        # the last rejected try from this start (its q₂ − q_c), for a retry's fit of δ
        kept = ok & ~accept & ~back
        new["rej_ok"] = ~accept & ~back & (ok | c["rej_ok"])
        new["rej_d"] = jnp.where(kept, d_raw, c["rej_d"])
        if not switched:
            new["rej_m"] = jnp.where(kept, m_raw, c["rej_m"])
        new["rej_h"] = jnp.where(kept, h_try, c["rej_h"])
        new["tries"] = c["tries"] + 1

        new["newton"] = c["newton"] + its
        new["aims"] = c["aims"] + jnp.where(aim, 1, 0)
        new["rejected"] = c["rejected"] + jnp.where(accept, 0, 1)
        small = ~accept & ~back & (h_next < hmin)
        new["status"] = jnp.where(small, jnp.where(ok, TOO_SMALL, FAILED_SOLVE), OK)
        # taking the last try again: its start state back, its two rows to be rewritten
        # (the gap before it is not checked again: the retaken try starts a new record)
        for key in _UNDO:
            new[key] = jnp.where(back, c["was_" + key], new[key])
        new["i"] = jnp.where(back, i - 2, new["i"])
        new["h"] = jnp.where(back, c["was_h"] * shrink, new["h"])
        new["back_ok"] = jnp.where(back, False, new["back_ok"])
        new["gap_ok"] = jnp.where(back, False, new["gap_ok"])
        new["redone"] = jnp.where(back, True, new["redone"])
        new["aimed"] = jnp.where(back, False, new["aimed"])
        return carry.pack(new)

    init = {
        "t": x["t"],
        "q": x["q"],
        "p": x["p"],
        "h": x["h"],
        "ib": x["ib"],
        "i": jnp.asarray(0),
        "v_last": x["v_last"],
        "mu_last": x["mu_last"],
        "h_last": x["h_last"],
        "q_peak": x["q_peak"],
        "v_peak": x["v_peak"],
        "m_peak": x["m_peak"],
        **({"p_peak": x["p_peak"]} if judge_p else {}),
        "c_last": x["c_last"],
        "tries": jnp.asarray(0),
        "newton": jnp.asarray(0),
        "aims": jnp.asarray(0),
        "rejected": jnp.asarray(0),
        "status": jnp.asarray(OK),
        "modes": x["modes"],
        "e_last": x["e_last"],
        "aimed": jnp.asarray(False),
        "u_prev": x["u_prev"],
        "phi_prev": x["phi_prev"],
        "y_mean1": x["y_mean1"],
        "y_mean2": x["y_mean2"],
        "back_ok": jnp.asarray(False),  # a new chunk cannot rewrite the last one's rows
        "gap_ok": jnp.asarray(False),
        "redone": jnp.asarray(False),
        "rej_ok": jnp.asarray(False),
        "rej_d": jnp.zeros(n, dtype),
        **({} if found else {"rej_m": jnp.zeros(m, dtype)}),
        "rej_h": jnp.asarray(1.0, dtype),
        **{"was_" + key: x[key] for key in _UNDO},
        "was_h": x["h"],
        "T": jnp.zeros(capacity + 1, dtype).at[0].set(x["t"]),
        "H": jnp.zeros(capacity, dtype),
        "Q": jnp.zeros((capacity + 1, n), dtype).at[0].set(x["q"]),
        "P": jnp.zeros((capacity + 1, n), dtype).at[0].set(x["p"]),
        "MU": jnp.zeros((capacity, m), dtype),
        "S": jnp.zeros((capacity, len(found)), dtype),
    }
    carry = _Carry(init)
    return carry.unpack(jax.lax.while_loop(cond, body, carry.pack(init)))


#: compiled with XLA's default optimization and its older fusion code generator (half
#: the compilation, the same step speed: runtime/compile.py: loop_options), or the
#: run-once options under DIRACVI_FAST_COMPILE=1, and kept in the program store: a
#: later process loads it
_program = stored_loop_jit(_march, "diracvi.driver.adaptive._march")


def buffer_size(n: int) -> int:
    """Steps recorded per compiled call: ~2²⁰ numbers per state buffer, 256 to 8192."""
    size = 1 << max(8, min(13, int(np.log2(max(1, (1 << 20) // max(n, 1))))))
    return size


def adaptive(
    system,
    q0,
    p0,
    *,
    t0: float,
    t_stop: float,
    controls: Controls,
    breakpoints=(),
    solver=None,
    max_tries: int = 1_000_000,
    event_atol=1e-6,
    modes=None,
    pinned=None,
    rebase: bool = True,
    gap_check: bool = True,
) -> AdaptiveRun:
    """March ``system`` from ``(q0, p0)`` at ``t0`` to ``t_stop`` under the midpoint
    rule with error-controlled steps, ending a step exactly on every breakpoint.

    ``controls``: :class:`Controls`; ``solver``: a :class:`~diracvi.NewtonSolver`
    (default: the simplified Newton of :class:`~diracvi.NewtonSolver`, its factors
    formed afresh at each solve's first iterate — a changing ``h`` changes the
    Jacobian — and kept while the updates contract: forming and factoring the dense
    Jacobian is most of an iteration's cost, ~4 of 5 on ng_rtlinv, and full Newton's
    last iterate, whose update is already at round-off, formed one for nothing).
    ``event_atol``: the absolute tolerance of each switch's control
    (:func:`~diracvi.driver.events.tolerances`), one number or one per switch;
    ``modes``: the switches' states at ``t0`` (default: as the system holds them).
    ``pinned``: a boolean per coordinate, the positions re-pinned at each step's end
    (:mod:`.pinned`: a behavioural source's ``ddt`` positions; default none).
    ``rebase``: step the growing coordinates from zero in each try's gauge
    (:mod:`.rebase`; on by default, ``rebase=False`` steps them as they are: the same
    steps in exact arithmetic, their round-off ``ulp(q)/h`` grows with the run).
    ``gap_check``: judge the output in the gap between tries (for a junction turning on).
    ``max_tries``: the budget of tries, the retries aimed at a switching instant left out
    (each event takes a few, and their number is bounded by the events'): a count, or a
    :class:`~.budget.TriesBudget` judged by the run's pace. Returns an
    :class:`AdaptiveRun`; a run that cannot meet the tolerance stops with
    ``status != 0`` and what it recorded until then.
    """
    ensure_float64()
    if not t_stop > t0:
        raise ModelError(f"t_stop={t_stop!r} must be after t0={t0!r}.")
    refuse_variable_steps(system, "adaptive")
    rule = get_rule("midpoint")
    if solver is None:
        # a large sparse step is formed and factorized as a band plus a border
        # (solvers/bordered.py); not with switches, whose states change the pattern
        # plain_lu: a small circuit's whole loop compiled as one kernel (NewtonSolver)
        solver = (
            NewtonSolver(reuse_jacobian=True, plain_lu=True)
            if events.relays(system)
            else newton_for(system, rule, reuse_jacobian=True, predict_stop=True, plain_lu=True)
        )
    n, m = system.n, system.m
    q = np.asarray(q0, dtype=np.float64).reshape(n)
    p = np.asarray(p0, dtype=np.float64).reshape(n)
    breaks = sorted(float(b) for b in breakpoints if t0 < b < t_stop)
    # padded to a power of two (at least 16): other breakpoint counts reuse the program
    width = 1 << max(4, int(np.ceil(np.log2(len(breaks) + 1))))
    padded = np.full(width, np.inf)
    padded[: len(breaks)] = breaks
    capacity = buffer_size(n)
    # growing coordinates stepped from zero (.rebase); not with switches, whose states
    # may change what the Lagrangian reads
    if not rebase or events.relays(system):
        rebased, gauge = np.zeros(n, bool), np.zeros((n, n))
    else:
        rebased, gauge = rebase_map(system, q, t0)
    state = {
        "t": np.float64(t0),
        "q": q,
        "p": p - gauge @ q,  # the gauge momentum p̃ = p − G q (.rebase)
        "h": np.float64(min(controls.h_first, 2.0 * controls.hmax)),
        "ib": np.asarray(0),
        "v_last": np.zeros(n),
        "mu_last": np.zeros(m),
        "h_last": np.float64(1.0),
        "q_peak": np.abs(q),
        "v_peak": np.zeros(n),
        "m_peak": np.zeros(m),
        "c_last": np.zeros(m),  # the given p0 carries no lag: c_{−1} = 0
        "modes": events.initial_modes(system) if modes is None else np.asarray(modes, float),
        "e_last": np.zeros(len(events.relays(system))),  # as c_last: no lag in p0
        "aimed": np.asarray(False),
        "u_prev": np.zeros(n),
        "phi_prev": np.zeros(m),
        "y_mean1": np.zeros(n),
        "y_mean2": np.zeros(n),
    }
    fixed = {
        "rtol": np.float64(controls.rtol),
        "safety": np.float64(SAFETY),
        "atol_q": np.broadcast_to(np.asarray(controls.atol_q, np.float64), (n,)).copy(),
        "atol_v": np.broadcast_to(np.asarray(controls.atol_v, np.float64), (n,)).copy(),
        "atol_m": np.broadcast_to(np.asarray(controls.atol_m, np.float64), (m,)).copy(),
        "hmax": np.float64(controls.hmax),
        "hmin": np.float64(controls.hmin),
        "t_stop": np.float64(t_stop),
        "breaks": padded,
        "event_tol": events.tolerances(system, controls.rtol, event_atol),
        "algebraic": algebraic_mask(system, q, p, t0),
        "inertia": _inertia(controls, n),
        "roundoff": _roundoff(controls, system, n),
        "pinned": np.zeros(n, bool) if pinned is None else np.asarray(pinned, bool).reshape(n),
        "rebase": rebased,
        "gauge": gauge,
        "gap_check": np.asarray(bool(gap_check)),
    }
    if fixed["inertia"] is not None:
        state["p_peak"] = np.zeros(n)  # the nodal momenta's running peak
    ts, hs, qs, ps, mus = [np.array([t0])], [], [q[None]], [p[None]], []
    modes = []
    tries = rejected = newton = 0
    tries = rejected = aims = 0
    status = OK
    budget = TriesBudget.of(max_tries, t0)  # (.budget: a count, or judged by the pace)
    while True:
        out = _program(system, rule, solver, capacity, {**state, **fixed})
        out = jax.tree.map(np.asarray, out)
        k = int(out["i"])
        ts.append(out["T"][1 : k + 1])
        hs.append(out["H"][:k])
        qs.append(out["Q"][1 : k + 1])
        ps.append(out["P"][1 : k + 1])
        mus.append(out["MU"][:k])
        modes.append(out["S"][:k])
        tries += int(out["tries"])
        aims += int(out["aims"])
        rejected += int(out["rejected"])
        newton += int(out["newton"])
        status = int(out["status"])
        if status != OK or not out["t"] < t_stop:
            break
        # a retry aimed at a switching instant is not counted: each event takes a few
        # (the secant on the crossing), and a switched oscillator has thousands of events
        # (ng_switch_osc: 1191 flips and 3755 aimed retries in 78 ns, against 10 500 tries)
        if budget.spent(float(out["t"]), tries - aims, t_stop):
            status = TOO_MANY
            break
        state = {key: out[key] for key in state}
    return AdaptiveRun(
        np.concatenate(ts),
        np.concatenate(hs),
        np.concatenate(qs),
        np.concatenate(ps),
        np.concatenate(mus) if mus else np.zeros((0, m)),
        tries,
        rejected,
        status,
        np.concatenate(modes) if modes else None,
        iterations=newton,
        aimed=aims,
    )
