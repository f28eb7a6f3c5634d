"""Director form (diracvi) against the Lie-group discrete rigid body (Lee–Leok–McClamroch).

The same torque-free body (``dv.problems.free_rigid_body``: J = diag(2, 3, 4), near the
unstable middle axis), the same step, N steps, both compiled by JAX in float64:

- **director**: ``dv.simulate`` of the 12-coordinate body with its 6 orthonormality rows
  (midpoint rule, Newton on 18 unknowns per step);
- **Lie group**: ``F_k J_d − J_d F_kᵀ = h Π̂_k`` solved by Newton for ``F_k = exp(ŵ)``
  (3 unknowns, Rodrigues' formula), ``R_{k+1} = R_k F_k``, ``Π_{k+1} = F_kᵀ Π_k``
  (Lee, Leok & McClamroch 2005), written here with ``jax.lax.scan``.

Printed: warm wall time per step (best of 3), max ‖RᵀR − I‖, the relative drift of
|Π| (spatial momentum for the director form) and the energy band. Run:

    PYTHONPATH=src python benchmarks/rigid_formulations.py [N]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import diracvi as dv
from diracvi.components.rigid_body import angular_momentum
from diracvi.problems.rigid_bodies import _turned, free_rigid_body


def _exp(w):
    angle = jnp.sqrt(w @ w + 1e-300)
    k = jnp.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]]) / angle
    return jnp.eye(3) + jnp.sin(angle) * k + (1.0 - jnp.cos(angle)) * k @ k


def lie_group(inertia, r0, pi0, h, n):
    jd = 0.5 * jnp.trace(inertia) * jnp.eye(3) - inertia
    jinv = jnp.linalg.inv(inertia)

    def residual(w, pi):
        m = _exp(w) @ jd - jd @ _exp(w).T
        return jnp.array([m[2, 1], m[0, 2], m[1, 0]]) - h * pi

    def step(carry, _):
        r, pi = carry
        w = h * jinv @ pi  # the first guess: F ≈ exp(h Ω)
        for _ in range(6):  # Newton (quadratic: 6 iterations reach round-off)
            w = w - jnp.linalg.solve(jax.jacfwd(residual)(w, pi), residual(w, pi))
        f = _exp(w)
        r1, pi1 = r @ f, f.T @ pi
        return (r1, pi1), (r1, pi1)

    run = jax.jit(lambda r, pi: jax.lax.scan(step, (r, pi), None, length=n)[1])
    return run, (jnp.asarray(r0), jnp.asarray(pi0))


def main(n: int = 100_000, h: float = 0.01) -> None:
    prob = free_rigid_body(dt=h, steps=n)
    inertia = np.diag(prob.parameters["J"])
    r0 = _turned((0.3, -0.2, 0.5))
    pi0 = inertia @ np.array(prob.parameters["Omega0"])

    def director():
        return dv.simulate(
            prob.system,
            prob.q0,
            prob.p0,
            dt=h,
            steps=n,
            discretization="midpoint",
            solver=dv.NewtonSolver(),
        )

    run, args = lie_group(jnp.asarray(inertia), r0, pi0, h, n)

    def lie():
        out = run(*args)
        jax.block_until_ready(out)
        return out

    rows = []
    for label, fn in (("director (diracvi)", director), ("Lie group (LLM)", lie)):
        fn()
        best = min(_timed(fn) for _ in range(3))
        rows.append((label, best / n))
    traj = director()
    d = traj.q[:, 3:12].reshape(-1, 3, 3)
    orth_d = np.max(np.abs(d @ np.swapaxes(d, 1, 2) - np.eye(3)))
    ang = angular_momentum(traj.q, traj.p)
    mom_d = np.max(np.abs(np.linalg.norm(ang, axis=1) / np.linalg.norm(ang[0]) - 1.0))
    en_d = np.ptp(traj.energy) / abs(traj.energy[0])
    r, pi = (np.asarray(x) for x in lie())
    orth_l = np.max(np.abs(np.swapaxes(r, 1, 2) @ r - np.eye(3)))
    mom_l = np.max(np.abs(np.linalg.norm(pi, axis=1) / np.linalg.norm(pi0) - 1.0))
    energy = 0.5 * np.einsum("ki,ij,kj->k", pi, np.linalg.inv(inertia), pi)
    en_l = np.ptp(energy) / energy[0]
    print(f"free rigid body, h = {h}, N = {n} steps")
    print("| formulation | µs/step (warm) | max ‖RᵀR − I‖ | |momentum| drift | energy band |")
    print("|---|---|---|---|---|")
    for (label, per), orth, mom, en in zip(
        rows, (orth_d, orth_l), (mom_d, mom_l), (en_d, en_l), strict=True
    ):
        print(f"| {label} | {per * 1e6:.1f} | {orth:.1e} | {mom:.1e} | {en:.1e} |")


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=100_000, help="steps")
    main(parser.parse_args().n)
