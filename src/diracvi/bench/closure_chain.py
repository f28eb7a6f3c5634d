r"""A torn chain built the natural way (a fresh closure per piece) against shared code.

The shared-code chain is ``problems.chain_torn(N, M)``: every piece's Lagrangian is an
``equinox.Module`` of one class, so pieces of one length are alike by construction. The
closure chain has the same pieces, each ``LagrangeDiracSystem`` given a new Python
closure over that piece's masses and stiffnesses, as a loop in a user's script makes
them. diracvi traces each closure once and compares the programs (see
:mod:`diracvi._program`), so both chains should group, compile and step alike.

Each variant runs in a fresh process with the compilation cache off: its first
``dv.simulate`` call (``save_states=False``, ``STEPS`` steps: tracing, compilation, the
run), then the warm time per step (min of the long repeats of the same call ÷ steps).
"""

from __future__ import annotations

import json
import sys
import time

from ._core import Result, Row, Settings, Target
from ._worker import WorkerFailed, run_child

NAME = "closure-chain"
DESCRIPTION = "torn chain of loop-built closures ÷ the same chain of shared code"

SIZES = {False: (5000, 50), True: (400, 8)}
STEPS = 200
TIMEOUT = 900.0
PER_STEP_TARGET = Target("<=", 1.3)
FIRST_TARGET = Target("<=", 1.5)


def closure_chain(masses: int, pieces: int):
    """``problems.chain_torn(masses, pieces)``'s system, one new closure per piece."""
    import jax.numpy as jnp
    import numpy as np

    import diracvi as dv

    mass = 1.0 + 0.5 * np.sin(np.arange(masses)) ** 2
    stiff = 1.0 + 0.3 * np.cos(np.arange(masses)) ** 2
    bounds = np.linspace(0, masses, pieces + 1).round().astype(int)
    subsystems, joints = [], []
    for j in range(pieces):
        lo, hi = bounds[j], bounds[j + 1]
        m, k = jnp.asarray(mass[lo:hi]), jnp.asarray(stiff[lo:hi])
        coords = tuple(f"q{i}" for i in range(hi - lo))
        if j == 0:

            def lagrangian(q, v, m=m, k=k):
                stretch = jnp.concatenate([q[:1], q[1:] - q[:-1]])
                return 0.5 * jnp.sum(m * v**2) - 0.5 * jnp.sum(k * stretch**2)

        else:
            coords = ("qbar", *coords)

            def lagrangian(q, v, m=m, k=k):
                return 0.5 * jnp.sum(m * v[1:] ** 2) - 0.5 * jnp.sum(k * (q[1:] - q[:-1]) ** 2)

            joints.append(dv.connect(f"s{j - 1}.q{bounds[j] - bounds[j - 1] - 1}", f"s{j}.qbar"))
        subsystems.append(dv.LagrangeDiracSystem(coords, lagrangian, name=f"s{j}"))
    return dv.interconnect(subsystems, joints, name="chain")


def measure(variant: str, masses: int, pieces: int, repeats: int) -> dict:
    import diracvi as dv
    from diracvi import problems

    from ._core import interleaved

    start = time.perf_counter()
    problem = problems.chain_torn(masses, pieces)
    system = problem.system if variant == "shared" else closure_chain(masses, pieces)
    build_s = time.perf_counter() - start

    def call():
        return dv.simulate(
            system, problem.q0, problem.p0, dt=problem.dt, steps=STEPS, save_states=False
        )

    start = time.perf_counter()
    traj = call()
    first_s = time.perf_counter() - start
    warm = float(interleaved({"run": call}, repeats)["run"].min())
    groups = len(dv.PartitionedSolver.layout(system).groups)
    return {
        "variant": variant,
        "build_s": build_s,
        "first_call_s": first_s,
        "per_step_s": warm / STEPS,
        "groups": groups,
        "solver": traj.solver,
    }


def _worker_main() -> None:
    variant, masses, pieces, repeats = sys.argv[1], *map(int, sys.argv[2:5])
    print(json.dumps(measure(variant, masses, pieces, repeats)))


def run(settings: Settings) -> Result:
    masses, pieces = SIZES[settings.quick]
    code = "from diracvi.bench.closure_chain import _worker_main; _worker_main()"
    out = {}
    label = f"chain N={masses:,} in {pieces} pieces"
    try:
        for variant in ("shared", "closure"):
            args = ["-c", code, variant, str(masses), str(pieces), str(settings.long_repeats)]
            out[variant] = run_child(args, timeout=TIMEOUT)
    except WorkerFailed as exc:
        row = Row(NAME, f"{label}: not run", None, None, None, notes=str(exc), status="not run")
        return Result([row], out)
    c, s = out["closure"], out["shared"]
    note = f"groups: closures {c['groups']}, shared {s['groups']}; fresh process, cache off"
    rows = [
        Row(
            NAME,
            f"{label}, {STEPS} steps: time/step, closures ÷ shared code",
            c["per_step_s"],
            s["per_step_s"],
            c["per_step_s"] / s["per_step_s"],
            PER_STEP_TARGET,
            solver=c["solver"],
            notes=note,
        ),
        Row(
            NAME,
            f"{label}: first call, closures ÷ shared code",
            c["first_call_s"],
            s["first_call_s"],
            c["first_call_s"] / s["first_call_s"],
            FIRST_TARGET,
            solver=c["solver"],
            notes=f"build: closures {c['build_s']:.2f} s, shared {s['build_s']:.2f} s",
        ),
    ]
    return Result(rows, out)
