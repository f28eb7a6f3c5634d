"""Cost per step of PartitionedSolver on a chain of N masses torn into N // 100 pieces.

Run: python examples/partitioned_scaling.py [N ...]   (default 1000 10000 100000, ~1 min;
     add 1000000 for ~2 more minutes and ~7 GB)

Each size runs in its own process (so the peak memory printed is that size's). What is
timed is ``solver.solve`` plus the explicit momentum update inside one compiled
``lax.scan`` — the step itself, not ``simulate()``'s per-step diagnostics or its dense
initial-data check. A chunk of steps is timed from a fresh solver state (it factorizes
once, at its first step) and from the valid state that chunk returned (no
factorization): per step = the second / steps, factorization = the difference. Dense
``NewtonSolver`` is timed alongside where its n × n factors fit (N ≤ 1000).
"""

import json
import os
import resource
import subprocess
import sys
import time

import numpy as np


def one(n_masses: int, kind: str, steps: int, repeats: int = 3) -> dict:
    import equinox as eqx
    import jax
    import jax.numpy as jnp

    import diracvi as dv
    from diracvi import problems
    from diracvi.discretization.equations import StepEquations

    t0 = time.perf_counter()
    problem = problems.chain_torn(n_masses, max(2, n_masses // 100))
    system = problem.system
    build = time.perf_counter() - t0
    solver = dv.PartitionedSolver() if kind == "partitioned" else dv.NewtonSolver()
    rule, n, h = dv.Retraction(), system.n, jnp.asarray(problem.dt)

    def equations(system, q, p):
        return StepEquations(system, rule, "plus", h, q, p)

    @eqx.filter_jit
    def chunk(system, carry, state):
        def body(carry, _):
            q, p, q_prev, mu, state = carry
            eqs = equations(system, q, p)
            res = solver.solve(eqs, jnp.concatenate([2 * q - q_prev, mu]), state)
            if kind == "partitioned":  # group by group, with the stacked parameters
                p_new = solver.momentum(eqs, res.x, res.state)
            else:
                p_new = eqs.momentum(res.x)
            return (res.x[:n], p_new, q, res.x[n:], res.state), (res.status, res.iterations)

        (*carry, state), out = jax.lax.scan(body, (*carry, state), None, length=steps)
        return tuple(carry), state, out

    def timed(*args):
        t0 = time.perf_counter()
        out = jax.block_until_ready(chunk(*args))
        return time.perf_counter() - t0, out

    q0, p0 = jnp.asarray(problem.q0), jnp.asarray(problem.p0)
    carry = (q0, p0, q0, jnp.zeros(system.m))
    fresh = eqx.filter_jit(lambda s, q, p: solver.init(equations(s, q, p)))(system, q0, p0)
    first, (_, valid, _) = timed(system, carry, fresh)
    first += timed(system, carry, valid)[0]  # a returned state may need its own compile
    t_fresh = min(timed(system, carry, fresh)[0] for _ in range(repeats))
    t_valid, (_, _, (status, iterations)) = min(
        (timed(system, carry, valid) for _ in range(repeats)), key=lambda r: r[0]
    )
    return {
        "N": n_masses,
        "M": len(system.subsystems),
        "solver": kind,
        "steps": steps,
        "build_s": build,
        "compile_s": first,
        "per_step_ms": 1e3 * t_valid / steps,
        "factorization_ms": 1e3 * max(0.0, t_fresh - t_valid),
        "iterations": float(iterations.mean()),
        "status": int(status.max()),
        "peak_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }


def main(sizes):
    rows = []
    for n_masses in sizes:
        steps = int(np.clip(4_000_000 // n_masses, 4, 400))
        for kind in ("partitioned", "newton") if n_masses <= 1000 else ("partitioned",):
            cmd = [sys.executable, __file__, "--one", str(n_masses), kind, str(steps)]
            out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=os.environ)
            row = json.loads(out.stdout.strip().splitlines()[-1])
            rows.append(row)
            print(
                f"N={row['N']:>8} M={row['M']:>6} {kind:>11}: {row['per_step_ms']:9.3f} ms/step "
                f"(factorization {row['factorization_ms']:7.0f} ms, compile {row['compile_s']:5.1f}"
                f" s, {row['iterations']:.1f} iterations/step, status {row['status']}, peak "
                f"{row['peak_rss_MB']:.0f} MB)",
                flush=True,
            )
    mine = [r for r in rows if r["solver"] == "partitioned"]
    if len(mine) >= 2:
        sizes = np.log([r["N"] for r in mine])
        slope = np.polyfit(sizes, np.log([r["per_step_ms"] for r in mine]), 1)[0]
        print(f"fitted exponent of time per step in N: {slope:.2f}")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        print(json.dumps(one(int(sys.argv[2]), sys.argv[3], int(sys.argv[4]))))
    else:
        main([int(a) for a in sys.argv[1:]] or [1000, 10000, 100000])
