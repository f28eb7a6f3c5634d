"""Upstream reproducer: jaxlib 0.10.2 (CPU) compiles a StableHLO module with LAPACK
typed-FFI calls on two CPUs and refuses it when the process may use only one:

    NOT_FOUND: No registered implementation for untyped custom call to
    lapack_dtrsm_ffi for Host

Usage: python lapack_one_cpu.py [lapack_one_cpu.mlir]
The module (216 lines) is diracvi's marching program reduced by deleting functions and
operations while the one-CPU compile kept failing and the two-CPU compile kept passing.
Its custom calls are JAX's lowering of typed FFI: api_version 1 (the default) with the
attributes in ``mhlo.backend_config``. Rewriting them as ``api_version = 4`` with the
dictionary as ``backend_config`` makes both compiles pass (the ``--typed`` run).
"""

import os
import re
import subprocess
import sys
import tempfile

COMPILE = r"""
import os, sys
cpus = sys.argv[2]
if cpus != "all":
    os.sched_setaffinity(0, {int(cpus)})  # before XLA starts
import jax
jax.config.update("jax_enable_x64", True)
from jax._src import xla_bridge as xb
from jax._src.interpreters import mlir
from jax._src.lib import xla_client as xc
from jax._src.lib.mlir import ir
import jax._src.lax.linalg  # registers the LAPACK targets
text = open(sys.argv[1]).read()
backend = xb.get_backend()
with mlir.make_ir_context():
    payload = mlir.module_to_bytecode(ir.Module.parse(text))
try:
    devices = xc.DeviceList(tuple(backend.devices()))
    backend.compile_and_load(payload, executable_devices=devices,
                             compile_options=xc.CompileOptions())
    print("compiled")
except Exception as e:
    print("FAILED:", str(e).splitlines()[0][:120])
"""


def typed(text):
    """The same module with each custom call as api_version = 4, dictionary backend_config."""
    return re.sub(
        r'backend_config = "", mhlo\.backend_config = (\{[^}]*\})',
        r"api_version = 4 : i32, backend_config = \1",
        text,
    )


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "lapack_one_cpu.mlir")
    fixed = os.path.join(tempfile.mkdtemp(), "typed.mlir")
    with open(path) as f, open(fixed, "w") as g:
        g.write(typed(f.read()))
    one = str(min(os.sched_getaffinity(0)))
    for label, module in (("as JAX lowers it", path), ("typed (api_version = 4)", fixed)):
        for cpus in ("all", one):
            out = subprocess.run(
                [sys.executable, "-c", COMPILE, module, cpus], capture_output=True, text=True
            )
            last = (out.stdout or out.stderr).strip().splitlines()[-1]
            print(f"{label:24s} cpus={cpus:4s} {last}")


if __name__ == "__main__":
    main()
