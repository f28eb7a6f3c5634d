r"""Driven linear models: a forced damped oscillator and circuits with sine sources.

All of them reduce to the forced linear oscillator

    m ẍ + c ẋ + k x = u(t),    u(t) = F_c cos ωt + F_s sin ωt,

whose solution is the steady state ``x_p = a cos ωt + b sin ωt`` with

    (k − m ω²) a + c ω b = F_c,    −c ω a + (k − m ω²) b = F_s,

plus the free transient ``x_h = e^{−γτ} (A cos ω_d τ + B sin ω_d τ)``, ``τ = t − t₀``,
``γ = c/(2m)``, ``ω_d = √(k/m − γ²)`` (complex when overdamped; the result is real),
``A = x₀ − x_p(t₀)``, ``B = (ẋ₀ − ẋ_p(t₀) + γ A)/ω_d`` (:func:`forced_linear_solution`).

The circuits keep their branch charges as coordinates and Kirchhoff's current law as
constraint one-forms (so the constraint impulse ``Aᵀμ`` is present and ``traj.p`` differs
from ``traj.p_nodal`` under the midpoint rule); a voltage source ``V(t)`` is a force
``+V(t)`` on its branch charge, a resistor ``−R v``.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model.interaction import connect
from ..model.interconnect import interconnect
from ..model.system import LagrangeDiracSystem
from ._problem import Problem, linear_flow


def forced_linear_solution(m, c, k, force_cos, force_sin, omega, x0, v0, t, t0=0.0):
    """``(x(t), ẋ(t))`` of ``m ẍ + c ẋ + k x = F_c cos ωt + F_s sin ωt``, ``x(t₀) = x₀``,
    ``ẋ(t₀) = v₀`` (closed form; see the module documentation)."""
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    det_k = k - m * omega**2
    a, b = np.linalg.solve(
        np.array([[det_k, c * omega], [-c * omega, det_k]]), np.array([force_cos, force_sin])
    )

    def steady(s):
        return (
            a * np.cos(omega * s) + b * np.sin(omega * s),
            omega * (b * np.cos(omega * s) - a * np.sin(omega * s)),
        )

    gamma = c / (2.0 * m)
    omega_d = np.sqrt(complex(k / m - gamma**2))
    if abs(omega_d) < 1e-9 * np.sqrt(k / m):
        raise ValueError("critically damped: the closed form here needs ω_d ≠ 0.")
    xp0, vp0 = steady(t0)
    big_a = x0 - xp0
    big_b = (v0 - vp0 + gamma * big_a) / omega_d
    tau = t - t0
    decay = np.exp(-gamma * tau)
    cos_d, sin_d = np.cos(omega_d * tau), np.sin(omega_d * tau)
    xh = decay * (big_a * cos_d + big_b * sin_d)
    vh = -gamma * xh + decay * omega_d * (big_b * cos_d - big_a * sin_d)
    xp, vp = steady(t)
    return np.real(xh) + xp, np.real(vh) + vp


def forced_oscillator(
    mass: float = 1.0,
    stiffness: float = 4.0,
    damping: float = 0.3,
    amplitude: float = 1.5,
    frequency: float = 3.0,
    q0: float = 1.0,
    p0: float = 0.0,
    t0: float = 0.0,
    dt: float = 0.01,
    steps: int = 2000,
) -> Problem:
    r"""``m ẍ + c ẋ + k x = F₀ cos ωt``: ``L = ½ m v² − ½ k q²``, ``F(q, v, t) = −c v + F₀ cos ωt``.

    Closed form: :func:`forced_linear_solution` (transient + steady state) from
    ``x(t₀) = q₀``, ``ẋ(t₀) = p₀/m``. Power balance ``dE/dt = F₀ cos ωt · v − c v²``.
    """
    m, k, c, f0, om = (float(x) for x in (mass, stiffness, damping, amplitude, frequency))
    system = LagrangeDiracSystem(
        ("x",),
        lambda q, v: 0.5 * m * v @ v - 0.5 * k * q @ q,
        force=lambda q, v, t: -c * v + f0 * jnp.cos(om * t),
        name="forced_oscillator",
    )

    def exact(t):
        x, _ = forced_linear_solution(m, c, k, f0, 0.0, om, q0, p0 / m, t, t0)
        return x[:, None]

    return Problem(
        name="forced-oscillator",
        description="Damped oscillator driven by F₀ cos ωt (closed form: transient + steady)",
        system=system,
        q0=np.array([q0]),
        p0=np.array([p0]),
        dt=dt,
        steps=steps,
        t0=float(t0),
        exact=exact,
        reference="textbook (forced damped harmonic oscillator)",
        parameters={"m": m, "k": k, "c": c, "F0": f0, "omega": om},
    )


def rlc_sine(
    resistance: float = 0.5,
    inductance: float = 0.25,
    capacitance: float = 0.5,
    amplitude: float = 2.0,
    frequency: float = 5.0,
    charge: float = 0.2,
    current: float = 0.0,
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    r"""A series RLC loop driven by ``V(t) = V₀ sin ωt``.

    Coordinates: the branch charges ``(q^V, q^R, q^L, q^C)``; KCL of the series loop
    ``v^V = v^R = v^L = v^C`` (three one-forms); ``L = ½ l (v^L)² − (q^C)²/(2C)``;
    force ``(V(t), −R v^R, 0, 0)``. Eliminating the multipliers (``μ`` are the branch
    voltages) gives ``l Q̈ + R Q̇ + Q/C = V₀ sin ωt`` for the capacitor charge ``Q = q^C``;
    every branch charge moves with it, ``q^i(t) = q^i_0 + Q(t) − Q(0)``. Closed form:
    :func:`forced_linear_solution` with ``m = l``, ``c = R``, ``k = 1/C``.

    The loop current ``i`` is the sum of the momenta over the loop divided by ``l``
    (the multipliers cancel in the sum), ``Σ p = l i``.
    """
    r, ell, cap, v0, om = (
        float(x) for x in (resistance, inductance, capacitance, amplitude, frequency)
    )

    def lagrangian(q, v):
        return 0.5 * ell * v[2] ** 2 - q[3] ** 2 / (2.0 * cap)

    def force(q, v, t):
        return jnp.stack([v0 * jnp.sin(om * t) + 0.0 * v[0], -r * v[1], 0.0 * v[2], 0.0 * v[3]])

    system = LagrangeDiracSystem(
        ("qV", "qR", "qL", "qC"),
        lagrangian,
        constraints=np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 1.0, -1.0, 0.0], [0.0, 0.0, 1.0, -1.0]]),
        force=force,
        name="rlc_sine",
        constraint_names=("KCL_VR", "KCL_RL", "KCL_LC"),
    )
    q0 = np.array([0.0, 0.0, 0.0, charge])
    p0 = np.array([0.0, 0.0, ell * current, 0.0])

    def exact(t):
        x, _ = forced_linear_solution(ell, r, 1.0 / cap, 0.0, v0, om, charge, current, t)
        return q0[None, :] + (x - charge)[:, None]

    return Problem(
        name="rlc-sine",
        description="Series RLC loop driven by a sine source V₀ sin ωt (closed form)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        exact=exact,
        reference="textbook (driven series RLC)",
        parameters={"R": r, "l": ell, "C": cap, "V0": v0, "omega": om},
    )


def rlc_sine_current(problem: Problem, t) -> np.ndarray:
    """The exact loop current ``i(t)`` of an :func:`rlc_sine` problem."""
    prm = problem.parameters
    _, v = forced_linear_solution(
        prm["l"],
        prm["R"],
        1.0 / prm["C"],
        0.0,
        prm["V0"],
        prm["omega"],
        problem.q0[3],
        problem.p0[2] / prm["l"],
        t,
    )
    return v


def _sine_source_generator(block: np.ndarray, source_row: np.ndarray, omega: float):
    """Augment ``ẋ = G x + s(t) e`` by ``(s, c) = (sin ωt, cos ωt)``: a linear flow."""
    d = block.shape[0]
    gen = np.zeros((d + 2, d + 2))
    gen[:d, :d] = block
    gen[:d, d] = source_row
    gen[d, d + 1] = omega
    gen[d + 1, d] = -omega
    return gen


def rlc_sine_torn(
    resistance: float = 1.0,
    inductance: float = 0.75,
    capacitance: float = 3.0,
    amplitude: float = 2.0,
    frequency: float = 2.0,
    dt: float = 0.05,
    steps: int = 400,
) -> Problem:
    r"""The paper's parallel RLC circuit, torn, with a sine source in series with the resistor.

    ``src``: ``(q^V, q^R, q^L, q^{S1})``, ``L¹ = ½ l (v^L)²``, KCL ``v^V − v^R = 0`` and
    ``v^R − v^L − v^{S1} = 0``, force ``(V₀ sin ωt, −R v^R, 0, 0)`` — the driven piece.
    ``cap``: ``(q^{S2}, q^C)``, ``L² = −(q^C)²/(2C)``, KCL ``v^C − v^{S2} = 0``.
    Interaction ``v^{S1} = v^{S2}``.

    With the node voltage ``u = q^C/C``: ``i^R = (V − u)/R``, ``l i̇^L = u``,
    ``q̇^C = i^R − i^L`` — a linear flow once ``(sin ωt, cos ωt)`` ride along as states.
    """
    r, ell, cap, v0, om = (
        float(x) for x in (resistance, inductance, capacitance, amplitude, frequency)
    )
    src = LagrangeDiracSystem(
        ("qV", "qR", "qL", "qS1"),
        lambda q, v: 0.5 * ell * v[2] ** 2,
        constraints=np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 1.0, -1.0, -1.0]]),
        force=lambda q, v, t: jnp.stack(
            [v0 * jnp.sin(om * t) + 0.0 * v[0], -r * v[1], 0.0 * v[2], 0.0 * v[3]]
        ),
        name="src",
        constraint_names=("KCL_VR", "KCL"),
    )
    capacitor = LagrangeDiracSystem(
        ("qS2", "qC"),
        lambda q, v: -(q[1] ** 2) / (2.0 * cap),
        constraints=np.array([[-1.0, 1.0]]),
        name="cap",
        constraint_names=("KCL",),
    )
    system = interconnect([src, capacitor], [connect("src.qS1", "cap.qS2")], name="rlc_sine")

    reduced_system = LagrangeDiracSystem(
        ("qV", "qR", "qL", "qC"),
        lambda q, v: 0.5 * ell * v[2] ** 2 - q[3] ** 2 / (2.0 * cap),
        constraints=np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 1.0, -1.0, -1.0]]),
        force=lambda q, v, t: jnp.stack(
            [v0 * jnp.sin(om * t) + 0.0 * v[0], -r * v[1], 0.0 * v[2], 0.0 * v[3]]
        ),
        name="rlc_sine",
        constraint_names=("KCL_VR", "KCL"),
    )
    # (qR, qL, qC, iL) with the source V₀ s(t): q̇R = (V − qC/C)/R, q̇L = iL,
    # q̇C = (V − qC/C)/R − iL, l i̇L = qC/C.
    block = np.zeros((4, 4))
    block[0, 2] = -1.0 / (r * cap)
    block[1, 3] = 1.0
    block[2, 2], block[2, 3] = -1.0 / (r * cap), -1.0
    block[3, 2] = 1.0 / (ell * cap)
    gen = _sine_source_generator(block, np.array([v0 / r, 0.0, v0 / r, 0.0]), om)
    start = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])  # at rest; sin 0 = 0, cos 0 = 1

    def exact_reduced(t):
        x = linear_flow(gen, start, t)
        return np.stack([x[:, 0], x[:, 0], x[:, 1], x[:, 2]], axis=1)

    reduced = Problem(
        name="rlc-sine-parallel",
        description="Parallel RLC with a sine source in the resistor branch (hand-built)",
        system=reduced_system,
        q0=np.zeros(4),
        p0=np.zeros(4),
        dt=dt,
        steps=steps,
        exact=exact_reduced,
    )

    def exact(t):
        x = exact_reduced(t)
        return np.stack([x[:, 0], x[:, 1], x[:, 2], x[:, 3], x[:, 3], x[:, 3]], axis=1)

    return Problem(
        name="rlc-sine-torn",
        description="Paper §5.2 RLC torn in two, driven by a sine source in the RL piece",
        system=system,
        q0=np.zeros(6),
        p0=np.zeros(6),
        dt=dt,
        steps=steps,
        exact=exact,
        reference="Parks & Leok §5.2 with a source added",
        parameters={"R": r, "l": ell, "C": cap, "V0": v0, "omega": om},
        reduced=reduced,
        shared={"src.qV": "qV", "src.qR": "qR", "src.qL": "qL", "cap.qC": "qC"},
        ports=(("src.qS1", "cap.qS2"),),
    )


def rlc_ladder(
    resistance: float = 1.0,
    inductances=(0.5, 0.4, 0.3),
    capacitances=(0.3, 0.4, 0.5),
    amplitude: float = 1.0,
    frequency: float = 3.0,
    dt: float = 0.01,
    steps: int = 200,
) -> Problem:
    r"""A 3-stage LC ladder fed through a resistor by ``V(t) = V₀ sin ωt``.

    Branch charges ``(q^R, q^{L1}, q^{C1}, q^{L2}, q^{C2}, q^{L3}, q^{C3})``; KCL at the
    four nodes ``v^R − v^{L1} = 0``, ``v^{L_j} − v^{C_j} − v^{L_{j+1}} = 0``,
    ``v^{L3} − v^{C3} = 0``; ``L = Σ ½ l_j (v^{L_j})² − Σ (q^{C_j})²/(2C_j)``; force
    ``(V(t) − R v^R, 0, …)``. The multipliers are the node voltages
    (``μ_j = −q^{C_j}/C_j``), so every inductor momentum line carries a constraint impulse.
    Reduced flow: ``l₁ i̇₁ = V − R i₁ − u₁``, ``l_j i̇_j = u_{j−1} − u_j``,
    ``q̇^{C_j} = i_j − i_{j+1}`` (``i₄ = 0``), ``u_j = q^{C_j}/C_j``.

    :func:`rlc_ladder_state` gives the exact charges and currents: the inductor momenta
    ``l_j i_j`` are what ``traj.p_nodal`` approximates to second order under midpoint.
    """
    r, v0, om = float(resistance), float(amplitude), float(frequency)
    ells = tuple(float(x) for x in inductances)
    caps = tuple(float(x) for x in capacitances)

    def lagrangian(q, v):
        kinetic = sum(0.5 * ell * v[1 + 2 * j] ** 2 for j, ell in enumerate(ells))
        return kinetic - sum(q[2 + 2 * j] ** 2 / (2.0 * c) for j, c in enumerate(caps))

    def force(q, v, t):
        return jnp.concatenate([jnp.atleast_1d(v0 * jnp.sin(om * t) - r * v[0]), 0.0 * v[1:]])

    forms = np.zeros((4, 7))
    forms[0, 0], forms[0, 1] = 1.0, -1.0
    for j in range(2):
        forms[1 + j, 1 + 2 * j], forms[1 + j, 2 + 2 * j], forms[1 + j, 3 + 2 * j] = 1, -1, -1
    forms[3, 5], forms[3, 6] = 1.0, -1.0
    coords = ("qR", "qL1", "qC1", "qL2", "qC2", "qL3", "qC3")
    system = LagrangeDiracSystem(
        coords,
        lagrangian,
        constraints=forms,
        force=force,
        name="ladder",
        constraint_names=("KCL0", "KCL1", "KCL2", "KCL3"),
    )
    return Problem(
        name="rlc-ladder",
        description="3-stage LC ladder fed through a resistor by a sine source",
        system=system,
        q0=np.zeros(7),
        p0=np.zeros(7),
        dt=dt,
        steps=steps,
        exact=lambda t: rlc_ladder_state(r, ells, caps, v0, om, t)[0],
        reference="textbook (LC ladder network)",
        parameters={"R": r, "l": ells, "C": caps, "V0": v0, "omega": om},
    )


def rlc_ladder_state(r, ells, caps, v0, om, t):
    """``(q, i)`` of :func:`rlc_ladder` from rest at t = 0: branch charges (T, 7) and
    inductor currents (T, 3), by the exact flow of the reduced linear system."""
    # state (qR, qL1, qC1, qL2, qC2, qL3, qC3, i1, i2, i3)
    block = np.zeros((10, 10))
    block[0, 7] = 1.0
    for j in range(3):
        block[1 + 2 * j, 7 + j] = 1.0  # q̇L_j = i_j
        block[2 + 2 * j, 7 + j] = 1.0  # q̇C_j = i_j − i_{j+1}
        if j < 2:
            block[2 + 2 * j, 8 + j] = -1.0
    l1, l2, l3 = ells
    c1, c2, c3 = caps
    block[7, 7], block[7, 2] = -r / l1, -1.0 / (l1 * c1)
    block[8, 2], block[8, 4] = 1.0 / (l2 * c1), -1.0 / (l2 * c2)
    block[9, 4], block[9, 6] = 1.0 / (l3 * c2), -1.0 / (l3 * c3)
    source = np.zeros(10)
    source[7] = v0 / l1
    gen = _sine_source_generator(block, source, om)
    start = np.zeros(12)
    start[11] = 1.0
    x = linear_flow(gen, start, t)
    return x[:, :7], x[:, 7:10]
