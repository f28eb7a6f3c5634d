"""The flexible slider crank at t = 0.1: diracvi's rules against SciPy's Radau, side by side.

Both sides start from the same consistent state (``problems.slider_crank``: the Bari IVP
test set's "close to smooth motion" ``INIT``) and are measured against the test set's
published solution at t = 0.1 (its ``SOLN``):

- **diracvi**: ``dv.simulate`` of the Lagrange–Dirac model (the loop and the crank drive
  as holonomic rows, index 3) with ``"midpoint"`` and ``"lobatto"`` at fixed steps; the
  velocity at the end from ``(q, p)`` on the constraint's tangent space
  (``slider_crank.velocity``);
- **SciPy Radau** on the test set's own equations, written out as it writes them (its
  mass matrix, its Coriolis and centrifugal terms, ``K q``, its constraint Jacobian and
  acceleration-level constraint): the index-1 ODE ``[M Gᵀ; G 0] [ẍ; λ] = [f; −γ]``, a
  ``jax.jit`` right-hand side and Jacobian. (The test set integrates the index-2 form;
  SciPy's ``solve_ivp`` takes no mass matrix, so no DAE: the index-1 form is what a SciPy
  user can run. Its drift off the position constraints is printed.)

Every timed call is warm (compiled once before); CPU seconds of this process (the machine
is shared: CPU time moves with the others' load much less than the wall clock), best of
``--repeats``. Printed: one Markdown table row per method.

    PYTHONPATH=src python benchmarks/slider_crank.py [--midpoint N …] [--lobatto N …] [--rtol R …]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import diracvi as dv
from diracvi.problems.slider_crank import (
    PARAMETERS,
    REFERENCE_Q,
    REFERENCE_T,
    REFERENCE_V,
    ROD,
    V0,
    closure,
    mass_matrix,
    slider_crank,
    velocity,
)


def test_set_rhs():
    """``(t, y) ↦ ẏ`` of the test set's equations in index-1 form, ``y = (x, ẋ)``,
    and its Jacobian (both jitted)."""
    P, R = PARAMETERS, ROD
    rho, l1, l2, m2 = P["rho"], P["l1"], P["l2"], P["m2"]
    mq, kq, bq = (jnp.asarray(R[k]) for k in ("mq", "kq", "bq"))
    c1, c2, c12 = (jnp.asarray(R[k]) for k in ("c1", "c2", "c12"))

    def forces(x, v):  # its F: rigid entries, "f^e", "Gamma", then − K q
        q, qd, w1, w2 = x[3:], v[3:], v[0], v[1]
        s12, co12 = jnp.sin(x[0] - x[1]), jnp.cos(x[0] - x[1])
        mqq, bqqd = mq @ q, bq @ qd
        f1 = (
            -0.5 * l1 * l2 * m2 * w2**2 * s12
            + rho * l1 * w2**2 * (-s12 * (c1 @ q) + co12 * (c2 @ q))
            - 2 * rho * l1 * w2 * (co12 * (c1 @ qd) + s12 * (c2 @ qd))
        )
        f2 = (
            0.5 * l1 * l2 * m2 * w1**2 * s12
            + rho * l1 * w1**2 * (s12 * (c1 @ q) - co12 * (c2 @ q))
            - 2 * rho * w2 * (c12 @ qd)
            - 2 * w2 * (qd @ mqq)
            - rho * (qd @ bqqd)
        )
        fq = w2**2 * mqq + rho * (w2**2 * c12 + l1 * w1**2 * (co12 * c1 + s12 * c2) + 2 * w2 * bqqd)
        return jnp.concatenate([jnp.stack([f1, f2, 0.0 * f1]), fq - kq @ q])

    def rhs(t, y):
        x, v = y[:7], y[7:]
        p1, p2, q4, qd4 = x[0], x[1], x[6], v[6]
        s1, c1_, s2, c2_ = jnp.sin(p1), jnp.cos(p1), jnp.sin(p2), jnp.cos(p2)
        z = 0.0 * p1
        jac = jnp.stack(  # its GP (KU = 4: the elongation q₄ enters the loop)
            [
                jnp.stack([l1 * c1_, (l2 + q4) * c2_, z, z, z, z, s2]),
                jnp.stack([l1 * s1, (l2 + q4) * s2, 1.0 + z, z, z, z, -c2_]),
                jnp.stack([1.0 + z, z, z, z, z, z, z]),
            ]
        )
        w1, w2 = v[0], v[1]
        gamma = jnp.stack(  # its ALC without G ẍ
            [
                -l1 * s1 * w1**2 - (l2 + q4) * s2 * w2**2 + 2 * w2 * c2_ * qd4,
                l1 * c1_ * w1**2 + (l2 + q4) * c2_ * w2**2 + 2 * w2 * s2 * qd4,
                z,
            ]
        )
        kkt = jnp.block([[mass_matrix(x), jac.T], [jac, jnp.zeros((3, 3))]])
        acc = jnp.linalg.solve(kkt, jnp.concatenate([forces(x, v), -gamma]))[:7]
        return jnp.concatenate([v, acc])

    return jax.jit(rhs), jax.jit(jax.jacfwd(rhs, argnums=1))


def _timed(call, repeats):
    best = None
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        out = call()
        took = (time.process_time() - cpu, time.perf_counter() - wall)
        best = took if best is None or took[0] < best[0] else best
    return out, best


def diracvi_row(rule, steps, repeats):
    prob = slider_crank(dt=REFERENCE_T / steps, steps=steps)

    def call():
        return dv.simulate(
            prob.system, prob.q0, prob.p0, dt=prob.dt, steps=steps, discretization=rule
        )

    call()  # compile
    traj, (cpu, wall) = _timed(call, repeats)
    x, p = jnp.asarray(traj.q[-1]), jnp.asarray(traj.p[-1])
    v = np.asarray(velocity(x, p, REFERENCE_T))
    held = jax.vmap(closure)(jnp.asarray(traj.q), jnp.asarray(traj.t))
    return {
        "method": f"diracvi {rule}",
        "work": f"{steps} steps, {traj.newton_iterations.mean():.1f} Newton it./step",
        "dx": np.max(np.abs(np.asarray(x) - REFERENCE_Q)),
        "dv": np.max(np.abs(v - REFERENCE_V)),
        "g": float(np.max(np.abs(np.asarray(held)))),
        "cpu": cpu,
        "wall": wall,
    }


def radau_row(rtol, repeats):
    import scipy.integrate

    rhs, jac = test_set_rhs()
    prob = slider_crank()
    y0 = np.concatenate([prob.q0, V0])
    f = lambda t, y: np.asarray(rhs(t, y))  # noqa: E731
    j = lambda t, y: np.asarray(jac(t, y))  # noqa: E731
    f(0.0, y0), j(0.0, y0)  # compile

    def call():
        return scipy.integrate.solve_ivp(
            f, (0.0, REFERENCE_T), y0, method="Radau", rtol=rtol, atol=1e-3 * rtol, jac=j
        )

    sol, (cpu, wall) = _timed(call, repeats)
    y = sol.y[:, -1]
    return {
        "method": f"SciPy Radau, rtol {rtol:g}, atol {1e-3 * rtol:g}",
        "work": f"{sol.t.size - 1} steps, {sol.nfev} f, {sol.njev} J",
        "dx": np.max(np.abs(y[:7] - REFERENCE_Q)),
        "dv": np.max(np.abs(y[7:] - REFERENCE_V)),
        "g": float(np.max(np.abs(np.asarray(closure(jnp.asarray(y[:7]), REFERENCE_T))))),
        "cpu": cpu,
        "wall": wall,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--midpoint", type=int, nargs="*", default=[128000])
    parser.add_argument("--lobatto", type=int, nargs="*", default=[8000, 16000])
    parser.add_argument("--rtol", type=float, nargs="*", default=[1e-6, 1e-8])
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    rows = [diracvi_row("midpoint", n, args.repeats) for n in args.midpoint]
    rows += [diracvi_row("lobatto", n, args.repeats) for n in args.lobatto]
    rows += [radau_row(r, args.repeats) for r in args.rtol]
    print("| method | work | max abs error x(0.1) | max abs error ẋ(0.1) | max abs g(x(t)) "
          "| CPU s | wall s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['method']} | {r['work']} | {r['dx']:.2e} | {r['dv']:.2e} | {r['g']:.1e} "
            f"| {r['cpu']:.2f} | {r['wall']:.2f} |"
        )


if __name__ == "__main__":
    main()
