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
