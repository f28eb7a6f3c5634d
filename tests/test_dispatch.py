"""Importing diracvi makes JAX run CPU programs on the calling thread (diracvi.runtime.dispatch),
unless DIRACVI_CPU_ASYNC_DISPATCH=1 keeps JAX's default, and says so truthfully when
JAX's CPU client existed before the import.

White-box: reads internals of ``diracvi.runtime``."""

import os
import subprocess
import sys

import pytest

from diracvi.runtime import dispatch as _dispatch

PROBE = """
import sys
if sys.argv[1] == "jax-first":
    import jax
    jax.numpy.ones(2).block_until_ready()  # JAX's CPU client exists before diracvi
import diracvi
from jax._src import xla_bridge
print(diracvi.runtime.dispatch.synchronous(), xla_bridge._CPU_ENABLE_ASYNC_DISPATCH.value)
"""


def test_import_sets_synchronous_cpu_dispatch_unless_kept_or_too_late():
    cases = {
        "default": ({}, "plain", "True False"),
        "kept": ({_dispatch.ASYNC_ENV: "1"}, "plain", "False True"),
        "explicit 0": ({_dispatch.ASYNC_ENV: "0"}, "plain", "True False"),
        # the client was created asynchronous; the option changes, the client does not
        "client first": ({}, "jax-first", "False False"),
    }
    base = {k: v for k, v in os.environ.items() if k != _dispatch.ASYNC_ENV}
    procs = {
        name: subprocess.Popen(
            [sys.executable, "-c", PROBE, mode],
            env={**base, **env},
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for name, (env, mode, _) in cases.items()
    }
    for name, proc in procs.items():
        out, err = proc.communicate(timeout=120)
        assert proc.returncode == 0, err
        assert out.split("\n")[-2] == cases[name][2], (name, out)


@pytest.mark.parametrize("value", ["yes", "2", "true"])
def test_a_setting_it_does_not_understand_names_the_variable_and_the_fix(monkeypatch, value):
    monkeypatch.setenv(_dispatch.ASYNC_ENV, value)
    with pytest.raises(ValueError, match=rf"{_dispatch.ASYNC_ENV}='{value}'.*Fix: set it to 1"):
        _dispatch.keep_async()
