"""The dense LU in plain operations (diracvi.solvers.small_lu) and the small-loop switch
(diracvi.runtime.small_loops) that lets a loop holding it run as one kernel."""

import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl

from diracvi.runtime import small_loops
from diracvi.solvers import small_lu

EPS = np.finfo(np.float64).eps


def _matrices():
    rng = np.random.default_rng(30)
    for n in (1, 2, 3, 7, 15, small_lu.SMALL):
        yield rng.normal(size=(n, n))
    # a circuit-like matrix: entries over 20 decades (a conducting and a blocking diode)
    a = rng.normal(size=(15, 15)) * 10.0 ** rng.uniform(-12, 8, size=(15, 15))
    yield a + np.diag(10.0 ** rng.uniform(-6, 4, size=15))


@pytest.mark.parametrize("a", list(_matrices()), ids=lambda a: f"n{a.shape[0]}")
def test_factors_are_lapacks_pivoting_to_round_off(a):
    """``a[perm] = L U`` within the backward error of Gaussian elimination with partial
    pivoting (Higham, Thm 9.3: ``|ΔA| ≤ γ_n |L||U|``), with the rows LAPACK's ``getrf``
    picks (the same partial pivoting: the first largest ``|a_pk|``)."""
    n = a.shape[0]
    lu, perm = (np.asarray(f) for f in jax.jit(small_lu.lu_factor)(jnp.asarray(a)))
    lower = np.tril(lu, -1) + np.eye(n)
    upper = np.triu(lu)
    gamma = n * EPS / (1 - n * EPS)
    bound = gamma * (np.abs(lower) @ np.abs(upper))
    assert np.all(np.abs(a[perm] - lower @ upper) <= bound + 1e-300)
    p, _, _ = sl.lu(a)  # a = P L U: row i of P L U is row perm[i] of a
    assert np.array_equal(perm, np.argmax(p, axis=0))


@pytest.mark.parametrize("a", list(_matrices()), ids=lambda a: f"n{a.shape[0]}")
def test_solve_is_backward_stable(a):
    """``A x = b``: the normwise backward error ``‖b − A x‖ / (‖A‖ ‖x‖ + ‖b‖)`` (∞-norms)
    within a small multiple of ``n ε`` (partial pivoting's growth on these matrices is
    small; LAPACK's own solve is held to the same bound)."""
    n = a.shape[0]
    b = np.random.default_rng(n).normal(size=n)
    x = np.asarray(jax.jit(lambda a, b: small_lu.lu_solve(small_lu.lu_factor(a), b))(a, b))
    ref = sl.lu_solve(sl.lu_factor(a), b)
    for sol in (x, ref):
        back = np.abs(b - a @ sol).max() / (
            np.abs(a).sum(axis=1).max() * np.abs(sol).max() + np.abs(b).max()
        )
        assert back <= 10 * n * EPS


def test_singular_matrix_gives_non_finite_solution():
    """An exactly singular Jacobian must reach Newton as a non-finite update (its
    ``SINGULAR`` status), as LAPACK's zero pivot does."""
    a = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]])
    x = jax.jit(lambda a: small_lu.lu_solve(small_lu.lu_factor(a), jnp.ones(3)))(a)
    assert not np.all(np.isfinite(np.asarray(x)))


_PROBE = """
import jax, jax.numpy as jnp
import diracvi
from diracvi.runtime import small_loops
from diracvi.solvers import small_lu

def newton(a, b):
    def body(carry):
        i, x = carry
        return i + 1, small_lu.lu_solve(small_lu.lu_factor(a + jnp.diag(x)), b)
    return jax.lax.while_loop(lambda c: c[0] < 3, body, (0, b))[1]

text = jax.jit(newton).lower(jnp.eye(15), jnp.ones(15)).compile().as_text()
print(small_loops.in_force(), "xla_cpu_small_call" in text)
"""


@pytest.mark.parametrize("setting", ["", "0"])
def test_a_newton_loop_is_one_kernel_when_in_force(setting):
    """In a fresh process, importing diracvi raises the threshold, and a loop of 15×15
    factorizations (whose body accesses 15×15 matrices, over XLA's default of 1024 bytes)
    is then compiled as one kernel (XLA's ``xla_cpu_small_call``); with
    ``DIRACVI_SMALL_LOOPS=0`` it is not."""
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    env[small_loops.ENV] = setting
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True
    )
    expected = "True True" if setting == "" else "False False"
    assert out.stdout.split("\n")[-2] == expected, out.stderr[-2000:]


def test_bad_switch_value_names_variable_and_fix(monkeypatch):
    monkeypatch.setenv(small_loops.ENV, "yes")
    with pytest.raises(ValueError, match=r"DIRACVI_SMALL_LOOPS='yes'.*Fix: set it to 1"):
        small_loops._wanted()


_BRIDGE = """
import sys
import numpy as np
from diracvi import spice
from diracvi.runtime import small_loops
from diracvi.spice._ngspice import CIRCUITS

netlist, probes, _ = CIRCUITS["bridge"]
result = spice.run(spice.read(netlist), internal=True)
march = result.trajectory
np.savez(sys.argv[1], t=result.time, **{p: result[p] for p in probes})
print(small_loops.in_force(), len(march.h), march.tries, march.iterations)
"""


@pytest.mark.slow
def test_bridge_steps_as_one_kernel_as_with_lapack(tmp_path):
    """The bridge rectifier's variable-step loop as one kernel (``small_lu``, the default
    optimization: what a user runs) takes the same steps, tries and Newton iterations as
    the loop of LAPACK's factors (``DIRACVI_SMALL_LOOPS=0``), and differs from it by
    round-off only. The step sizes come from the step-doubling difference, which the
    factors' round-off moves, so the time points drift (measured 3.8e-11 s over the 40 ms:
    bound 1e-8 of the run) and the waveforms at the same step differ by that drift times
    their slope (measured ≤ 1.7e-8 of peak: bound 1e-6, against the 3.4e-5 of peak by
    which the run differs from ngspice's converged reference)."""
    out = {}
    for setting in ("1", "0"):
        env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
        env.update({small_loops.ENV: setting, "DIRACVI_FAST_COMPILE": "0"})
        path = tmp_path / f"run{setting}.npz"
        done = subprocess.run(
            [sys.executable, "-c", _BRIDGE, str(path)],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        out[setting] = (done.stdout.split("\n")[-2].split(), np.load(path))
    (kernel, a), (lapack, b) = out["1"], out["0"]
    assert kernel[0] == "True" and lapack[0] == "False"
    assert kernel[1:] == lapack[1:]
    assert np.abs(a["t"] - b["t"]).max() <= 1e-8 * b["t"][-1]
    for name in a.files:
        if name != "t":
            peak = np.abs(b[name]).max()
            assert np.abs(a[name] - b[name]).max() <= 1e-6 * peak, name
