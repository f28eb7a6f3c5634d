"""The program store on a large model: first call of ``chain_torn(N, M)`` in a cold process
and in a second one sharing its new, empty cache directory.

python benchmarks/store_chain.py [N] [M] [--steps S]

Each process builds the chain and times its first ``dv.simulate`` (S steps); the second
loads the programs the first stored (``diracvi.runtime.store``) instead of tracing them. Also
printed: the time to print the chain's key (``canonical``), which both processes pay.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

CHILD = """
import json, sys, time
import diracvi as dv
from diracvi import problems
from diracvi.runtime.fingerprint import canonical
n, m, steps = (int(a) for a in sys.argv[1:4])
problem = problems.chain_torn(n, m)
start = time.perf_counter()
dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps=steps)
first = time.perf_counter() - start
start = time.perf_counter()
canonical(problem.system)
print(json.dumps({"first": first, "key": time.perf_counter() - start}))
"""


def main(n: int, m: int, steps: int) -> None:
    cache = tempfile.mkdtemp(prefix="diracvi-store-chain-")
    try:
        env = {**os.environ, "DIRACVI_CACHE_DIR": cache}
        times = []
        for label in ("cold", "second"):
            out = subprocess.run(
                [sys.executable, "-c", CHILD, str(n), str(m), str(steps)],
                env=env,
                capture_output=True,
                text=True,
                check=True,
            )
            times.append(json.loads(out.stdout.splitlines()[-1]))
            print(
                f"{label:6s} first call {times[-1]['first']:6.2f} s, key {times[-1]['key']:.3f} s"
            )
        print(f"second ÷ cold: {times[1]['first'] / times[0]['first']:.3f}")
    finally:
        shutil.rmtree(cache, ignore_errors=True)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", type=int, nargs="?", default=100_000)
    parser.add_argument("m", type=int, nargs="?", default=1000)
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args()
    main(args.n, args.m, args.steps)
