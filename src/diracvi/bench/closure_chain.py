r"""A torn chain built the natural way (a fresh closure per piece) against shared code.

The shared-code chain is ``problems.chain_torn(N, M)``: every piece's Lagrangian is an
``equinox.Module`` of one class, so pieces of one length are alike by construction. The
closure chain has the same pieces, each ``LagrangeDiracSystem`` given a new Python
closure over that piece's masses and stiffnesses, as a loop in a user's script makes
them. diracvi traces each closure once and compares the programs (see
:mod:`diracvi.runtime.program`), so both chains should group, compile and step alike.

Each variant's first ``dv.simulate`` call (``save_states=False``, ``STEPS`` steps:
tracing, compilation, the run) is timed in a fresh process of its own with the
compilation cache off. The time per step is taken in one more process that builds both,
warms them up and times them interleaved (min over the long repeats ÷ steps), so a
change of load between processes does not fall on one side only.
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
    """``variant`` "shared" or "closure": build and first call; "both": per-step times."""
    import diracvi as dv
    from diracvi import problems

    from ._core import interleaved

    start = time.perf_counter()
    problem = problems.chain_torn(masses, pieces)
    systems = {}
    if variant in ("shared", "both"):
        systems["shared"] = problem.system
    if variant in ("closure", "both"):
        systems["closure"] = closure_chain(masses, pieces)
    build_s = time.perf_counter() - start

    def call(system):
        return lambda: dv.simulate(
            system, problem.q0, problem.p0, dt=problem.dt, steps=STEPS, save_states=False
        )

    if variant == "both":
        times = interleaved({name: call(s) for name, s in systems.items()}, repeats)
        return {name: float(t.min()) / STEPS for name, t in times.items()}
    (system,) = systems.values()
    start = time.perf_counter()
    traj = call(system)()
    first_s = time.perf_counter() - start
    return {
        "variant": variant,
        "build_s": build_s,
        "first_call_s": first_s,
        "groups": len(dv.PartitionedSolver.layout(system).groups),
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
        for variant in ("shared", "closure", "both"):
            args = ["-c", code, variant, str(masses), str(pieces), str(settings.long_repeats)]
            out[variant] = run_child(args, timeout=TIMEOUT)
    except WorkerFailed as exc:
        row = Row(NAME, f"{label}: not run", None, None, None, notes=str(exc), status="not run")
        return Result([row], out)
    c, s, step = out["closure"], out["shared"], out["both"]
    note = f"groups: closures {c['groups']}, shared {s['groups']}; interleaved, one process"
    rows = [
        Row(
            NAME,
            f"{label}, {STEPS} steps: time/step, closures ÷ shared code",
            step["closure"],
            step["shared"],
            step["closure"] / step["shared"],
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
            notes=f"fresh process each, cache off; build: closures {c['build_s']:.2f} s, "
            f"shared {s['build_s']:.2f} s",
        ),
    ]
    return Result(rows, out)
