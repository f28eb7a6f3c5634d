"""The free rigid body's invariants over a long run (docs/rigid-bodies.md, issue 33).

python benchmarks/free_body_drift.py [--steps N] [--rest] [--discretization RULE]

``problems.free_rigid_body`` at h = 0.01 with ``save_every=100`` and the default solver:
prints ‖RᵀR − I‖, the spatial angular momentum's largest change (vector and |L|,
relative) after a tenth, three tenths and the whole run, the energy band over the run and
in its first and last tenth, the change of a straight line fitted to the energy over the
run, and the run's time. ``--rest``: the body at rest in translation (as in the docs).
"""

import argparse
import time

import numpy as np

import diracvi as dv
from diracvi.components.rigid_body import angular_momentum
from diracvi.problems import free_rigid_body


def main(steps: int, rest: bool, rule: str) -> None:
    velocity = (0.0, 0.0, 0.0) if rest else (0.2, 0.0, -0.1)
    prob = free_rigid_body(dt=0.01, steps=steps, velocity0=velocity)
    start = time.perf_counter()
    tr = dv.simulate(
        prob.system, prob.q0, prob.p0, dt=prob.dt, steps=steps, discretization=rule, save_every=100
    )
    elapsed = time.perf_counter() - start
    ang = angular_momentum(tr.q, tr.p)
    size = np.linalg.norm(ang[0])
    change = np.linalg.norm(ang - ang[0], axis=1) / size
    length = np.abs(np.linalg.norm(ang, axis=1) - size) / size
    d = tr.q[:, 3:12].reshape(-1, 3, 3)
    orth = np.max(np.abs(d @ np.swapaxes(d, 1, 2) - np.eye(3)))
    energy = tr.energy / abs(tr.energy[0])
    tenth = len(energy) // 10
    trend = np.polyfit(np.arange(len(energy)), energy, 1)[0] * len(energy)
    parts = {f: np.max(change[: max(2, int(f * len(change)))]) for f in (0.1, 0.3, 1.0)}
    print(f"{steps} steps, {rule}, {'at rest' if rest else 'moving'}: {elapsed:.0f} s")
    print(f"  max |RᵀR − I|            {orth:.2e}")
    print("  max |L − L₀|/|L₀|        " + ", ".join(f"{v:.2e} ({f})" for f, v in parts.items()))
    print(f"  max ||L| − |L₀||/|L₀|    {np.max(length):.2e}")
    print(
        f"  energy band              {np.ptp(energy):.2e} (first tenth "
        f"{np.ptp(energy[:tenth]):.2e}, last {np.ptp(energy[-tenth:]):.2e}; "
        f"fitted line moves {trend:.1e})"
    )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--rest", action="store_true", help="no translation")
    parser.add_argument("--discretization", default="midpoint")
    args = parser.parse_args()
    main(args.steps, args.rest, args.discretization)
