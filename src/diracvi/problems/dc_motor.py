r"""A DC motor: armature circuit + rotor, coupled through a gyrator.

``armature``: branch charges ``(q^S, q^R, q^L, q^M)`` of a series loop — source, resistor,
inductor and the motor port — with KCL ``v^S = v^R = v^L = v^M`` (three one-forms),
``L = ½ L_a (v^L)²`` and force ``(V_s, −R v^R, 0, 0)`` (a constant source voltage does
work ``V_s i``). ``rotor``: ``L = ½ J θ̇²`` with viscous friction ``−b θ̇``.
``gyrator``: ``(q^e, φ)`` with ``L = K φ v^e`` — linear in velocity, so degenerate and
energy-free: its electrical port sees the back-emf ``K φ̇``, its mechanical port the torque
``K i``. Interactions ``v^M = v^e`` and ``θ̇ = φ̇``.

The reduced model ``(q, θ)`` with ``L = ½ L_a q̇² + ½ J θ̇² + K θ q̇``,
``F = (V_s − R q̇, −b θ̇)`` gives ``L_a q̈ = V_s − R q̇ − K θ̇``, ``J θ̈ = K q̇ − b θ̇``: the
textbook motor, whose exact flow is a matrix exponential.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model.interaction import connect
from ..model.interconnect import interconnect
from ..model.system import LagrangeDiracSystem
from ._problem import Problem, linear_flow


def _torn_exact(exact_reduced):
    """The torn motor's exact solution from the reduced one: the armature's four branch
    charges, the rotor angle, then the gyrator's charge and angle port copies."""

    def exact(t):
        x = exact_reduced(t)
        charge, angle = x[:, :1], x[:, 1:]
        return np.concatenate([np.repeat(charge, 4, axis=1), angle, charge, angle], axis=1)

    return exact


def dc_motor(
    voltage: float = 12.0,
    resistance: float = 1.0,
    inductance: float = 0.5,
    inertia: float = 0.01,
    friction: float = 0.1,
    motor_constant: float = 0.05,
    dt: float = 0.001,
    steps: int = 2000,
) -> Problem:
    """A DC motor: armature circuit and rotor joined through a gyrator (``diracvi run
    dc-motor``); see the module docstring for the three subsystems.

    Equations of the reduced model (``problem.reduced``): ``L_a q̈ = V_s − R q̇ − K θ̇``,
    ``J θ̈ = K q̇ − b θ̇``; the torn model's ``armature.qL`` and ``rotor.theta`` equal ``q``
    and ``θ`` (``problem.shared``), and ``exact(t)`` is the reduced model's exact flow.

    Args:
        voltage: source ``V_s``.
        resistance: armature ``R``.
        inductance: armature ``L_a``.
        inertia: rotor ``J``.
        friction: viscous ``b``.
        motor_constant: gyrator ``K`` (torque ``K i``, back-emf ``K θ̇``).
        dt: the time step used by ``diracvi run``.
        steps: the number of steps used by ``diracvi run``.

    Returns:
        A [`Problem`][diracvi.problems.Problem] starting at rest. Nothing is checked
        here; ``inductance=0`` or ``inertia=0`` make the step equations singular, which
        ``dv.simulate`` reports as ``ModelError``/``UnsolvableStepError``.
    """
    vs, r, la, j, b, k = (
        float(x) for x in (voltage, resistance, inductance, inertia, friction, motor_constant)
    )
    armature = LagrangeDiracSystem(
        ("qS", "qR", "qL", "qM"),
        lambda q, v: 0.5 * la * v[2] ** 2,
        constraints=np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 1.0, -1.0, 0.0], [0.0, 0.0, 1.0, -1.0]]),
        force=lambda q, v: jnp.stack([vs + 0.0 * v[0], -r * v[1], 0.0 * v[2], 0.0 * v[3]]),
        name="armature",
        constraint_names=("KCL_SR", "KCL_RL", "KCL_LM"),
    )
    rotor = LagrangeDiracSystem(
        ("theta",), lambda q, v: 0.5 * j * v[0] ** 2, force=lambda q, v: -b * v, name="rotor"
    )
    gyrator = LagrangeDiracSystem(("qe", "phi"), lambda q, v: k * q[1] * v[0], name="gyrator")
    system = interconnect(
        [armature, rotor, gyrator],
        [connect("armature.qM", "gyrator.qe"), connect("rotor.theta", "gyrator.phi")],
        name="motor",
    )

    reduced_system = LagrangeDiracSystem(
        ("q", "theta"),
        lambda q, v: 0.5 * la * v[0] ** 2 + 0.5 * j * v[1] ** 2 + k * q[1] * v[0],
        force=lambda q, v: jnp.stack([vs - r * v[0], -b * v[1]]),
        name="motor",
    )
    # Exact flow of (q, θ, i, ω, 1): the constant source rides along as a fifth state.
    gen = np.zeros((5, 5))
    gen[0, 2] = gen[1, 3] = 1.0
    gen[2, 2], gen[2, 3], gen[2, 4] = -r / la, -k / la, vs / la
    gen[3, 2], gen[3, 3] = k / j, -b / j
    start = np.array([0.0, 0.0, 0.0, 0.0, 1.0])

    def exact_reduced(t):
        return linear_flow(gen, start, t)[:, :2]

    reduced = Problem(
        name="dc-motor-reduced",
        description="DC motor in (charge, angle) with a gyroscopic coupling term",
        system=reduced_system,
        q0=np.zeros(2),
        p0=np.zeros(2),  # p = (L_a i + K θ, J ω) = 0 at rest
        dt=dt,
        steps=steps,
        exact=exact_reduced,
    )

    return Problem(
        name="dc-motor",
        description="DC motor: armature circuit + rotor joined through a gyrator subsystem",
        system=system,
        q0=np.zeros(7),
        p0=np.zeros(7),
        dt=dt,
        steps=steps,
        exact=_torn_exact(exact_reduced),
        reference="Jacobs & Yoshimura 2014 (electromechanical interconnection)",
        parameters={"V": vs, "R": r, "La": la, "J": j, "b": b, "K": k},
        reduced=reduced,
        shared={"armature.qL": "q", "rotor.theta": "theta"},
        ports=(("armature.qM", "gyrator.qe"), ("rotor.theta", "gyrator.phi")),
    )


def dc_motor_driven(
    amplitude: float = 12.0,
    frequency: float = 20.0,
    resistance: float = 1.0,
    inductance: float = 0.5,
    inertia: float = 0.01,
    friction: float = 0.1,
    motor_constant: float = 0.05,
    dt: float = 0.001,
    steps: int = 2000,
) -> Problem:
    r"""The DC motor of ``dc_motor()`` with a prescribed voltage ``V(t) = V₀ sin ωt``.

    The armature's source branch carries the force ``V(t)`` (``force=F(q, v, t)``); the
    rest is unchanged. Reduced model ``L_a q̈ = V(t) − R q̇ − K θ̇``, ``J θ̈ = K q̇ − b θ̇``:
    its exact flow is a matrix exponential once ``(sin ωt, cos ωt)`` ride along as states
    (``ṡ = ω c``, ``ċ = −ω s``).
    """
    v0, om, r, la, j, b, k = (
        float(x)
        for x in (
            amplitude,
            frequency,
            resistance,
            inductance,
            inertia,
            friction,
            motor_constant,
        )
    )

    def source(t):
        return v0 * jnp.sin(om * t)

    armature = LagrangeDiracSystem(
        ("qS", "qR", "qL", "qM"),
        lambda q, v: 0.5 * la * v[2] ** 2,
        constraints=np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 1.0, -1.0, 0.0], [0.0, 0.0, 1.0, -1.0]]),
        force=lambda q, v, t: jnp.stack(
            [source(t) + 0.0 * v[0], -r * v[1], 0.0 * v[2], 0.0 * v[3]]
        ),
        name="armature",
        constraint_names=("KCL_SR", "KCL_RL", "KCL_LM"),
    )
    rotor = LagrangeDiracSystem(
        ("theta",), lambda q, v: 0.5 * j * v[0] ** 2, force=lambda q, v: -b * v, name="rotor"
    )
    gyrator = LagrangeDiracSystem(("qe", "phi"), lambda q, v: k * q[1] * v[0], name="gyrator")
    system = interconnect(
        [armature, rotor, gyrator],
        [connect("armature.qM", "gyrator.qe"), connect("rotor.theta", "gyrator.phi")],
        name="motor",
    )
    reduced_system = LagrangeDiracSystem(
        ("q", "theta"),
        lambda q, v: 0.5 * la * v[0] ** 2 + 0.5 * j * v[1] ** 2 + k * q[1] * v[0],
        force=lambda q, v, t: jnp.stack([source(t) - r * v[0], -b * v[1]]),
        name="motor",
    )
    # (q, θ, i, ω, sin ωt, cos ωt)
    gen = np.zeros((6, 6))
    gen[0, 2] = gen[1, 3] = 1.0
    gen[2, 2], gen[2, 3], gen[2, 4] = -r / la, -k / la, v0 / la
    gen[3, 2], gen[3, 3] = k / j, -b / j
    gen[4, 5], gen[5, 4] = om, -om
    start = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])

    def exact_reduced(t):
        return linear_flow(gen, start, t)[:, :2]

    reduced = Problem(
        name="dc-motor-driven-reduced",
        description="DC motor in (charge, angle) driven by V₀ sin ωt",
        system=reduced_system,
        q0=np.zeros(2),
        p0=np.zeros(2),
        dt=dt,
        steps=steps,
        exact=exact_reduced,
    )

    return Problem(
        name="dc-motor-driven",
        description="DC motor (armature + rotor + gyrator) with a prescribed voltage V₀ sin ωt",
        system=system,
        q0=np.zeros(7),
        p0=np.zeros(7),
        dt=dt,
        steps=steps,
        exact=_torn_exact(exact_reduced),
        reference="Jacobs & Yoshimura 2014 (electromechanical interconnection), driven",
        parameters={"V0": v0, "omega": om, "R": r, "La": la, "J": j, "b": b, "K": k},
        reduced=reduced,
        shared={"armature.qL": "q", "rotor.theta": "theta"},
        ports=(("armature.qM", "gyrator.qe"), ("rotor.theta", "gyrator.phi")),
    )
