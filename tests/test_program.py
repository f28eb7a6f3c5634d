"""User functions are alike by what they compute (traced programs, constants lifted):
closures from a loop group and vmap, and each piece still computes with its own numbers.

White-box: reads internals of ``diracvi.runtime.program``."""

import jax.numpy as jnp
import numpy as np
import pytest

import diracvi as dv
from diracvi import problems
from diracvi.runtime.program import lift


def _closure_chain(n: int, m: int):
    """The torn chain of ``problems.chain_torn(n, m)``, built as a user would: a fresh
    closure per piece over that piece's masses and stiffnesses."""
    mass = 1.0 + 0.5 * np.sin(np.arange(n)) ** 2
    stiff = 1.0 + 0.3 * np.cos(np.arange(n)) ** 2
    bounds = np.linspace(0, n, m + 1).round().astype(int)
    pieces, joints = [], []
    for j in range(m):
        lo, hi = bounds[j], bounds[j + 1]
        mj, kj = jnp.asarray(mass[lo:hi]), jnp.asarray(stiff[lo:hi])
        coords = tuple(f"q{i}" for i in range(hi - lo))
        if j == 0:

            def lagrangian(q, v, mj=mj, kj=kj):
                stretch = jnp.concatenate([q[:1], q[1:] - q[:-1]])
                return 0.5 * jnp.sum(mj * v**2) - 0.5 * jnp.sum(kj * stretch**2)

        else:
            coords = ("qbar", *coords)

            def lagrangian(q, v, mj=mj, kj=kj):
                return 0.5 * jnp.sum(mj * v[1:] ** 2) - 0.5 * jnp.sum(kj * (q[1:] - q[:-1]) ** 2)

            joints.append(dv.connect(f"s{j - 1}.q{bounds[j] - bounds[j - 1] - 1}", f"s{j}.qbar"))
        pieces.append(dv.LagrangeDiracSystem(coords, lagrangian, name=f"s{j}"))
    return dv.interconnect(pieces, joints, name="chain")


# 12 s, in `-m slow` (CI time): grouping of alike pieces by default in tests/test_stacked.py
# (test_packed_trajectory_matches_unpacked, test_chunk_program_does_not_grow_with_alike_pieces)
@pytest.mark.slow
def test_loop_closures_group_and_match_the_module_built_chain():
    ref = problems.chain_torn(24, 6)  # pieces of 4 masses: the wall end, 4 alike, the free end
    system = _closure_chain(24, 6)
    layout = dv.PartitionedSolver.layout(system)
    assert layout.groups == (("s0",), ("s1", "s2", "s3", "s4"), ("s5",))
    assert layout == dv.PartitionedSolver.layout(ref.system)  # as the Module-built chain
    solver = dv.PartitionedSolver()
    a = dv.simulate(system, ref.q0, ref.p0, dt=0.01, steps=50, solver=solver)
    b = dv.simulate(ref.system, ref.q0, ref.p0, dt=0.01, steps=50, solver=solver)
    assert np.max(np.abs(a.q - b.q)) <= 1e-12
    assert np.max(np.abs(a.multipliers - b.multipliers)) <= 1e-12


def test_each_piece_keeps_its_own_literals():
    # two oscillators that differ only in a Python float: one program, two constants
    def oscillator(k, name):
        return dv.LagrangeDiracSystem(("x",), lambda q, v: 0.5 * v @ v - 0.5 * k * q @ q, name=name)

    soft, stiff = oscillator(1.0, "soft"), oscillator(4.0, "stiff")
    assert soft._lagrangian.rest is stiff._lagrangian.rest  # the same (interned) program
    dt, steps = 1e-2, 300
    t = dt * np.arange(steps + 1)
    for system, omega in ((soft, 1.0), (stiff, 2.0)):
        traj = dv.simulate(system, [1.0], [0.0], dt=dt, steps=steps, discretization="midpoint")
        assert np.max(np.abs(traj.q[:, 0] - np.cos(omega * t))) < 5e-4


def test_different_computations_are_different_programs():
    square = lift(lambda q: jnp.sum(q**2), [(3,)])
    cube = lift(lambda q: jnp.sum(q**3), [(3,)])
    assert square[0] != cube[0]
    captured = np.array([1.0, 2.0, 3.0])
    weighted = lift(lambda q: jnp.sum(captured * q), [(3,)])
    program, consts, out = weighted
    assert out.shape == ()
    assert float(program(consts, jnp.ones(3))) == 6.0
    # NumPy computes 2·captured while tracing: the same program with another constant
    doubled = lift(lambda q: jnp.sum(2.0 * captured * q), [(3,)])
    assert doubled[0] is program
    assert float(program(doubled[1], jnp.ones(3))) == 12.0


def test_functions_calling_jitted_numpy_functions_group():
    # jnp.clip is itself a jit: its device mesh parameter is data, not hidden code
    def piece(k):
        return dv.LagrangeDiracSystem(
            ("x",), lambda q, v: 0.5 * v @ v - k * jnp.sum(jnp.clip(q, -1.0, 1.0) ** 2)
        )

    a, b = piece(1.0), piece(2.0)
    assert a._lagrangian.rest is b._lagrangian.rest and not a._lagrangian.rest.keep


_GAIN = 1.0  # a module global read by the functions _scaled makes (rebound by a test)


def _scaled():
    return lambda q: _GAIN * jnp.sum(q)


@pytest.fixture
def traces(monkeypatch):
    """How many times ``lift`` traced (its cache missed), with the cache empty."""
    from diracvi.runtime import program

    count = [0]
    untraced = program._lift

    def counted(fn, shapes):
        count[0] += 1
        return untraced(fn, shapes)

    monkeypatch.setattr(program, "_LIFTED", {})
    monkeypatch.setattr(program, "_lift", counted)
    return count


def test_functions_equal_by_content_are_traced_once(traces):
    def make(k, table):
        def f(q):  # a closure over a float, an array, a dict and a nested closure
            def inner(x):
                return table["a"] * x

            return jnp.sum(inner(q)) * k

        return f

    table = {"a": np.array([1.0, 2.0, 3.0])}
    first = lift(make(2.0, table), [(3,)])
    again = lift(make(2.0, {"a": np.array([1.0, 2.0, 3.0])}), [(3,)])
    assert traces[0] == 1 and again is first  # equal content: no second trace
    other = lift(make(3.0, table), [(3,)])
    shifted = lift(make(2.0, {"a": np.array([1.0, 2.0, 4.0])}), [(3,)])
    assert traces[0] == 3  # another float, another array: traced
    assert other[0] is first[0]  # the same program with its own constants
    ones = jnp.ones(3)
    assert [float(p(c, ones)) for p, c, _ in (first, other, shifted)] == [12.0, 18.0, 14.0]
    # −0.0 and 0.0 compare equal but are different constants (a sign that can show)
    plus, minus = lift(make(0.0, table), [(3,)]), lift(make(-0.0, table), [(3,)])
    assert traces[0] == 5
    assert not np.signbit(plus[0](plus[1], ones)) and np.signbit(minus[0](minus[1], ones))
    # other argument shapes are another trace
    lift(make(2.0, table), [(4,)])
    assert traces[0] == 6


def test_a_rebound_global_is_traced_again(traces, monkeypatch):
    import sys

    # a fresh function of the same code each time (JAX itself does not trace one function
    # object twice): the global it reads is part of its content
    ones = jnp.ones(2)
    program, consts, _ = lift(_scaled(), [(2,)])
    assert float(program(consts, ones)) == 2.0
    lift(_scaled(), [(2,)])
    assert traces[0] == 1
    monkeypatch.setattr(sys.modules[__name__], "_GAIN", 5.0)
    program, consts, _ = lift(_scaled(), [(2,)])
    assert traces[0] == 2 and float(program(consts, ones)) == 10.0


def test_what_cannot_be_compared_by_content_is_always_traced(traces):
    from collections import Counter

    from diracvi.runtime.program import trace_key

    seen = Counter()  # a dict subclass: its items are not its __dict__

    def counting(q):
        return jnp.sum(q) * len(seen)

    assert trace_key(counting, [(2,)]) is None
    lift(counting, [(2,)])
    lift(counting, [(2,)])
    assert traces[0] == 2

    def recursive(q, n=2):  # reaches itself: no key
        return jnp.sum(q) if n == 0 else recursive(q, n - 1)

    assert trace_key(recursive, [(2,)]) is None


_NAND_PAIR = """two NAND gates of one subcircuit
.subckt nand a b out vdd
M1 out a vdd vdd p1 W=7.5u L=0.35u
M2 out b vdd vdd p1 W=7.5u L=0.35u
M3 out a mid 0 n1 W=3u L=0.35u
M4 mid b 0 0 n1 W=3u L=0.35u
D1 0 out dmod
.ends nand
VDD vdd 0 3.3
VA a 0 PULSE(0 3.3 1n 1n 1n 10n 20n)
X1 a vdd y vdd nand
X2 y a z vdd nand
.model n1 nmos level=1 vto=0.7 kp=1e-4 cbd=1f cgso=1e-10
.model p1 pmos level=1 vto=-0.7 kp=5e-5 cbd=1f cgso=1e-10
.model dmod d is=1e-15 cjo=1p
.tran 1n 40n
.end
"""


def test_a_subcircuits_alike_devices_are_traced_once_and_build_the_same_system(traces, monkeypatch):
    import jax

    from diracvi import spice
    from diracvi.runtime import program
    from diracvi.spice import _parse

    # each device built by its constructor (not the reader's alike parts, which are not
    # traced at all: tests/test_read_alike.py): what is counted is lift's memory
    monkeypatch.setattr(_parse, "REMEMBER_PARTS", False)
    cached = spice.read(_NAND_PAIR)
    with_cache = traces[0]
    monkeypatch.setattr(program, "trace_key", lambda fn, shapes: None)
    traced = spice.read(_NAND_PAIR)
    # the second gate's diode (two functions) is not traced: with the content key one
    # diode's functions are traced, without it both gates' (the level-1 MOSFETs are
    # Modules read once per class and traced by neither: tests/test_mos_module.py)
    assert with_cache > 0 and traces[0] - with_cache >= 2 * with_cache
    a, b = cached.system, traced.system
    assert jax.tree.structure(a) == jax.tree.structure(b)
    for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b), strict=True):
        assert np.array_equal(np.asarray(x), np.asarray(y))
    assert np.array_equal(cached.q0, traced.q0) and np.array_equal(cached.p0, traced.p0)
    assert cached.notes == traced.notes
