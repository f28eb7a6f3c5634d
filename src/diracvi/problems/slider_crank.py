r"""Simeon's flexible slider crank: a rigid crank, an elastic connecting rod, a sliding block.

The problem "Slider Crank" of the Test Set for IVP Solvers (Bari; F. Mazzia and
C. Magherini, http://www.dm.uniba.it/~testset/, source
http://www.dm.uniba.it/~testset/src/problems/crank.f, revision
``$Id: crank.F,v 1.2 2006/10/02 10:29:14 testset Exp $``; model by B. Simeon, "Modelling a
flexible slider crank mechanism by a mixed system of DAEs and PDEs", Math. Modelling of
Systems 2, 1–18 (1996)). Written here from its equations, in JAX.

Coordinates ``x = (φ₁, φ₂, x₃, q₁, q₂, q₃, q₄)``: the crank angle, the rod's angle, the
block's position, two lateral modes (``w(ξ) = q₁ sin(πξ/ℓ₂) + q₂ sin(2πξ/ℓ₂)``) and two
longitudinal nodes (a quadratic ansatz, ``q₄`` the elongation at the rod's end) of the rod
in its floating frame. The kinetic energy of crank, rod (density ``ρ``, section ``b×h``)
and block is ``½ ẋᵀ M(x) ẋ`` with the test set's mass matrix

    M₁₁ = J₁ + m₂ℓ₁²,   M₁₂ = ½ℓ₁ℓ₂m₂ cos φ₁₂ + ρℓ₁ (sin φ₁₂ c₂ᵀq + cos φ₁₂ c₁ᵀq),
    M₂₂ = J₂ + qᵀM_q q + 2ρ c₁₂ᵀq,   M₃₃ = m₃,   M_qq = M_q,
    M₁,q = ρℓ₁ (cos φ₁₂ c₂ − sin φ₁₂ c₁)ᵀ,   M₂,q = ρ (c₂₁ + B_qᵀq)ᵀ,   (φ₁₂ = φ₁ − φ₂)

so the Lagrangian is

    L(x, ẋ) = ½ ẋᵀ M(x) ẋ − ½ qᵀ K_q q  [ − W(q) ],

with the rod's stiffness ``K_q`` and, with ``nonlinear_stiffness=True`` (the test set's
``ipar(1) = 1``), the cubic strain energy
``W = k (½q₁²q₄ + 2q₂²q₄ + 4c q₁q₂q₃ − 2c q₁q₂q₄)``, ``k = Ebhπ²/(2ℓ₂²)``, ``c = 80/(9π²)``,
whose gradient is the test set's nonlinear stiffness term. With ``damping=True``
(``ipar(2) = 1``) the rod's modes feel the dissipative force ``F = −(0, 0, 0, D_q q̇)``.
The test set writes out the quadratic-velocity terms ``f = ∂T/∂x − Ṁ ẋ``; the same terms
JAX derives from this ``L`` equal them to round-off (``tests/test_slider_crank.py``).

Three holonomic rows close the mechanism (the rod's end, elongated by ``q₄``, at the
block on the axis ``y = 0``) and drive the crank at ``ω = 150 rad/s``:

    g₁ = ℓ₁ sin φ₁ + (ℓ₂ + q₄) sin φ₂,   g₂ = x₃ − ℓ₁ cos φ₁ − (ℓ₂ + q₄) cos φ₂,
    g₃ = φ₁ − ω t.

The engine holds them in position form (index 3); the test set integrates their
velocity form (index 2), which has the same solution. Gravity is zero, as in the test
set, and ``π`` is the test set's ``3.1415927`` (it enters ``K_q``, ``B_q``, ``c₂``, ``c₂₁``).

The published reference at ``t = 0.1`` (the test set's ``SOLN``, for the linear
stiffness and no damping, from the "close to smooth motion" initial values ``INIT``) is
:data:`REFERENCE_Q`, :data:`REFERENCE_V`. The test set gives ``INIT`` to nine digits, off
the rows by 2.0e-10 (``g₂``) and 1.2e-8 (``ġ₁``); :data:`Q0`, :data:`V0` are those values
with ``x₃`` and ``φ̇₂`` solved from ``g₂ = 0`` and ``ġ₁ = 0`` (changes of 2.0e-10 and
4.0e-8).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..model.system import LagrangeDiracSystem
from ._problem import Problem

#: the test set's data set (SI units); ``pi`` is its 3.1415927, kept for its reference
PARAMETERS = {
    "m1": 0.36, "m2": 0.151104, "m3": 0.075552, "l1": 0.15, "l2": 0.30,
    "j1": 0.002727, "j2": 0.0045339259, "pi": 3.1415927, "E": 0.20e12, "b": 0.0080,
    "h": 0.0080, "rho": 7870.0, "omega": 150.0,
}  # fmt: skip

COORDS = ("phi1", "phi2", "x3", "q1", "q2", "q3", "q4")


def _rod_matrices():
    """The rod's Galerkin data: ``M_q``, ``K_q``, ``B_q``, ``c₁``, ``c₂``, ``c₁₂``,
    ``c₂₁`` and the damping ``D_q`` (test set: ``MQ``, ``KQ``, ``BQ``, ``c1`` …, ``DQ``).
    ``M_q``, ``K_q`` carry ``ρ`` and ``E``; the ``c``'s and ``B_q`` are volume integrals
    that the mass matrix multiplies by ``ρ``."""
    P = PARAMETERS
    pi, l2 = P["pi"], P["l2"]
    facm = P["rho"] * P["b"] * P["h"] * l2  # the rod's mass
    fack = P["E"] * P["b"] * P["h"] / l2  # its axial stiffness
    facb = P["b"] * P["h"] * l2  # its volume
    mq = facm * np.array([[0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 8.0, 1.0], [0, 0, 1.0, 2.0]])
    slender = (P["h"] / l2) ** 2  # bending: E I / ℓ³ = E b h (h/ℓ)² / (12 ℓ)
    kq = fack * np.array(
        [
            [pi**4 / 24 * slender, 0, 0, 0],
            [0, pi**4 * 2 / 3 * slender, 0, 0],
            [0, 0, 16 / 3, -8 / 3],
            [0, 0, -8 / 3, 7 / 3],
        ]
    )
    # B_q = ∫ (φ_lateralᵀ φ_axial − φ_axialᵀ φ_lateral) dV: skew, the rod's gyroscopic coupling
    bq = np.zeros((4, 4))
    bq[0, 2] = -facb * 16 / pi**3
    bq[0, 3] = facb * (8 / pi**3 - 1 / pi)
    bq[1, 3] = facb * 0.5 / pi
    bq = bq - bq.T
    c1 = facb * np.array([0, 0, 2 / 3, 1 / 6])  # ∫ axial shapes dV
    c2 = facb * np.array([2 / pi, 0, 0, 0])  # ∫ lateral shapes dV
    c12 = l2 * facb * np.array([0, 0, 1 / 3, 1 / 6])  # ∫ ξ · axial shapes dV
    c21 = l2 * facb * np.array([1 / pi, -0.5 / pi, 0, 0])  # ∫ ξ · lateral shapes dV
    # the test set's 0.5 % modal damping (its DQ(3,4) and DQ(4,3) differ in the 16th digit;
    # the symmetric mean is taken)
    d34 = -0.5 * 0.5 * (2.62688487992052e2 + 2.626884879920526e2)
    dq = np.array(
        [
            [5.0, 0, 0, 0],
            [0, 25.0, 0, 0],
            [0, 0, 0.5 * 2.308375455264791e2, d34],
            [0, 0, d34, 0.5 * 4.217421837156818e2],
        ]
    )
    return {"mq": mq, "kq": kq, "bq": bq, "c1": c1, "c2": c2, "c12": c12, "c21": c21, "dq": dq}


#: the rod's Galerkin matrices and vectors by name (:func:`_rod_matrices`)
ROD = _rod_matrices()


def mass_matrix(x):
    """``M(x)``, 7×7 symmetric (module docstring)."""
    P, R = PARAMETERS, ROD
    rho, l1 = P["rho"], P["l1"]
    q = x[3:]
    s12, c12 = jnp.sin(x[0] - x[1]), jnp.cos(x[0] - x[1])
    m12 = 0.5 * l1 * P["l2"] * P["m2"] * c12 + rho * l1 * (s12 * R["c2"] @ q + c12 * R["c1"] @ q)
    m22 = P["j2"] + q @ R["mq"] @ q + 2 * rho * R["c12"] @ q
    row1 = rho * l1 * (c12 * R["c2"] - s12 * R["c1"])
    row2 = rho * (R["c21"] + q @ R["bq"])
    z = jnp.zeros((), dtype=x.dtype)
    rigid = jnp.stack(
        [
            jnp.stack([P["j1"] + P["m2"] * l1**2 + z, m12, z]),
            jnp.stack([m12, m22, z]),
            jnp.stack([z, z, P["m3"] + z]),
        ]
    )
    coupling = jnp.stack([row1, row2, jnp.zeros(4, dtype=x.dtype)])
    return jnp.block([[rigid, coupling], [coupling.T, jnp.asarray(R["mq"])]])


def strain_energy(x, nonlinear: bool = False):
    """``½ qᵀ K_q q``, plus the cubic ``W(q)`` with ``nonlinear`` (module docstring)."""
    q = x[3:]
    energy = 0.5 * q @ ROD["kq"] @ q
    if nonlinear:
        P = PARAMETERS
        k = 0.5 * P["E"] * P["b"] * P["h"] / P["l2"] ** 2 * P["pi"] ** 2
        c = 80.0 / (P["pi"] ** 2 * 9.0)
        q1, q2, q3, q4 = q[0], q[1], q[2], q[3]
        energy = energy + k * (
            0.5 * q1**2 * q4 + 2 * q2**2 * q4 + 4 * c * q1 * q2 * q3 - 2 * c * q1 * q2 * q4
        )
    return energy


def closure(x, t):
    """The three holonomic rows ``g(x, t)`` (module docstring)."""
    P = PARAMETERS
    phi1, phi2, x3, q4 = x[0], x[1], x[2], x[6]
    rod = P["l2"] + q4
    return jnp.stack(
        [
            P["l1"] * jnp.sin(phi1) + rod * jnp.sin(phi2),
            x3 - P["l1"] * jnp.cos(phi1) - rod * jnp.cos(phi2),
            phi1 - P["omega"] * t,
        ]
    )


def _initial_state():
    """The test set's ``INIT`` ("close to smooth motion"), made consistent: ``x₃`` from
    ``g₂ = 0`` and ``φ̇₂`` from ``ġ₁ = 0`` (both change in the ninth digit)."""
    P = PARAMETERS
    q = np.array([0.0, 0.0, 0.450016933, 0.0, 0.0, 0.103339863e-4, 0.169327969e-4])
    v = np.array(
        [
            0.150000000e3,
            -0.749957670e2,
            -0.268938672e-5,
            0.444896105,
            0.463434311e-2,
            -0.178591076e-5,
            -0.268938672e-5,
        ]
    )
    q[2] = P["l1"] + P["l2"] + q[6]  # φ₁ = φ₂ = 0: the block at ℓ₁ + ℓ₂ + q₄
    v[1] = -P["l1"] * v[0] / (P["l2"] + q[6])  # ġ₁ = ℓ₁ φ̇₁ + (ℓ₂ + q₄) φ̇₂ = 0 at φ = 0
    return q, v


#: consistent initial positions and velocities (:func:`_initial_state`)
Q0, V0 = _initial_state()

#: the time of the published reference solution
REFERENCE_T = 0.1
#: positions at ``REFERENCE_T`` (the test set's ``SOLN``, ``YEND(1:7)``; linear stiffness,
#: no damping)
REFERENCE_Q = np.array(
    [
        1.500000000000000e01,
        -3.311734987910881e-01,
        1.697373326718410e-01,
        1.893192460247178e-04,
        2.375751865617931e-05,
        -5.323907988763734e-06,
        -8.363283141616840e-06,
    ]
)
#: velocities at ``REFERENCE_T`` (``YEND(8:14)``, same source)
REFERENCE_V = np.array(
    [
        1.500000000000000e02,
        6.025346682645789e01,
        -8.753116989887888e00,
        -3.005536801092212e-02,
        -5.500488291932075e-03,
        4.978243404809343e-04,
        1.104933470696396e-03,
    ]
)


@jax.jit
def velocity(x, p, t):
    r"""The velocity of the state ``(x, p)`` on the constraint's tangent space: ``v`` of

        M(x) v + G(x)ᵀ ν = p,     G(x) v = −∂g/∂t,

    (``G = ∂g/∂x``). A step's end momentum ``p_{k+1} = D₂L_d`` carries no reaction at
    ``x_{k+1}``, so it is off the physical momentum along ``G(x_{k+1})ᵀ`` by O(h) (the
    step's reaction impulse sits at its known node); ``ν`` takes that component out and
    leaves the rule's own order."""
    jac = jax.jacfwd(closure)(x, t)
    rate = jax.jacfwd(closure, argnums=1)(x, t)
    k = jac.shape[0]
    kkt = jnp.block([[mass_matrix(x), jac.T], [jac, jnp.zeros((k, k))]])
    return jnp.linalg.solve(kkt, jnp.concatenate([p, -rate]))[: x.shape[0]]


def slider_crank(
    dt: float = 1e-4,
    steps: int = 1000,
    *,
    nonlinear_stiffness: bool = False,
    damping: bool = False,
) -> Problem:
    r"""The flexible slider crank from the test set's consistent initial state to
    ``t = dt · steps`` (default 0.1 s, the reference time).

    ``L = ½ ẋᵀ M(x) ẋ − ½ qᵀ K_q q`` (``− W(q)`` with ``nonlinear_stiffness``), the modal
    damping ``−D_q q̇`` as a force with ``damping``, the loop closure and the driven crank
    as holonomic rows (module docstring). The published solution at 0.1 s
    (:data:`REFERENCE_Q`, :data:`REFERENCE_V`) is for the default: linear, undamped.
    """
    dq = jnp.asarray(ROD["dq"])

    def lagrangian(x, v):
        return 0.5 * v @ mass_matrix(x) @ v - strain_energy(x, nonlinear_stiffness)

    def force(x, v):
        return jnp.concatenate([jnp.zeros(3, dtype=v.dtype), -dq @ v[3:]])

    system = LagrangeDiracSystem(
        COORDS,
        lagrangian,
        force=force if damping else None,
        holonomic=closure,
        holonomic_names=("closure_y", "closure_x", "crank_drive"),
        name="slider_crank",
    )
    p0 = np.asarray(mass_matrix(jnp.asarray(Q0)) @ jnp.asarray(V0))
    flags = ((nonlinear_stiffness, ", nonlinear"), (damping, ", damped"))
    variant = "".join(label for flag, label in flags if flag)
    return Problem(
        name="slider-crank",
        description="flexible slider crank: elastic rod in 4 modal coordinates, 3 rows "
        "(Bari test set)" + variant,
        system=system,
        q0=Q0.copy(),
        p0=p0,
        dt=dt,
        steps=steps,
        discretizations=("midpoint", "lobatto"),
        reference=(
            "Simeon 1996; IVP test set 'crank' (Mazzia & Magherini, Bari), "
            "http://www.dm.uniba.it/~testset/src/problems/crank.f, crank.F v1.2 2006/10/02: "
            "reference solution at t = 0.1"
        ),
        notes=(
            "the published solution (REFERENCE_Q, REFERENCE_V) is for the linear, undamped "
            "model at t = 0.1; velocity(x, p, t) recovers v from a step's state"
        ),
        parameters={
            "dt": dt,
            "steps": steps,
            "nonlinear_stiffness": nonlinear_stiffness,
            "damping": damping,
        },
    )


__all__ = [
    "COORDS",
    "PARAMETERS",
    "Q0",
    "REFERENCE_Q",
    "REFERENCE_T",
    "REFERENCE_V",
    "ROD",
    "V0",
    "closure",
    "mass_matrix",
    "slider_crank",
    "strain_energy",
    "velocity",
]
