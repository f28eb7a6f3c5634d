r"""Circuits as Lagrange–Dirac systems: charges are coordinates, currents velocities.

``L`` = magnetic energy of the inductors − electric energy of the capacitors; it has no
velocity term for resistor and capacitor charges, so it is degenerate, and Kirchhoff's
current law enters as constraint one-forms.

**The resistor's sign.** The resistor force is ``F = (−R v^R, 0, 0)``. By the discrete
Lagrange–d'Alembert principle the left-point rule gives ``f_d^− = h F(q_k, v_k)``, which
enters as ``p_k = −D₁L_d − f_d^− + …``, i.e. ``p_k^R = +R (q_{k+1}^R − q_k^R) + μ``. The
paper (§5.2) prints ``f_d^− = −h F`` and ``p_k^R = −R (q_{k+1}^R − q_k^R) + μ₁``: with that
sign the resistor *injects* energy (a negative resistance) and the circuit's energy
grows. diracvi uses the physical sign; ``tests/test_energy.py`` shows both.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..model.interaction import connect
from ..model.interconnect import interconnect
from ..model.system import LagrangeDiracSystem
from ._problem import Problem, linear_flow


def rlc_circuit(
    resistance: float = 1.0,
    inductance: float = 0.75,
    capacitance: float = 3.0,
    dt: float = 0.1,
    steps: int = 400,
) -> Problem:
    r"""The paper's parallel RLC circuit (§5.2), monolithic form.

    Coordinates ``(q^R, q^L, q^C)``; ``L = ½ l (v^L)² − (q^C)²/(2C)``; KCL
    ``v^R − v^L − v^C = 0`` (one-form ``(1, −1, −1)``); resistor force ``(−R v^R, 0, 0)``.
    Paper data: ``R = 1``, ``l = 0.75``, ``C = 3``, ``q_0 = 0``, ``p_0^L = 10 l``,
    ``h = 0.1``, 400 steps.
    """
    r, ell, cap = float(resistance), float(inductance), float(capacitance)

    def lagrangian(q, v):
        return 0.5 * ell * v[1] ** 2 - q[2] ** 2 / (2.0 * cap)

    def force(q, v):
        return jnp.stack([-r * v[0], 0.0 * v[1], 0.0 * v[2]])

    system = LagrangeDiracSystem(
        ("qR", "qL", "qC"),
        lagrangian,
        constraints=np.array([[1.0, -1.0, -1.0]]),
        force=force,
        name="rlc",
        constraint_names=("KCL",),
    )
    # Exact flow of the index-reduced ODE in (qR, qL, qC, vL): μ = R v^R = −q^C/C,
    # l v̇^L = −μ, v^C = v^R − v^L.
    gen = np.zeros((4, 4))
    gen[0, 2] = -1.0 / (r * cap)
    gen[1, 3] = 1.0
    gen[2, 2], gen[2, 3] = -1.0 / (r * cap), -1.0
    gen[3, 2] = 1.0 / (ell * cap)
    q0 = np.zeros(3)
    p0 = np.array([0.0, 10.0 * ell, 0.0])

    def exact(t):
        return linear_flow(gen, np.array([0.0, 0.0, 0.0, 10.0]), t)[:, :3]

    return Problem(
        name="rlc",
        description="Paper §5.2: parallel RLC circuit, monolithic (degenerate L, KCL, resistor)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        exact=exact,
        reference="Parks & Leok §5.2 (monolithic equations)",
        notes="The paper's printed resistor sign is anti-dissipative; see module docs.",
        parameters={"R": r, "l": ell, "C": cap},
    )


def lc_circuit(
    inductance: float = 0.5,
    capacitances=(1.0, 3.0),
    charge: float = 1.0,
    current: float = 0.0,
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    r"""One inductor and two capacitors in parallel.

    Coordinates ``(q^L, q^{C1}, q^{C2})``; ``L = ½ l (v^L)² − (q^{C1})²/(2C_1) −
    (q^{C2})²/(2C_2)``; KCL ``v^L − v^{C1} − v^{C2} = 0``. The capacitor loop forces
    equal voltages ``q^{C1}/C_1 = q^{C2}/C_2`` (a secondary constraint), and the pair
    behaves as one capacitor ``C_1 + C_2``: ``ω₀ = 1/√(l (C_1 + C_2))``.

    Only ``"midpoint"`` can step it. Under the left-point rule the capacitor terms of
    ``L_d`` depend on ``q_k`` alone, so both capacitor momentum equations read
    ``p_k^{Ci} = h q_k^{Ci}/C_i − μ`` — two equations for the one unknown μ and nothing
    for ``q_{k+1}``: the step Jacobian is singular, and diracvi says so before stepping.
    """
    ell = float(inductance)
    c1, c2 = (float(c) for c in capacitances)

    def lagrangian(q, v):
        return 0.5 * ell * v[0] ** 2 - q[1] ** 2 / (2.0 * c1) - q[2] ** 2 / (2.0 * c2)

    system = LagrangeDiracSystem(
        ("qL", "qC1", "qC2"),
        lagrangian,
        constraints=np.array([[1.0, -1.0, -1.0]]),
        name="lc",
        constraint_names=("KCL",),
    )
    ctot = c1 + c2
    q0 = np.array([0.0, charge * c1 / ctot, charge * c2 / ctot])  # equal voltages
    p0 = np.array([ell * current, 0.0, 0.0])
    # Exact flow in (qL, Q = qC1 + qC2, vL): q̇L = vL, Q̇ = vL, l v̇L = −Q/(C1 + C2).
    gen = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, -1.0 / (ell * ctot), 0.0]])

    def exact(t):
        x = linear_flow(gen, np.array([0.0, charge, current]), t)
        return np.stack([x[:, 0], x[:, 1] * c1 / ctot, x[:, 1] * c2 / ctot], axis=1)

    return Problem(
        name="lc",
        description="An inductor and two capacitors in parallel (capacitor loop; midpoint only)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        exact=exact,
        discretizations=("midpoint",),
        reference="Yoshimura & Marsden 2006 (LC circuits as Lagrange–Dirac systems)",
        notes="The left-point ('retraction') step is singular for a capacitor loop.",
        parameters={"l": ell, "C1": c1, "C2": c2},
    )


def rlc_torn(
    resistance: float = 1.0,
    inductance: float = 0.75,
    capacitance: float = 3.0,
    dt: float = 0.1,
    steps: int = 400,
) -> Problem:
    r"""The paper's RLC circuit torn into two primitive circuits (§5.2).

    ``rl``: ``(q^R, q^L, q^{S1})``, ``L^1 = ½ l (v^L)²``, KCL ``v^R − v^L − v^{S1} = 0``,
    resistor force. ``cap``: ``(q^{S2}, q^C)``, ``L^2 = −(q^C)²/(2C)``, KCL
    ``v^C − v^{S2} = 0``. Interaction ``v^{S1} = v^{S2}``.

    The paper writes ``ω₁ = dq^R − dq^L + dq^{S1}`` in words and ``(1, −1, −1)`` in
    coordinates, and its ``ω_{d+,1}`` has ``+(q^{S1}_{k+1} − q^{S1}_k)``; only
    ``(1, −1, −1)`` matches its distribution ``v^R − v^L − v^{S1} = 0`` and its step
    equations, so that is what is used here. Its ``p_k^{S2} = μ₂ − λ``,
    ``p_k^C = … − μ₂`` use ``ω₂ = (1, −1)`` rather than the stated ``(−1, 1)`` — the same
    constraint with μ₂ of opposite sign, harmless.
    """
    r, ell, cap = float(resistance), float(inductance), float(capacitance)
    rl = LagrangeDiracSystem(
        ("qR", "qL", "qS1"),
        lambda q, v: 0.5 * ell * v[1] ** 2,
        constraints=np.array([[1.0, -1.0, -1.0]]),
        force=lambda q, v: jnp.stack([-r * v[0], 0.0 * v[1], 0.0 * v[2]]),
        name="rl",
        constraint_names=("KCL",),
    )
    capacitor = LagrangeDiracSystem(
        ("qS2", "qC"),
        lambda q, v: -(q[1] ** 2) / (2.0 * cap),
        constraints=np.array([[-1.0, 1.0]]),
        name="cap",
        constraint_names=("KCL",),
    )
    system = interconnect([rl, capacitor], [connect("rl.qS1", "cap.qS2")], name="rlc")
    return Problem(
        name="rlc-torn",
        description="Paper §5.2: the RLC circuit as an RL loop joined to a capacitor",
        system=system,
        q0=np.zeros(5),
        p0=np.array([0.0, 10.0 * ell, 0.0, 0.0, 0.0]),
        dt=dt,
        steps=steps,
        reference="Parks & Leok §5.2, eqs. (forced_int_eqns)",
        notes="Physical resistor sign (the paper's printed sign is anti-dissipative).",
        parameters={"R": r, "l": ell, "C": cap},
        reduced=rlc_circuit(r, ell, cap, dt=dt, steps=steps),
        shared={"rl.qR": "qR", "rl.qL": "qL", "cap.qC": "qC"},
        ports=(("rl.qS1", "cap.qS2"),),
    )


class _RLCLagrangian(eqx.Module):
    """``L = ½ l (v^L)² − (q^C)²/(2C)`` with ``l`` and ``C`` as array leaves."""

    inductance: np.ndarray
    capacitance: np.ndarray

    def __call__(self, q, v):
        return 0.5 * self.inductance * v[1] ** 2 - q[2] ** 2 / (2.0 * self.capacitance)


class _Resistor(eqx.Module):
    """The resistor's force ``(−R v^R, 0, 0)`` with ``R`` as an array leaf."""

    resistance: np.ndarray

    def __call__(self, q, v):
        return jnp.stack([-self.resistance * v[0], 0.0 * v[1], 0.0 * v[2]])


def build_rlc(R: float = 1.0, C: float = 3.0, l: float = 0.75, i0: float = 10.0):  # noqa: E741
    r"""``(system, q0, p0)`` of the paper's monolithic RLC circuit, for :func:`diracvi.sweep`.

    The same equations as :func:`rlc_circuit`, but the Lagrangian and the resistor are
    ``equinox.Module`` callables whose parameters are array leaves: circuits that differ
    only in ``R``, ``C``, ``l`` share one compiled program, so a sweep over them is one
    vmapped batch. The initial state is ``q = 0`` and an inductor current ``i0``
    (``p^L = l i0``).
    """
    system = LagrangeDiracSystem(
        ("qR", "qL", "qC"),
        _RLCLagrangian(np.asarray(float(l)), np.asarray(float(C))),
        constraints=np.array([[1.0, -1.0, -1.0]]),
        force=_Resistor(np.asarray(float(R))),
        name="rlc",
        constraint_names=("KCL",),
    )
    return system, np.zeros(3), np.array([0.0, float(l) * float(i0), 0.0])
