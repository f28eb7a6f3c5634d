"""``DIRACVI_FAST_COMPILE``: the same program compiled without LLVM optimization."""

import numpy as np
import pytest

import diracvi as dv
from diracvi import _compile, problems
from diracvi._compile import FAST_COMPILE_ENV, RUN_ONCE_OPTIONS, fast_compile
from diracvi._plan import clear_cache


def test_fast_compiled_chunks_give_the_default_trajectory(monkeypatch):
    problem = problems.get("rlc")
    jit, options = _compile.jax.jit, {}

    def spy(fn, **kwargs):  # what the marching chunk is compiled with
        options[value] = kwargs.get("compiler_options")
        return jit(fn, **kwargs)

    monkeypatch.setattr(_compile.jax, "jit", spy)
    runs = {}
    for value in ("0", "1"):
        monkeypatch.setenv(FAST_COMPILE_ENV, value)
        clear_cache()  # a fresh plan: its chunk is compiled under this setting
        runs[value] = dv.simulate(problem.system, problem.q0, problem.p0, dt=0.01, steps=300)
    assert options == {"0": None, "1": RUN_ONCE_OPTIONS}
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
