"""A check shared by the packing tests: one step packed equals one step part by part."""

from __future__ import annotations

import jax
import numpy as np

from diracvi.discretization.rules import get_rule
from diracvi.driver import events
from diracvi.driver.tries import one_step
from diracvi.solvers.newton import NewtonSolver


def assert_packed_step_equals_plain(netlist, t, sizes):
    """One variable step (Newton, the junctions limited) of each size in ``sizes`` from
    the netlist's operating point at ``t``, packed (alike parts stacked) and part by
    part: both converge and agree to 1e-12 of each array's largest value (the vmapped
    groups sum in another order)."""
    op = netlist.operating_point()
    rule, solver = get_rule("midpoint"), NewtonSolver(reuse_jacobian=True)
    mu = np.zeros(netlist.system.m)
    out = []
    for system in (netlist.system, events.packed_unless_switched(netlist.system)):

        def step(h, t, q, p, system=system):
            return one_step(system, rule, solver, h, t, q, p, q, mu)

        out.append([jax.jit(step)(h, t, op.q0, op.p0) for h in sizes])
    for plain, packed in zip(*out, strict=True):
        assert bool(plain[3]) and bool(packed[3])  # both converged
        for a, b in zip(plain[:2], packed[:2], strict=True):
            a, b = np.asarray(a), np.asarray(b)
            assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a))
