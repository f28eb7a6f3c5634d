"""The program store (diracvi.runtime.store): a second process loads the first one's compiled
programs without tracing, gets bitwise the same run, and a key never confuses two
programs — what the key cannot represent is compiled as before.

White-box: reads internals of ``diracvi.runtime``, ``diracvi.runtime.fingerprint``,
``diracvi.runtime.program``, ``diracvi.runtime.store``, ``diracvi.solvers``."""

import functools
import json
import os
import subprocess
import sys
import time
from collections import OrderedDict

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi.runtime import fingerprint as _fingerprint
from diracvi.runtime import mappings as _mappings
from diracvi.runtime import store as _stored
from diracvi.runtime.fingerprint import Unstorable, canonical
from diracvi.runtime.program import lift
from diracvi.runtime.store import StoredJit

# A torn model in a fresh process: what the store did (its log) and the run's bits.
CHILD = """
import hashlib, json, logging, sys
records = []
class Keep(logging.Handler):
    def emit(self, record):
        records.append(record.getMessage())
logging.getLogger("diracvi.runtime.store").addHandler(Keep())
logging.getLogger("diracvi.runtime.store").setLevel(logging.DEBUG)
import jax
traces = []
jax.monitoring.register_event_duration_secs_listener(
    lambda name, *a, **k: traces.append(name) if name.endswith("trace_duration") else None
)
import diracvi as dv
from diracvi import problems
from diracvi.runtime import store as _stored
if sys.argv[2] == "off":  # JAX's cache only, as before the store
    _stored.enabled = lambda: False
pr = problems.get(sys.argv[1])
traces.clear()  # building the problem traces its user functions once (lifting)
tr = dv.simulate(pr.system, pr.q0, pr.p0, dt=pr.dt, steps=100)
digest = hashlib.sha256(tr.q.tobytes() + tr.p.tobytes() + tr.energy.tobytes()).hexdigest()
print(json.dumps({"log": records, "traces": len(traces), "digest": digest}))
"""


def _child(cache, problem, store="on"):
    env = {**os.environ, "DIRACVI_CACHE_DIR": str(cache)}
    out = subprocess.run(
        [sys.executable, "-c", CHILD, problem, store], env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1])


# in `-m slow` (15 s; the default suite's time on CI): by default a second process reads
# the first one's programs in tests/test_cache.py (test_second_process_reads_the_first_ones_...)
@pytest.mark.parametrize(
    "problem",
    [
        pytest.param("double-pendulum-torn", marks=pytest.mark.slow),
        pytest.param("rlc-torn", marks=pytest.mark.slow),
    ],
)
def test_a_later_process_loads_every_program_and_traces_nothing(tmp_path, problem):
    # JAX's cache already holds the programs (an earlier diracvi, or the store off): the
    # store must still compile them afresh (an executable read from JAX's cache does not
    # serialize whole), and a later process loads and runs them
    before = _child(tmp_path, problem, store="off")
    first = _child(tmp_path, problem)
    written = [m for m in first["log"] if m.startswith("stored program written")]
    assert written and first["traces"] > 0
    second = _child(tmp_path, problem)
    hits = [m for m in second["log"] if m.startswith("stored program hit")]
    assert sorted(m.split()[-1] for m in hits) == sorted(m.split()[-1] for m in written)
    assert second["traces"] == 0  # nothing traced, lowered or compiled
    assert second["digest"] == first["digest"] == before["digest"]  # bitwise the same run


def _oscillator(k):
    return dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v - 0.5 * k * q @ q)


def test_the_key_is_what_a_trace_can_see():
    # closures with different numbers: one program, the numbers are leaves (avals only)
    assert canonical(_oscillator(1.0)) == canonical(_oscillator(4.0))
    assert canonical(_oscillator(1.0), values=True) != canonical(_oscillator(4.0), values=True)
    # a different computation, or another shape, is another key
    cubic = dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v - 0.25 * jnp.sum(q**4))
    assert canonical(cubic) != canonical(_oscillator(1.0))
    assert canonical(np.zeros(3)) != canonical(np.zeros(4)) != canonical(np.zeros(4, np.int32))
    # numbers and strings by value; a NumPy scalar is an array (traced), a float is not
    assert canonical((1.0, "plus")) != canonical((2.0, "plus")) != canonical((1.0, "minus"))
    assert canonical(np.float64(1.0)) == canonical(np.float64(2.0))
    spec = jax.ShapeDtypeStruct((3,), jnp.float64)
    assert canonical(spec) != canonical(jax.ShapeDtypeStruct((4,), jnp.float64))


@pytest.mark.filterwarnings("ignore:A JAX array is being set as static")
def test_an_array_in_a_static_field_is_keyed_by_value():
    class Holder(eqx.Module):  # a diracvi-like Module (the check is on the field)
        table: np.ndarray = eqx.field(static=True)

    Holder.__module__, Holder.__qualname__ = "diracvi._test_holder", "Holder"
    a, b = Holder(np.array([1.0, 2.0])), Holder(np.array([1.0, 3.0]))
    assert canonical(a) != canonical(b)


def _module_level_lambda():
    f = lambda x: x  # noqa: E731 (a lambda is the point)
    f.__module__, f.__qualname__ = "diracvi._somewhere", "<lambda>"
    return f


def test_what_the_key_cannot_represent_is_refused():
    class Users(eqx.Module):  # a class of the user's: its methods are not in the key
        k: float = 1.0

    refused = [
        lambda x: x,  # a user's function kept whole
        _module_level_lambda(),  # its name does not say which lambda of the module it is
        Users(),
        functools.partial(_double, scale=2.0),  # a function of the user's, partially applied
    ]
    for obj in refused:
        with pytest.raises(Unstorable):
            canonical(obj)

    def opaque(x):  # a custom derivative rule prints by name only
        return jax.nn.relu(x).sum()

    program = lift(opaque, [(3,)])[0]
    assert program.keep
    with pytest.raises(Unstorable, match="opaque"):
        canonical(program)


def test_a_diracvi_setting_is_part_of_the_key(monkeypatch):
    from diracvi.solvers import affine

    before = _fingerprint.key("f", "args", {})
    monkeypatch.setattr(affine, "MAX_BLOCK", affine.MAX_BLOCK + 1)
    assert _fingerprint.key("f", "args", {}) != before
    assert _fingerprint.key("f", "args", {"xla_backend_optimization_level": 0}) != before


def _double(x, scale):
    return 2.0 * x * scale


def _new_process(monkeypatch):
    """Forget the executables this process holds, as a new process starts."""
    monkeypatch.setattr(_stored, "_LOADED", OrderedDict())


def test_calls_load_compile_fall_back_and_survive_a_damaged_file(tmp_path, monkeypatch):
    monkeypatch.setattr(_stored, "folder", lambda: tmp_path)
    _new_process(monkeypatch)
    program = StoredJit(_double, "tests._double", dict)
    x = np.arange(3.0)
    np.testing.assert_array_equal(program(x, 1.5), 3.0 * x)
    (stored,) = tmp_path.glob("*.exe")
    np.testing.assert_array_equal(program(x, 2.0), 4.0 * x)  # a static float: a new key
    assert len(list(tmp_path.glob("*.exe"))) == 2
    # a new StoredJit in a new process loads the file; a damaged one is recompiled
    _new_process(monkeypatch)
    np.testing.assert_array_equal(StoredJit(_double, "tests._double", dict)(x, 1.5), 3.0 * x)
    stored.write_bytes(b"not an executable")
    _new_process(monkeypatch)
    np.testing.assert_array_equal(StoredJit(_double, "tests._double", dict)(x, 1.5), 3.0 * x)
    assert stored.read_bytes() != b"not an executable"  # overwritten by the new program
    # under a transformation the call is traced as before
    grad = jax.grad(lambda y: program(y, 1.5).sum())(x)
    np.testing.assert_array_equal(grad, np.full(3, 3.0))


def test_a_program_this_process_holds_is_not_loaded_again(tmp_path, monkeypatch):
    # a model read again from the same netlist has new StoredJits with the same keys:
    # the executable compiled (or loaded) for the first is reused, not read from disk
    monkeypatch.setattr(_stored, "folder", lambda: tmp_path)
    _new_process(monkeypatch)
    x = np.arange(3.0)
    np.testing.assert_array_equal(StoredJit(_double, "tests._double", dict)(x, 1.5), 3.0 * x)
    loads = []
    real_load = _stored.load
    monkeypatch.setattr(_stored, "load", lambda key_: loads.append(key_) or real_load(key_))
    again = StoredJit(_double, "tests._double", dict)
    np.testing.assert_array_equal(again(x, 1.5), 3.0 * x)
    assert loads == []
    np.testing.assert_array_equal(again(x, 2.0), 4.0 * x)  # another key: looked for on disk
    assert len(loads) == 1
    # bounded as the StoredJits' own maps are: the least recently used goes
    monkeypatch.setattr(_stored, "MEMORY_LIMIT", 1)
    np.testing.assert_array_equal(again(x, 3.0), 6.0 * x)
    assert len(_stored._LOADED) == 1


def test_the_store_keeps_the_most_recently_used_within_its_bound(tmp_path):
    for i, size in enumerate((100, 200, 300)):
        path = tmp_path / f"{i}.exe"
        path.write_bytes(b"x" * size)
        os.utime(path, (1000 + i, 1000 + i))
    stale, fresh = tmp_path / ".k.1.tmp", tmp_path / ".k.2.tmp"  # unfinished writes
    for path, age in ((stale, 2 * _stored.STALE_SECONDS), (fresh, 0.0)):
        path.write_bytes(b"t")
        os.utime(path, (time.time() - age,) * 2)
    assert _stored.prune(tmp_path, 520) == 1  # the oldest goes first
    assert sorted(p.name for p in tmp_path.glob("*.exe")) == ["1.exe", "2.exe"]
    assert not stale.exists() and fresh.exists()  # another process may be writing that one
    assert _stored.prune(tmp_path, 0) == 2


def test_interaction_functions_are_lifted_like_lagrangians():
    # joints built in a loop with different lengths: one program, their own constants
    def joint(length):
        return dv.Interaction(lambda q: jnp.array([[1.0, -length * jnp.cos(q[1])]]))

    parts = [dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v, name=n) for n in "ab"]
    short, long_ = (dv.interconnect(parts, [joint(s)]) for s in (1.0, 2.0))
    (a,), (b,) = short.interactions, long_.interactions
    assert a._fn is b._fn  # the same (interned) program, each with its own constants
    q = np.array([0.3, 0.4])
    np.testing.assert_allclose(short.interaction_forms(q), [[1.0, -np.cos(0.4)]], rtol=1e-15)
    np.testing.assert_allclose(long_.interaction_forms(q), [[1.0, -2 * np.cos(0.4)]], rtol=1e-15)


def _lagrangian_at(system, q):
    return system.lagrangian(q, q, 0.0)


def test_repeated_calls_on_a_model_use_its_own_numbers(tmp_path, monkeypatch):
    # a call on the same model object skips re-flattening it; a model freed and another
    # built (often at the same address) must not inherit its arrays
    monkeypatch.setattr(_stored, "folder", lambda: tmp_path)
    program = StoredJit(_lagrangian_at, "tests._lagrangian_at", dict)
    q = np.array([2.0])
    for k in (1.0, 2.0, 3.0, 4.0):
        system = _oscillator(k)
        for _ in range(2):
            assert float(program(system, q)) == 0.5 * 4.0 - 0.5 * k * 4.0
        del system


def test_a_function_lifted_inside_a_trace_leaves_no_tracer_in_the_cache():
    # a model built inside a function under jit or grad lifts its user functions there;
    # the lifted constants are cached for later calls, so they must be concrete arrays,
    # not the trace's own values (the quadrotor's index arrays were: UnexpectedTracerError
    # on the next gradient)
    index = np.array([2, 0, 1])

    def user(q):
        return jnp.sum(q[index] * np.array([1.0, 2.0, 3.0]))

    @jax.jit
    def build_inside(x):
        lift(user, [(3,)])
        return x

    build_inside(1.0)
    _, consts, _ = lift(user, [(3,)])
    assert consts and not any(isinstance(c, jax.core.Tracer) for c in consts)
    assert float(jax.jit(lambda x: build_inside(x) + 1.0)(1.0)) == 2.0


def _solve_shifted(a):
    # an LU and a loop: an executable with several kernels, each in mappings of its own
    n = a.shape[0]
    x = jnp.linalg.solve(2.0 * jnp.eye(n) + a, a[0])
    return jax.lax.fori_loop(0, 3, lambda i, y: 1.5 * y, x)


def test_executables_are_dropped_before_the_processs_mappings_run_out(tmp_path, monkeypatch):
    # Linux allows vm.max_map_count mappings a process and every live XLA executable holds
    # dozens (diracvi.runtime.mappings): a process that compiled ~1400 programs died in
    # serialize_executable at 65 433 mappings. With the budget set a few programs above
    # this process's count, 16 more programs would pass it by ~13 programs' mappings; the
    # relief keeps the count within two compiles' growth of the budget, and a dropped
    # program still answers (loaded again from disk) with the same bits.
    if _mappings.count() is None:
        pytest.skip("no /proc/self/maps here: no mapping limit to keep under")
    monkeypatch.setattr(_stored, "folder", lambda: tmp_path)
    _new_process(monkeypatch)
    program = StoredJit(_solve_shifted, "tests._solve_shifted", dict)
    counts = [_mappings.count()]
    for n in (2, 3, 4):  # what one program takes in this process (freed regions are reused)
        program(np.full((n, n), 0.1))
        counts.append(_mappings.count())
    first = program(np.full((2, 2), 0.1))
    one_program = int(max(np.diff(counts)))
    assert one_program > 10  # premise: an executable's mappings are counted here
    budget = counts[-1] + 3 * one_program
    monkeypatch.setattr(_mappings, "BUDGET", budget)
    drops = []
    real_drop = _stored._drop_programs
    monkeypatch.setattr(_stored, "_drop_programs", lambda: drops.append(1) or real_drop())
    counts = [counts[-1]]
    for n in range(5, 21):
        a = np.full((n, n), 0.1)
        np.testing.assert_allclose(program(a), _solve_shifted(jnp.asarray(a)), rtol=1e-14)
        counts.append(_mappings.count())
    growth = max(one_program, int(max(np.diff(counts))))  # the most one compile added
    assert drops  # the budget was reached ...
    assert max(counts) <= budget + 2 * growth  # ... and the count held near it
    np.testing.assert_array_equal(program(np.full((2, 2), 0.1)), first)  # a dropped one
