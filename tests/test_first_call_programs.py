"""What a netlist's first call compiles: reading a deck with diodes, BJTs or MOSFETs
lowers no XLA program, and with a warm disk cache neither do its operating point and
its march (their programs are loaded from the store, untraced).

Counted in a fresh process, as a user's ``diracvi run`` is one: an eager ``jax.numpy``
operation is compiled once per process and operation shape, so in the test process
another test's history would hide it. The count is JAX's monitoring event for lowering a
program to MLIR, which every compilation passes (a persistent-cache hit included); the
child checks that the event is still emitted (one ``jax.jit`` call of its own), so a
JAX that renamed it fails here rather than counting nothing.

White-box: runs ``diracvi.spice._run``'s phases one by one."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

NETLISTS = Path(__file__).parent / "data" / "netlists"

CHILD = """
import json, sys
import jax
LOWERED = "/jax/core/compile/jaxpr_to_mlir_module_duration"
count = [0]
jax.monitoring.register_event_duration_secs_listener(
    lambda name, *a, **k: count.__setitem__(0, count[0] + (name == LOWERED))
)
from diracvi import spice
from diracvi.spice import _run

def phase():
    n, count[0] = count[0], 0
    return n

out = {"import": phase()}
for deck in sys.argv[2:]:
    netlist = spice.read(deck)
    netlist.system  # noqa: B018  (built: part of the read)
    out[deck] = {"read": phase()}
    if sys.argv[1] == "run":
        netlist.initial_state()
        out[deck]["operating point"] = phase()
        settings = _run.tran_settings(netlist)
        breaks = _run.breakpoints(netlist.system, 0.0, settings.stop)
        _run._march(netlist, settings, breaks)
        out[deck]["march"] = phase()
jax.jit(lambda x: x + 1.0)(2.0)  # the event is emitted: this program was lowered
out["probe"] = phase()
print(json.dumps(out))
"""


def _child(mode: str, decks: list[Path], cache=None) -> dict:
    env = dict(os.environ)
    if cache is not None:
        env["DIRACVI_CACHE_DIR"] = str(cache)
    out = subprocess.run(
        [sys.executable, "-c", CHILD, mode, *map(str, decks)],
        env=env,
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stderr
    found = json.loads(out.stdout.splitlines()[-1])
    assert found["probe"] == 1, found  # the counter sees a lowering
    return found


def test_reading_device_decks_lowers_no_program():
    """A diode (liec_halfwave), two BJTs (ng_rtlinv), MOSFETs (xy_invert1) and the 27
    MOSFETs of ng_mosamp: their parts, junction tables and the circuit are built in
    NumPy and Python (before, each eager ``jax.numpy`` operation of a part's tables and
    of its initial momentum was a program: 13 for the diode deck, 49 for the BJT one)."""
    decks = [NETLISTS / f"{n}.cir" for n in ("liec_halfwave", "ng_rtlinv", "xy_invert1")]
    decks.append(NETLISTS / "ng_mosamp.cir")
    found = _child("read", decks)
    assert found["import"] == 0
    assert {str(d): found[str(d)]["read"] for d in decks} == {str(d): 0 for d in decks}


@pytest.mark.parametrize(
    "deck", ["liec_halfwave", pytest.param("ng_rtlinv", marks=pytest.mark.slow)]
)
def test_a_warm_cache_serves_every_program_of_a_run(tmp_path, deck):
    """A second process on the cache the first one filled lowers nothing: the
    operating point's and the march's programs come from the store (before, the march's
    inertia probe and the junction tables compiled 2–3 eager programs in every process)."""
    path = NETLISTS / f"{deck}.cir"
    _child("run", [path], cache=tmp_path)
    warm = _child("run", [path], cache=tmp_path)
    assert warm[str(path)] == {"read": 0, "operating point": 0, "march": 0}


def test_a_netlist_read_inside_a_trace_keeps_its_parameters_traced():
    """The parts' initial momenta are one stored program with its own XLA options, which
    a nested ``jit`` refuses; read inside a trace (``params=`` of a traced fit, as
    ``examples/fit_netlist.py`` does) they are evaluated in the enclosing trace instead,
    and the run's value and derivative are the untraced ones (central differences)."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    from diracvi import spice

    deck = (
        "rectifier\n.param rload=1k\nV1 in 0 SIN(0 5 1k)\nD1 in out dmod\n"
        "R1 out 0 {rload}\nC1 out 0 1u\n.model dmod D(IS=1e-14)\n.tran 20u 0.4m UIC\n.end\n"
    )

    def last(r):
        return spice.run(deck, dt=20e-6, params={"rload": r})["v(out)"][-1]

    value, slope = jax.jit(jax.value_and_grad(last))(jnp.float64(1e3))
    assert np.isclose(float(value), float(last(1e3)), rtol=1e-12, atol=0.0)
    step = 1.0
    fd = (float(last(1e3 + step)) - float(last(1e3 - step))) / (2 * step)
    assert np.isclose(float(slope), fd, rtol=1e-5)
