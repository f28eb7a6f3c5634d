"""``DIRACVI_FAST_COMPILE``: the same program compiled without LLVM optimization, and the
run-once options themselves.

White-box: reads internals of ``diracvi.driver.plan``, ``diracvi.runtime``,
``diracvi.runtime.compile``."""

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.driver.plan import clear_cache
from diracvi.runtime import compile as _compile
from diracvi.runtime import store as _stored
from diracvi.runtime.compile import FAST_COMPILE_ENV, fast_compile, loop_options, run_once_options


def test_fast_compiled_chunks_give_the_default_trajectory(monkeypatch, tmp_path):
    problem = problems.get("rlc")
    # an empty program store: both chunks are compiled here, not loaded from another test's
    monkeypatch.setattr(_stored, "folder", lambda: tmp_path)
    jit, options = _compile.jax.jit, {}

    def spy(fn, **kwargs):  # what the marching chunk (its function is `flat`) is compiled with
        if getattr(fn, "__name__", "") == "flat":
            options[value] = kwargs.get("compiler_options")
        return jit(fn, **kwargs)

    monkeypatch.setattr(_compile.jax, "jit", spy)
    runs = {}
    for value in ("0", "1"):
        monkeypatch.setenv(FAST_COMPILE_ENV, value)
        clear_cache()  # a fresh plan: its chunk is compiled under this setting
        runs[value] = dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps=300)
    assert options == {"0": None, "1": run_once_options()}
    a, b = runs["0"], runs["1"]
    scale = np.max(np.abs(a.q))
    # the same HLO: only the machine code's rounding (operation order, fused multiply-adds)
    np.testing.assert_allclose(b.q, a.q, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(b.energy, a.energy, rtol=1e-12)


@pytest.mark.parametrize(("value", "expected"), [("", False), ("0", False), ("1", True)])
def test_the_setting_is_read_as_documented(monkeypatch, value, expected):
    monkeypatch.setenv(FAST_COMPILE_ENV, value)
    assert fast_compile() is expected


def test_a_misspelt_setting_is_refused_with_the_fix(monkeypatch):
    monkeypatch.setenv(FAST_COMPILE_ENV, "yes")
    with pytest.raises(ValueError, match=r"DIRACVI_FAST_COMPILE='yes'.*set it to 1"):
        fast_compile()


def test_run_once_options_drop_an_option_this_jaxlib_refuses(monkeypatch):
    """A jaxlib without the older fusion code generator's switch still compiles (without
    it); one with it gets it."""
    assert run_once_options()["xla_backend_optimization_level"] == 0
    jit = _compile.jax.jit

    def refusing(fn, compiler_options=None, **kwargs):
        if compiler_options and "xla_cpu_use_fusion_emitters" in compiler_options:
            raise RuntimeError("INVALID_ARGUMENT: No such compile option")
        return jit(fn, compiler_options=compiler_options, **kwargs)

    assert loop_options() == {"xla_cpu_use_fusion_emitters": False}
    _compile._older_fusion_known.cache_clear()
    monkeypatch.setattr(_compile.jax, "jit", refusing)
    try:
        refused, loop_refused = run_once_options(), loop_options()
    finally:
        _compile._older_fusion_known.cache_clear()
    assert refused == {
        "xla_backend_optimization_level": 0,
        "xla_llvm_disable_expensive_passes": True,
    }
    assert loop_refused == {}
    monkeypatch.undo()
    x = np.linspace(-3.0, 3.0, 101)
    fused = _compile.jax.jit(lambda x: jnp.sin(x) * x**3 + x, compiler_options=run_once_options())
    np.testing.assert_allclose(fused(x), np.sin(x) * x**3 + x, rtol=1e-15, atol=1e-15)
