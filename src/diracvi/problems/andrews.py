r"""Andrews' squeezing mechanism: 7 bodies, 6 loop constraints, an angle-dependent mass matrix.

The planar mechanism of Hairer & Wanner, *Solving ODEs II*, §VII.7 (after Schiehlen's
multibody benchmark), in the seven angles ``q = (β, Θ, γ, Φ, δ, Ω, ε)`` with the parameters
and initial data of the Bari / CWI IVP test set ("andrews"). Its equations of motion

    M(q) q̈ = f(q, q̇) − G(q)ᵀ λ,     g(q) = 0   (6 rows),

are Lagrange's with

    L = ½ q̇ᵀ M(q) q̇ − ½ c₀ (ℓ(γ) − ℓ₀)²,     F = (mom, 0, …, 0),

``M`` depending on ``Θ``, ``Φ`` and ``Ω`` (its derivatives give the test set's Coriolis
terms in ``f``), the spring of stiffness ``c₀`` and rest length ``ℓ₀`` between the fixed
point ``C`` and the point ``D(γ)`` of body 3, and the constant driving torque ``mom`` on
``β``. The six holonomic rows close the three loops through the fixed points ``A`` and
``B``:

    g₁ = r cos β − d cos(β+Θ) − s sin γ − x_B,      g₂ = r sin β − d sin(β+Θ) + s cos γ − y_B,
    g₃ = r cos β − d cos(β+Θ) − e sin(Φ+δ) − z_t cos δ − x_A,
    g₄ = r sin β − d sin(β+Θ) + e cos(Φ+δ) − z_t sin δ − y_A,
    g₅ = r cos β − d cos(β+Θ) − z_f cos(Ω+ε) − u sin ε − x_A,
    g₆ = r sin β − d sin(β+Θ) − z_f sin(Ω+ε) + u cos ε − y_A.

The published reference solution at ``t = 0.03`` (PSIDE at tolerance 1e-14, Cray double
precision; the test set's ``SOLN``) is :data:`REFERENCE_Q`. In 0.03 s the driving link turns
by about 16 rad (≈ 2.5 revolutions), at up to ≈ 1400 rad/s.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ..model.system import LagrangeDiracSystem
from ._problem import Problem

#: the test set's parameters (SI units: kg, m, kg m², N/m, N m)
PARAMETERS = {
    "m1": 0.04325, "m2": 0.00365, "m3": 0.02373, "m4": 0.00706,
    "m5": 0.07050, "m6": 0.00706, "m7": 0.05498,
    "xa": -0.06934, "ya": -0.00227, "xb": -0.03635, "yb": 0.03273,
    "xc": 0.014, "yc": 0.072, "c0": 4530.0,
    "i1": 2.194e-6, "i2": 4.410e-7, "i3": 5.255e-6, "i4": 5.667e-7,
    "i5": 1.169e-5, "i6": 5.667e-7, "i7": 1.912e-5,
    "d": 28e-3, "da": 115e-4, "e": 2e-2, "ea": 1421e-5, "rr": 7e-3, "ra": 92e-5,
    "l0": 7785e-5, "ss": 35e-3, "sa": 1874e-5, "sb": 1043e-5, "sc": 18e-3, "sd": 2e-2,
    "ta": 2308e-5, "tb": 916e-5, "u": 4e-2, "ua": 1228e-5, "ub": 449e-5,
    "zf": 2e-2, "zt": 4e-2, "fa": 1421e-5, "mom": 33e-3,
}  # fmt: skip

#: consistent initial angles (the test set's ``INITIAL``); all velocities are zero
Q0 = np.array(
    [
        -0.0617138900142764496358948458001,
        0.0,
        0.455279819163070380255912382449,
        0.222668390165885884674473185609,
        0.487364979543842550225598953530,
        -0.222668390165885884674473185609,
        1.23054744454982119249735015568,
    ]
)

#: the time of the published reference solution
REFERENCE_T = 0.03
#: the angles at ``REFERENCE_T`` (the test set's ``SOLN``, PSIDE at tolerance 1e-14)
REFERENCE_Q = np.array(
    [
        0.1581077119629904e2,
        -0.1575637105984298e2,
        0.4082224013073101e-1,
        -0.5347301163226948,
        0.5244099658805304,
        0.5347301163226948,
        0.1048080741042263e1,
    ]
)
#: the angular velocities at ``REFERENCE_T`` (same source)
REFERENCE_V = np.array(
    [
        0.1139920302151208e4,
        -0.1424379294994111e4,
        0.1103291221937134e2,
        0.1929337464421385e2,
        0.5735699284790808,
        -0.1929337464421385e2,
        0.3231791658026955,
    ]
)

COORDS = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")


def mass_matrix(q, xp=jnp):
    """``M(q)``, 7×7 symmetric, block diagonal in (β, Θ), (γ), (Φ, δ), (Ω, ε)."""
    P = PARAMETERS
    m2, m4, m6 = P["m2"], P["m4"], P["m6"]
    da, rr, zt, u = P["da"], P["rr"], P["zt"], P["u"]
    eea, zffa = P["e"] - P["ea"], P["zf"] - P["fa"]
    coth, siph, siom = xp.cos(q[1]), xp.sin(q[3]), xp.sin(q[5])
    m11 = P["m1"] * P["ra"] ** 2 + m2 * (rr**2 - 2 * da * rr * coth + da**2) + P["i1"] + P["i2"]
    m21 = m2 * (da**2 - da * rr * coth) + P["i2"]
    m22 = m2 * da**2 + P["i2"]
    m33 = P["m3"] * (P["sa"] ** 2 + P["sb"] ** 2) + P["i3"]
    m44 = m4 * eea**2 + P["i4"]
    m54 = m4 * (eea**2 + zt * eea * siph) + P["i4"]
    m55 = (
        m4 * (zt**2 + 2 * zt * eea * siph + eea**2)
        + P["m5"] * (P["ta"] ** 2 + P["tb"] ** 2)
        + P["i4"]
        + P["i5"]
    )
    m66 = m6 * zffa**2 + P["i6"]
    m76 = m6 * (zffa**2 - u * zffa * siom) + P["i6"]
    m77 = (
        m6 * (zffa**2 - 2 * u * zffa * siom + u**2)
        + P["m7"] * (P["ua"] ** 2 + P["ub"] ** 2)
        + P["i6"]
        + P["i7"]
    )
    z = 0.0 * coth
    rows = [
        [m11, m21, z, z, z, z, z],
        [m21, m22, z, z, z, z, z],
        [z, z, m33 + z, z, z, z, z],
        [z, z, z, m44 + z, m54, z, z],
        [z, z, z, m54, m55, z, z],
        [z, z, z, z, z, m66 + z, m76],
        [z, z, z, z, z, m76, m77],
    ]
    return xp.stack([xp.stack(r) for r in rows])


def spring_energy(q, xp=jnp):
    """``½ c₀ (ℓ − ℓ₀)²``, ``ℓ = |D(γ) − C|``, ``D = B + (s_d cos γ + s_c sin γ,
    s_d sin γ − s_c cos γ)``."""
    P = PARAMETERS
    cg, sg = xp.cos(q[2]), xp.sin(q[2])
    xd = P["sd"] * cg + P["sc"] * sg + P["xb"]
    yd = P["sd"] * sg - P["sc"] * cg + P["yb"]
    length = xp.sqrt((xd - P["xc"]) ** 2 + (yd - P["yc"]) ** 2)
    return 0.5 * P["c0"] * (length - P["l0"]) ** 2


def loops(q, xp=jnp):
    """The six loop-closure rows ``g(q)`` (module docstring)."""
    P = PARAMETERS
    rr, d, e, zt, zf, u = P["rr"], P["d"], P["e"], P["zt"], P["zf"], P["u"]
    be, th, ga, ph, de, om, ep = (q[i] for i in range(7))
    x = rr * xp.cos(be) - d * xp.cos(be + th)
    y = rr * xp.sin(be) - d * xp.sin(be + th)
    return xp.stack(
        [
            x - P["ss"] * xp.sin(ga) - P["xb"],
            y + P["ss"] * xp.cos(ga) - P["yb"],
            x - e * xp.sin(ph + de) - zt * xp.cos(de) - P["xa"],
            y + e * xp.cos(ph + de) - zt * xp.sin(de) - P["ya"],
            x - zf * xp.cos(om + ep) - u * xp.sin(ep) - P["xa"],
            y - zf * xp.sin(om + ep) + u * xp.cos(ep) - P["ya"],
        ]
    )


def andrews(dt: float = 1e-4, steps: int = 300) -> Problem:
    r"""Andrews' squeezing mechanism from the test set's consistent rest state to
    ``t = dt · steps`` (default 0.03 s, the reference time).

    ``L = ½ q̇ᵀ M(q) q̇ − ½ c₀ (ℓ(γ) − ℓ₀)²``, the torque ``mom`` on ``β``, the six loop
    closures as holonomic constraints (module docstring). Checked against the test set's
    published solution at 0.03 s (:data:`REFERENCE_Q`).
    """
    mom = PARAMETERS["mom"]

    def lagrangian(q, v):
        return 0.5 * v @ mass_matrix(q) @ v - spring_energy(q)

    def force(q, v, t):
        return jnp.zeros(7).at[0].set(mom) + 0.0 * v

    system = LagrangeDiracSystem(
        COORDS,
        lagrangian,
        force=force,
        holonomic=loops,
        holonomic_names=tuple(f"loop{i}" for i in range(1, 7)),
        name="andrews",
    )
    return Problem(
        name="andrews",
        description="Andrews' squeezing mechanism: 7 bodies, 6 loop constraints (Hairer–Wanner)",
        system=system,
        q0=Q0.copy(),
        p0=np.zeros(7),
        dt=dt,
        steps=steps,
        discretizations=("midpoint", "lobatto"),
        reference=(
            "Hairer & Wanner, Solving ODEs II, §VII.7; IVP test set 'andrews' (reference "
            "solution at t = 0.03 by PSIDE, tolerance 1e-14)"
        ),
        notes="the published solution is known at t = 0.03 only (REFERENCE_Q, REFERENCE_V)",
        parameters={"dt": dt, "steps": steps},
    )


__all__ = ["REFERENCE_Q", "REFERENCE_T", "REFERENCE_V", "andrews", "loops", "mass_matrix"]
