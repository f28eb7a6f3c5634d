"""LAPACK custom calls reach XLA as typed FFI calls (diracvi.runtime.typed_ffi), so a
process restricted to one CPU compiles a program holding them, to the same result as a
process on all CPUs (jaxlib 0.10.2 left them untyped there: "No registered
implementation for untyped custom call to lapack_dgetrf_ffi for Host").

White-box: reads the StableHLO text JAX hands to XLA."""

import os
import re
import subprocess
import sys

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
import pytest

import diracvi as dv
from conftest import run
from diracvi import problems
from diracvi.runtime import typed_ffi


def _custom_calls(text):
    """(target, attribute text) of each ``stablehlo.custom_call`` in ``text``."""
    return re.findall(r"stablehlo\.custom_call @(\w+)\([^)]*\) \{(.*?)\} :", text)


def test_lapack_calls_are_lowered_with_api_version_4():
    assert typed_ffi.installed()

    def program(a, b, d):
        lu, piv = jsl.lu_factor(a)
        x = jsl.lu_solve((lu, piv), b)  # getrf and two trsm
        y = jax.lax.linalg.tridiagonal_solve(d, d + 4.0, d, b[:, None])  # gtsv
        return x, y

    a = jnp.eye(3) + 0.1
    text = jax.jit(program).lower(a, jnp.ones(3), jnp.ones(3)).as_text()
    calls = _custom_calls(text)
    targets = sorted({target for target, _ in calls})
    assert targets == ["lapack_dgetrf_ffi", "lapack_dgtsv_ffi", "lapack_dtrsm_ffi"], targets
    for target, attributes in calls:
        assert "api_version = 4" in attributes, (target, attributes)
        assert "mhlo.backend_config" not in attributes, (target, attributes)
    # the trsm's options travel in the typed backend_config dictionary
    trsm = [attributes for target, attributes in calls if target == "lapack_dtrsm_ffi"]
    assert all(re.search(r"backend_config = \{.*side = ", a) for a in trsm), trsm


ONE_CPU = """
import os, sys
os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # before XLA starts
import numpy as np
import diracvi as dv
from diracvi import problems
p = problems.get("spring-chain")
t = dv.simulate(p.system, p.q0, p.p0, dt=p.dt, steps=p.steps, discretization="midpoint",
                solver=dv.NewtonSolver(reuse_jacobian=False))
np.savez(sys.argv[1], q=t.q, p=t.p)
"""


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity call")
def test_one_cpu_process_compiles_lapack_newton_program_to_the_same_trajectory(tmp_path):
    # the program that failed to compile on one CPU: midpoint spring chain, a fresh
    # LAPACK LU at every Newton iteration; compiled in the child (no program store)
    out = tmp_path / "one_cpu.npz"
    env = {**os.environ, "DIRACVI_CACHE_DIR": ""}
    proc = subprocess.run(
        [sys.executable, "-c", ONE_CPU, str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]

    here = run(
        problems.get("spring-chain"),
        discretization="midpoint",
        solver=dv.NewtonSolver(reuse_jacobian=False),
    )
    there = np.load(out)
    assert np.array_equal(there["q"], np.asarray(here.q))
    assert np.array_equal(there["p"], np.asarray(here.p))
