"""Newton's early stops (the variable-step loop's): what is left in the iterate kept.

- ``NewtonSolver(predict_stop=True)`` keeps an iterate when the next chord update,
  predicted as ``θ |dx|`` from the observed contraction, would pass the stopping test:
  the error left is then that next update's size over ``1 − θ``, so within about the
  test's own tolerance of the converged solution.
- ``solve(..., atol=…)`` stops once an update that contracted by ``θ ≤ 1/4`` against
  the one before it is within its bound: in Newton's contracting phase the error left is
  then at most ``|dx|/3``. (Before it, an update bounds nothing: on the step below from
  the previous state, the first update within a bound of 1e-2 of the increment left
  1.5 times the bound, so that phase is not what is asserted.)

Both are checked against the same step solved to round-off, on a diode turning on
within one long step (Newton's limited iterations on an exponential), with the tests'
tolerance made loose (1e-6 of the increment) so the error left is far above round-off.
"""

from __future__ import annotations

import functools

import jax.numpy as jnp
import numpy as np

from diracvi import spice
from diracvi.discretization.equations import StepEquations, first_guess
from diracvi.discretization.rules import get_rule
from diracvi.solvers.newton import NewtonSolver

DECK = """diode turning on within a step
V1 in 0 SIN(0 10 1k)
D1 in out dx
R1 out 0 1k
C1 out 0 1u
.model dx D(is=1e-14 rs=1 cjo=2p)
.tran 1u 1m
.end
"""

LOOSE = 1e-6


@functools.cache
def _step(h):
    netlist = spice.read(DECK)
    system = netlist.system
    rule = get_rule("midpoint")
    q, p = jnp.asarray(netlist.q0), jnp.asarray(netlist.p0)
    eqs = StepEquations(system, rule, "plus", h, q, p, 0.0)
    guess = first_guess(system, rule, q, q, jnp.zeros(system.m))
    return eqs, guess


@functools.cache
def _exact(h):
    """The step of ``_step(h)`` from its guess, solved to round-off: (x, iterations)."""
    eqs, guess = _step(h)
    solver = NewtonSolver(reuse_jacobian=True)
    res = solver.solve(eqs, guess, solver.init(eqs))
    assert int(res.status) == 0
    return np.asarray(res.x), int(res.iterations)


def test_a_predicted_stop_keeps_an_iterate_within_the_test_of_the_solution():
    eqs, guess = _step(2.5e-4)
    exact, _ = _exact(2.5e-4)
    increment = np.max(np.abs(exact - np.asarray(eqs.reference())))
    counts = {}
    for predict in (False, True):
        solver = NewtonSolver(rtol=LOOSE, reuse_jacobian=True, predict_stop=predict)
        res = solver.solve(eqs, guess, solver.init(eqs))
        assert int(res.status) == 0
        counts[predict] = int(res.iterations)
        # θ ≤ 1/4: what is left is at most (4/3) of the tolerance
        assert np.max(np.abs(np.asarray(res.x) - exact)) <= 4 / 3 * LOOSE * increment
    assert counts[True] < counts[False], counts  # the confirming iteration saved


def test_a_predicted_stop_waits_for_a_contraction_of_its_own_solve():
    """Factors kept from another solve (another step size) have no contraction observed
    in this one: the first chord update with them is not a stop by prediction."""
    eqs, guess = _step(2.5e-4)
    exact, _ = _exact(2.5e-4)
    increment = np.max(np.abs(exact - np.asarray(eqs.reference())))
    solver = NewtonSolver(rtol=LOOSE, reuse_jacobian=True, predict_stop=True)
    other, other_guess = _step(1.0e-4)
    earlier = solver.solve(other, other_guess, solver.init(other))
    assert int(earlier.status) == 0 and bool(earlier.state[-1])  # factors kept as valid
    res = solver.solve(eqs, guess, earlier.state)
    assert int(res.status) == 0
    assert int(res.iterations) >= 2
    assert np.max(np.abs(np.asarray(res.x) - exact)) <= 4 / 3 * LOOSE * increment


def test_an_absolute_stop_leaves_at_most_its_bound():
    """From a guess the step's increment off in every unknown by 5 % (the variable-step
    loop's coarse step starts from an extrapolation), the first update within ``atol``
    after a contraction leaves less than ``atol`` in every unknown."""
    eqs, _ = _step(2.5e-4)
    exact, _ = _exact(2.5e-4)
    change = exact - np.asarray(eqs.reference())
    guess = jnp.asarray(exact + 0.05 * change)
    solver = NewtonSolver(reuse_jacobian=True)
    full = int(solver.solve(eqs, guess, solver.init(eqs)).iterations)
    for share in (1e-2, 1e-4, 1e-6):
        atol = jnp.asarray(share * np.max(np.abs(change)) * np.ones_like(exact))
        res = solver.solve(eqs, guess, solver.init(eqs), atol=atol)
        assert int(res.status) == 0
        assert int(res.iterations) <= full
        assert np.all(np.abs(np.asarray(res.x) - exact) <= np.asarray(atol)), share


def test_an_absolute_stop_waits_for_a_contraction():
    """An update of a solve that has not yet contracted (the first, with fresh factors)
    is not taken as final however small: from 1e-8 of the increment off the solution the
    first update is within a bound of 1e-6 of it, and a second is still taken."""
    eqs, _ = _step(2.5e-4)
    exact, _ = _exact(2.5e-4)
    change = exact - np.asarray(eqs.reference())
    solver = NewtonSolver(reuse_jacobian=True)
    atol = jnp.asarray(np.full_like(exact, 1e-6 * np.max(np.abs(change))))
    res = solver.solve(eqs, jnp.asarray(exact + 1e-8 * change), solver.init(eqs), atol=atol)
    assert int(res.status) == 0 and int(res.iterations) == 2
