"""``dv.simulate(..., save_only=names)``: a run that keeps chosen columns of its states.

What it keeps must be the whole run's values of those columns, bit for bit, on every
path: the circuit-scale sparse map (which never forms the other columns, and takes its
driven offsets from another program than the whole run's), the compiled chunk and the
warm-call path; bad names and combinations are refused, saying which and how to fix.
"""

from __future__ import annotations

import numpy as np
import pytest

import diracvi as dv
from diracvi import spice
from diracvi.bench.ladders import ladder
from diracvi.errors import ModelError
from diracvi.solvers.sparse_affine import SparseAffineSolver

SPARSE = "sparse affine step map (condensed to the nodes, SuperLU)"


def _kw(netlist, **extra):
    return dict(dt=netlist.dt, steps=netlist.steps, discretization="midpoint", **extra)


def _columns(system, traj):
    """The whole run's column indices of ``traj``'s chosen coordinates and rows."""
    return (
        [system.coords.index(c) for c in traj.coords],
        [system.constraint_names.index(c) for c in traj.constraint_names],
    )


def _assert_kept(system, full, part):
    qi, mi = _columns(system, part)
    np.testing.assert_array_equal(part.q, full.q[:, qi])
    np.testing.assert_array_equal(part.multipliers, full.multipliers[:, mi])
    np.testing.assert_array_equal(part.t, full.t)
    np.testing.assert_array_equal(part.step_index, full.step_index)
    for a, b in zip(part.final_state, full.final_state, strict=True):
        np.testing.assert_array_equal(a, b)
    assert part.p is None and part.energy is None and part.constraint_residual is None
    assert part.constraint_violation is None


@pytest.mark.parametrize(
    ("source", "save_every"), [(True, 1), (True, 4), (False, 1)], ids=["driven", "every4", "free"]
)
def test_sparse_path_keeps_the_whole_runs_columns(source, save_every):
    """A 20-stage ladder over 300 steps (two blocks of the sparse map, the second
    partial): the kept node voltages' multipliers and charges are the whole run's,
    bit for bit, driven (the offsets from the drivers' own program) or autonomous."""
    netlist = spice.read(ladder(20, steps=300, source=source, v0=0.0 if source else 1.0))
    system = netlist.system
    names = ["KCL(n3)", "L7.q", "KCL(m20)", "C1.q", "KCL(n0)" if source else "KCL(n1)"]
    kw = _kw(netlist, solver=SparseAffineSolver(), save_every=save_every)
    full = dv.simulate(system, netlist.q0, netlist.p0, **kw)
    part = dv.simulate(system, netlist.q0, netlist.p0, save_only=names, **kw)
    assert full.solver == part.solver == SPARSE
    assert part.coords == ("L7.q", "C1.q")  # in the order named, coordinates then rows
    assert part.constraint_names == tuple(n for n in names if n.startswith("KCL"))
    assert part.q.shape == (300 // save_every + 1, 2)
    assert part.multipliers.shape == (300 // save_every, 3)
    _assert_kept(system, full, part)
    # a waveform of the kept columns is the whole run's (the sampler reads only them)
    assert np.max(np.abs(part.multiplier("KCL(n3)"))) > 0.0
    np.testing.assert_array_equal(part["L7.q"], full["L7.q"])


def test_chunk_and_warm_paths_keep_the_whole_runs_columns():
    """A 3-stage ladder (the dense affine map in a compiled chunk): the first call, the
    warm call after it, and a whole run after both (the warm paths are kept apart)."""
    netlist = spice.read(ladder(3, steps=50))
    system = netlist.system
    kw = _kw(netlist)
    full = dv.simulate(system, netlist.q0, netlist.p0, **kw)
    names = ("C2.q", "KCL(n1)")
    first = dv.simulate(system, netlist.q0, netlist.p0, save_only=names, **kw)
    warm = dv.simulate(system, netlist.q0, netlist.p0, save_only=list(names), **kw)
    again = dv.simulate(system, netlist.q0, netlist.p0, **kw)
    assert first.solver == "affine step map"
    _assert_kept(system, full, first)
    _assert_kept(system, full, warm)
    np.testing.assert_array_equal(again.p, full.p)
    assert again.q.shape == full.q.shape


def test_newton_path_keeps_the_whole_runs_columns():
    """A nonlinear mechanical model (the torn double pendulum, Newton in the compiled
    chunk): the option is the same cut of the same run."""
    from diracvi import problems

    problem = problems.double_pendulum_torn(dt=0.01, steps=40)
    system = problem.system
    kw = dict(dt=0.01, steps=40)
    full = dv.simulate(system, problem.q0, problem.p0, **kw)
    names = [system.constraint_names[-1], system.coords[0]]
    part = dv.simulate(system, problem.q0, problem.p0, save_only=names, **kw)
    assert "Newton" in part.solver or "newton" in part.solver.lower()
    assert part.coords == (system.coords[0],)
    assert part.constraint_names == (system.constraint_names[-1],)
    _assert_kept(system, full, part)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        (dict(save_only=["nope.q"]), "neither a coordinate nor a constraint row"),
        (dict(save_only="C1.q"), "a sequence of names"),
        (dict(save_only=[]), "no column to keep"),
        (dict(save_only=["C1.q", "C1.q"]), "appears twice"),
        (dict(save_only=["C1.q"], save_states=False), "save_states=True"),
        (dict(save_only=["C1.q"], checkpoint="x.nc"), "checkpoint"),
    ],
)
def test_bad_choices_are_refused(kwargs, words):
    netlist = spice.read(ladder(2, steps=10))
    with pytest.raises(ModelError, match=words):
        dv.simulate(netlist.system, netlist.q0, netlist.p0, **_kw(netlist, **kwargs))


def test_a_cut_trajectory_is_not_written_as_a_whole_one():
    netlist = spice.read(ladder(2, steps=10))
    part = dv.simulate(netlist.system, netlist.q0, netlist.p0, **_kw(netlist, save_only=["C1.q"]))
    with pytest.raises(ModelError, match="chosen columns only"):
        part.to_xarray()


def test_waveforms_of_the_kept_columns():
    """``spice.waveforms`` of a run of chosen columns: the signals of the kept columns
    (a node from its KCL row, a current from its charge), equal to the whole run's."""
    from diracvi.spice import waveforms

    netlist = spice.read(ladder(20, steps=300))
    assembly, system = netlist.assembly, netlist.system
    kw = _kw(netlist, solver=SparseAffineSolver())
    names = [assembly.kcl_rows["n5"], assembly.currents["L2"], assembly.currents["V1"]]
    part = dv.simulate(system, netlist.q0, netlist.p0, save_only=names, **kw)
    whole = waveforms(netlist, dv.simulate(system, netlist.q0, netlist.p0, **kw))
    waves = waveforms(netlist, part)
    assert sorted(waves) == ["i(L2)", "i(V1)", "v(n5)"]
    for key, values in waves.items():
        np.testing.assert_array_equal(values, whole[key])


def test_refused_under_a_transformation():
    """The cut is made on the host: inside jax.grad the option is refused, naming the fix."""
    import jax

    netlist = spice.read(ladder(2, steps=10))
    kw = _kw(netlist, save_only=["C1.q"])

    def loss(q0):
        return dv.simulate(netlist.system, q0, netlist.p0, **kw).q.sum()

    with pytest.raises(ModelError, match="host run's option"):
        jax.grad(loss)(np.asarray(netlist.q0))
