r"""A closed spatial loop: the RSSR spatial four-bar, with a reduced one-coordinate reference.

A crank turns on a revolute joint about the axis ``a`` through ``A``; a rocker on a
revolute joint about ``u`` through ``D``, the two axes skew; a coupler joins the crank's
tip ``B`` to the rocker's tip ``C`` by spherical joints at both ends, so ``|C − B| = ℓ``.
With the links' joint angles ``θ`` (crank) and ``φ`` (rocker),

    B(θ) = A + E_A R_z(θ) (r₁, 0, 0),   C(φ) = D + E_D R_z(φ) (r₃, 0, 0),
    g(θ, φ) = |C − B|² − ℓ² = 0,

one degree of freedom moves the loop, plus the coupler's spin about its own axis ``BC``,
which the spherical joints cannot drive: for a coupler symmetric about that axis (a rod)
the spin's momentum is conserved, and it starts at zero. The reference integrates ``θ``
alone (``φ(θ)`` from the closure, one branch of ``a cos φ + b sin φ = c``), with the
coupler's kinetic energy ``½ m |(Ḃ + Ċ)/2|² + ½ J⊥ |Ċ − Ḃ|²/ℓ²`` — NumPy and SciPy's
DOP853 only, no diracvi. The diracvi model is three director bodies, two revolute and two
spherical joints (34 holonomic rows on 36 coordinates), built monolithic or torn.

Why not Bricard's linkage: its six revolute joints give 30 joint rows on the 30 degrees
of freedom of five moving bodies, of which only 29 are independent on the mechanism (its
mobility is one by a special geometry, not by counting), so the rows' Jacobian is rank
deficient everywhere and the step's KKT matrix singular; the RSSR's rows are independent
(one spatial loop, mobility by counting).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from ..components import Multibody, RigidBody
from ._problem import Problem


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: the loop's geometry: pivots, axes (third columns skew), crank, coupler and rocker lengths
GEOMETRY = {
    "A": np.zeros(3),
    "E_A": _rx(0.3),
    "r1": 0.2,
    "D": np.array([0.6, 0.1, 0.25]),
    "E_D": _ry(np.pi / 2) @ _rx(0.4),
    "r3": 0.45,
    "l": 0.78,
}
#: (mass, moment about the link's own axis) of crank, coupler, rocker: slender rods
MASSES = ((0.5, 1e-3), (0.8, 1e-3), (0.6, 1e-3))
BRANCH = 1.0  # which of the two assemblies of the loop (the sign of arccos)


def _rod(mass, axial, length):
    """A rod's transverse moment about its centre of mass, ``m ℓ²/12``."""
    return mass * length**2 / 12.0, axial


class _Loop:
    """The loop's kinematics in (θ, φ): points, their derivatives and the closure."""

    def __init__(self, gravity):
        geo = GEOMETRY
        self.g = np.array([0.0, 0.0, -float(gravity)])
        self.a, self.ea, self.r1 = geo["A"], geo["E_A"], geo["r1"]
        self.d, self.ed, self.r3, self.l = geo["D"], geo["E_D"], geo["r3"], geo["l"]
        (m1, _), (mc, _), (m3, _) = MASSES
        self.m1, self.mc, self.m3 = m1, mc, m3
        jc, _ = _rod(mc, 0.0, self.l)
        # the crank's and rocker's moments about their pivots (rods turning end-on)
        self.i_a = _rod(m1, 0.0, self.r1)[0] + m1 * (self.r1 / 2) ** 2
        self.i_d = _rod(m3, 0.0, self.r3)[0] + m3 * (self.r3 / 2) ** 2
        alpha, beta = mc / 4 + jc / self.l**2, mc / 4 - jc / self.l**2
        self.k = np.kron(np.array([[alpha, beta], [beta, alpha]]), np.eye(3))

    @staticmethod
    def _tip(p, e, r, angle):
        c, s = np.cos(angle), np.sin(angle)
        return p + e @ [r * c, r * s, 0.0], e @ [-r * s, r * c, 0.0], e @ [-r * c, -r * s, 0.0]

    def crank(self, theta):
        return self._tip(self.a, self.ea, self.r1, theta)

    def rocker(self, phi):
        return self._tip(self.d, self.ed, self.r3, phi)

    def phi(self, theta, branch=BRANCH):
        """The rocker angle closing the loop: ``a cos φ + b sin φ = c``."""
        b_pt, _, _ = self.crank(theta)
        w = self.d - b_pt
        a = 2 * self.r3 * self.ed[:, 0] @ w
        b = 2 * self.r3 * self.ed[:, 1] @ w
        c = self.l**2 - w @ w - self.r3**2
        return np.arctan2(b, a) + branch * np.arccos(c / np.hypot(a, b))

    def rates(self, theta, omega, branch=BRANCH):
        """``φ`` and ``φ̇`` from ``ġ = 0``, with the points and their derivatives."""
        phi = self.phi(theta, branch)
        bp, b1, b2 = self.crank(theta)
        cp, c1, c2 = self.rocker(phi)
        phidot = (cp - bp) @ b1 / ((cp - bp) @ c1) * omega
        return phi, phidot, (bp, b1, b2), (cp, c1, c2)

    def energy(self, theta, omega, branch=BRANCH):
        r"""``½ I_A θ̇² + ½ I_D φ̇² + ½ (Ḃ, Ċ)ᵀ K (Ḃ, Ċ) − g·Σ m r_c`` of the loop."""
        _, phidot, (bp, b1, _), (cp, c1, _) = self.rates(theta, omega, branch)
        rates = np.concatenate([b1 * omega, c1 * phidot])
        kinetic = 0.5 * (self.i_a * omega**2 + self.i_d * phidot**2 + rates @ self.k @ rates)
        centres = (
            self.m1 * (self.a + bp) / 2 + self.m3 * (self.d + cp) / 2 + self.mc * (bp + cp) / 2
        )
        return kinetic - self.g @ centres

    def acceleration(self, theta, omega, branch=BRANCH):
        r"""``θ̈`` from ``[[M, Gᵀ], [G, 0]] (q̈, −λ) = (f, −Ġ q̇)`` in ``q = (θ, φ)``."""
        _, phidot, (bp, b1, b2), (cp, c1, c2) = self.rates(theta, omega, branch)
        jq = np.zeros((6, 2))
        jq[:3, 0], jq[3:, 1] = b1, c1
        mass = np.diag([self.i_a, self.i_d]) + jq.T @ self.k @ jq
        centripetal = np.concatenate([b2 * omega**2, c2 * phidot**2])
        grad_v = -np.array(
            [self.g @ b1 * (self.m1 + self.mc) / 2, self.g @ c1 * (self.m3 + self.mc) / 2]
        )
        force = -grad_v - jq.T @ self.k @ centripetal
        w = cp - bp
        wdot = c1 * phidot - b1 * omega
        gq = 2 * np.array([-w @ b1, w @ c1])
        rhs = -2 * wdot @ wdot - 2 * w @ (c2 * phidot**2 - b2 * omega**2)
        kkt = np.zeros((3, 3))
        kkt[:2, :2], kkt[:2, 2], kkt[2, :2] = mass, gq, gq
        return np.linalg.solve(kkt, np.concatenate([force, [rhs]]))[0]


def rssr_reference(t, theta0, omega0, gravity=9.81, branch=BRANCH, rates=False):
    r"""The crank angle ``θ(t)`` of the RSSR loop by DOP853 (``rtol = 1e-12``, ``atol =
    1e-13``) on its one-coordinate equation (see the module docstring); with
    ``rates=True`` also ``θ̇(t)``."""
    loop = _Loop(gravity)
    t = np.atleast_1d(np.asarray(t, dtype=np.float64))
    sol = solve_ivp(
        lambda _, y: [y[1], loop.acceleration(y[0], y[1], branch)],
        (0.0, float(t[-1])),
        [float(theta0), float(omega0)],
        method="DOP853",
        t_eval=t,
        rtol=1e-12,
        atol=1e-13,
    )
    return (sol.y[0], sol.y[1]) if rates else sol.y[0]


def rssr_energy(theta, omega, gravity=9.81, branch=BRANCH):
    """The loop's energy at crank angle ``theta`` and rate ``omega`` (reduced model)."""
    return _Loop(gravity).energy(float(theta), float(omega), branch)


def _aligned(e):
    """A rotation whose third column is the unit vector ``e`` (turned from ``z``)."""
    z = np.array([0.0, 0.0, 1.0])
    v, c = np.cross(z, e), z @ e
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def rssr_linkage(
    theta0: float = 0.4,
    omega0: float = 6.0,
    gravity: float = 9.81,
    torn: bool = False,
    dt: float = 0.005,
    steps: int = 400,
) -> Problem:
    r"""The RSSR spatial four-bar under gravity: crank angle ``theta0`` turning at
    ``omega0`` (rad/s); the rocker and coupler placed and moving as the loop requires,
    the coupler's spin zero. ``torn=True``: one subsystem per body and per joint.
    ``parameters["reference"](t)`` is the crank angle by :func:`rssr_reference`."""
    loop = _Loop(gravity)
    phi0, phidot0, (bp, b1, _), (cp, c1, _) = loop.rates(theta0, omega0)
    g = loop.g
    (m1, ax1), (mc, axc), (m3, ax3) = MASSES
    r1, r3, ell = loop.r1, loop.r3, loop.l
    jt1, jtc, jt3 = _rod(m1, ax1, r1)[0], _rod(mc, axc, ell)[0], _rod(m3, ax3, r3)[0]
    # rods: the crank and rocker along their body x (z the joint axis), the coupler along z
    crank = RigidBody(
        m1, (ax1, jt1, jt1), name="crank", com=(r1 / 2, 0, 0), gravity=g, frames={"tip": (r1, 0, 0)}
    )
    rocker = RigidBody(
        m3,
        (ax3, jt3, jt3),
        name="rocker",
        com=(r3 / 2, 0, 0),
        gravity=g,
        frames={"tip": (r3, 0, 0)},
    )
    coupler = RigidBody(
        mc,
        (jtc, jtc, axc),
        name="coupler",
        com=(0, 0, ell / 2),
        gravity=g,
        frames={"end": (0, 0, ell)},
    )
    e = (cp - bp) / ell
    edot = (c1 * phidot0 - b1 * omega0) / ell
    mb = Multibody("rssr")
    mb.add(crank, position=loop.a, orientation=loop.ea @ _rz(theta0), omega=omega0 * loop.ea[:, 2])
    mb.add(
        coupler, position=bp, orientation=_aligned(e), velocity=b1 * omega0, omega=np.cross(e, edot)
    )
    mb.add(rocker, position=loop.d, orientation=loop.ed @ _rz(phi0), omega=phidot0 * loop.ed[:, 2])
    mb.joint("revolute", mb.world_frame("A", loop.a, loop.ea), "crank.origin", name="hinge_a")
    mb.joint("spherical", "crank.tip", "coupler.origin", name="ball_b")
    mb.joint("spherical", "coupler.end", "rocker.tip", name="ball_c")
    mb.joint("revolute", mb.world_frame("D", loop.d, loop.ed), "rocker.origin", name="hinge_d")
    model = mb.build(torn=torn)
    return Problem(
        name="rssr-linkage",
        description="RSSR spatial four-bar: crank, coupler, rocker on skew axes (director form)",
        system=model.system,
        q0=model.q0,
        p0=model.p0,
        dt=dt,
        steps=steps,
        discretizations=("midpoint",),
        reference="one-coordinate equation of the loop by DOP853 (rssr_reference)",
        parameters={
            "model": model,
            "theta0": float(theta0),
            "omega0": float(omega0),
            "reference": lambda t: rssr_reference(t, theta0, omega0, gravity),
            "torn": torn,
        },
    )


__all__ = ["GEOMETRY", "MASSES", "rssr_energy", "rssr_linkage", "rssr_reference"]
