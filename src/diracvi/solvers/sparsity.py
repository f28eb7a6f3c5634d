r"""Which entries of a subsystem's step Jacobian ``∂ρ/∂y`` can be nonzero (host side, once).

The pattern is read off ``jax.jacfwd`` of the subsystem's step residual at two random
points ``(q, p, y, h, t)``, with every floating array of the subsystem (masses,
stiffnesses, a traced program's lifted constants) replaced by random numbers in
``[0.5, 1.5]``: an entry that is zero at both is structurally zero except on a set of
measure zero, and the subsystem's own parameter values (a spring of stiffness zero in
the first piece) cannot hide an entry that another member of its group needs. A
non-finite value counts as nonzero. The pattern is the same for every member of a
group (same program, same shapes), so it is computed for the first member and cached by
the group's structure key.

A pattern read this way misses an entry only where the residual's derivative vanishes on
an open set containing both points (a branch of ``jnp.where`` not taken). Even then the
answer is not changed: Newton's residual is always exact, so an incomplete Jacobian can
only slow the iteration down, and a step that does not converge says so in its status.

With ``finite_rows=True`` a row that is not finite at a point says nothing at that point:
forward mode multiplies every tangent by each partial on the way, so one non-finite
partial (a square root of a random negative argument in a transistor model) makes the
whole row non-finite whatever its structure. Such a row is read at the points where it
is finite — the random points and as many again with the subsystem's own parameters
(random states), where device models stay in their domain — and is counted full only
if it is finite at none of them. (On a chain of 8 CMOS inverters the default reading
counted 29 of 335 rows full, 11 504 entries against the 1901 this reading finds.)
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..discretization.equations import residual, unknown_count

_CACHE: dict = {}
_CACHE_SIZE = 256
POINTS = 2


def _random_like(leaf, rng):
    """A concrete (NumPy) stand-in for one array leaf: random floats, integers as they
    are (0 where traced)."""
    shape, dtype = np.shape(leaf), np.dtype(jnp.result_type(leaf))
    if np.issubdtype(dtype, np.inexact):
        return rng.uniform(0.5, 1.5, shape).astype(dtype)
    if isinstance(leaf, jax.core.Tracer):
        return np.zeros(shape, dtype)
    return np.asarray(leaf)


def step_pattern(sub, rule, scheme: str, key, *, finite_rows: bool = False) -> np.ndarray:
    """Boolean ``s × s`` pattern of ``∂ρ/∂y`` for one subsystem, ``s`` its step's unknowns
    (``n + m``, or ``3(n + m)`` with the stages of ``"lobatto"``; see the module
    documentation); ``key`` identifies what the pattern depends on (cache key).
    ``finite_rows``: read each row where it is finite (see the module documentation)."""
    key = (key, finite_rows)
    hit = _CACHE.get(key)
    if hit is not None:
        return hit
    size = unknown_count(sub, rule)
    rng = np.random.default_rng(20261123)
    # the rule too: a user's rule may hold arrays, traced like the model's
    arrays, static = eqx.partition((sub, rule), eqx.is_array)

    def jac(arrays, h, t, q, p, y):
        model, rule_ = eqx.combine(arrays, static)
        return jax.jacfwd(lambda y: residual(model, rule_, scheme, h, q, p, y, t))(y)

    pattern = np.zeros((size, size), dtype=bool)
    seen = np.zeros(size, dtype=bool)  # rows finite at some point (finite_rows)
    compiled = None
    # the own parameters cannot be read where they are being traced (under jax.grad)
    concrete = not any(isinstance(a, jax.core.Tracer) for a in jax.tree.leaves(arrays))
    for point in range(2 * POINTS if finite_rows and concrete else POINTS):
        own = point >= POINTS  # the subsystem's own parameters, random states
        fake = arrays if own else jax.tree.map(lambda a: _random_like(a, rng), arrays)
        h, t = rng.uniform(0.01, 0.5), rng.uniform(0.0, 1.0)
        q, p = rng.uniform(-1.0, 1.0, (2, sub.n))
        y = rng.uniform(-1.0, 1.0, size)
        args = (fake, h, t, q, p, y)
        # compiled ahead of time and run on concrete numbers, also while the caller is
        # being traced under jit (evaluated op by op it would take seconds)
        compiled = compiled or jax.jit(jac).lower(*args).compile()
        try:
            values = np.asarray(compiled(*args))
        except TypeError as exc:
            if "compiled for" not in str(exc):
                raise
            # The model's functions close over values being traced (a closure over a
            # parameter under jax.grad): the program has inputs no concrete call can
            # supply. Every entry then counts, and the group keeps dense factors.
            return np.ones((size, size), dtype=bool)
        if finite_rows:
            finite = np.all(np.isfinite(values), axis=1)
            pattern[finite] |= values[finite] != 0
            seen |= finite
        else:
            pattern |= (values != 0) | ~np.isfinite(values)
    pattern[~seen if finite_rows else np.zeros(size, bool)] = True
    _CACHE[key] = pattern
    while len(_CACHE) > _CACHE_SIZE:
        _CACHE.pop(next(iter(_CACHE)))
    return pattern
