r"""The round-off of a computed value: a first-order running error bound.

A function ``f`` built of JAX operations is evaluated with a bound ``E`` on each
intermediate value's absolute round-off carried beside it (Higham, *Accuracy and
Stability of Numerical Algorithms*, 2nd ed., §3.3, "running error analysis"): the
inputs are exact (``E = 0``), and each operation ``z = g(x₁, …, x_k)`` gives

    E(z) = Σ_j |∂g/∂x_j| E(x_j)  +  u |z|,        u = 2⁻⁵³,

the first sum the inputs' errors carried through ``g`` (one Jacobian-vector product per
input, its absolute value: no cancellation of bounds), the last term ``z``'s own rounding —
left out for the operations that round nothing (a slice, a sign change, ``abs``, a
select, ``max``/``min``, a comparison). A sum whose terms cancel keeps the bound of its
terms: ``β y + ½(α − β)(|y + V_t| − |y − V_t|)`` (``ng_memristor``'s memristor law,
``β`` = 2e12, ``α`` = 0) is exactly 0 for ``|y| < V_t`` and computes as up to ~5e-4,
either sign; its bound there is ``u`` times the terms, ~1.4e-3 near ``|y| = V_t``.

Used by the variable-step loop (:mod:`diracvi.driver.roundoff`): a quantity is not judged
below its own evaluation's round-off, which no shorter step lowers. First order: the
products of two errors are dropped (each ``~u²``).
"""

from __future__ import annotations

import jax
import jax.extend
import jax.numpy as jnp

#: the unit round-off of float64 (half its machine epsilon)
UNIT = 2.0**-53

#: operations that round nothing: their result's error is their inputs' carried through
EXACT = frozenset(
    {
        "abs",
        "neg",
        "sign",
        "floor",
        "ceil",
        "round",
        "max",
        "min",
        "clamp",
        "select_n",
        "slice",
        "squeeze",
        "reshape",
        "broadcast_in_dim",
        "concatenate",
        "gather",
        "dynamic_slice",
        "dynamic_update_slice",
        "scatter",
        "convert_element_type",
        "copy",
        "copy_p",
        "stop_gradient",
        "transpose",
        "expand_dims",
        "rev",
        "pad",
        "iota",
    }
)

#: primitives holding a jaxpr that is interpreted operation by operation (its parameter)
_NESTED = {
    "pjit": "jaxpr",
    "jit": "jaxpr",
    "closed_call": "call_jaxpr",
    "custom_jvp_call": "call_jaxpr",
}


def _inexact(x) -> bool:
    return jnp.issubdtype(jnp.result_type(x), jnp.inexact)


def _carried(prim, params, values, errors):
    """``Σ_j |∂g/∂x_j| E(x_j)`` of one primitive ``g`` (a list, one per output)."""

    def g(*args):
        out = prim.bind(*args, **params)
        return list(out) if prim.multiple_results else [out]

    outs = g(*values)
    total = [jnp.zeros(jnp.shape(o), jnp.result_type(o)) if _inexact(o) else None for o in outs]
    for j, (x, e) in enumerate(zip(values, errors, strict=True)):
        if e is None or not _inexact(x):
            continue

        def of_j(xj, j=j):
            return g(*values[:j], xj, *values[j + 1 :])

        _, tangent = jax.jvp(of_j, (x,), (jnp.asarray(e, jnp.result_type(x)),))
        total = [
            t if t is None or not _inexact(d) else t + jnp.abs(d)
            for t, d in zip(total, tangent, strict=True)
        ]
    return outs, total


def _run(jaxpr, consts, args, errors, corners=None, rounding=True):
    """Evaluate ``jaxpr`` on ``args`` with each value's error bound beside it; with a list
    ``corners``, each corner's argument and its carried bound appended to it
    (:func:`corner_arguments`); ``rounding=False`` adds no operation's own rounding (the
    inputs' bounds carried through only)."""
    env = {}

    def read(var):
        if isinstance(var, jax.extend.core.Literal):
            return var.val, None
        return env[var]

    for var, value in zip(jaxpr.constvars, consts, strict=True):
        env[var] = (value, None)
    for var, value, error in zip(jaxpr.invars, args, errors, strict=True):
        env[var] = (value, error)
    for eqn in jaxpr.eqns:
        pairs = [read(v) for v in eqn.invars]
        values = [p[0] for p in pairs]
        errs = [p[1] for p in pairs]
        name = eqn.primitive.name
        if corners is not None and name in CORNERS:
            corners.extend(_corner(name, values, errs))
        if name in _NESTED and _NESTED[name] in eqn.params:
            inner = eqn.params[_NESTED[name]]
            closed = getattr(inner, "jaxpr", inner)
            outs, total = _run(
                closed, getattr(inner, "consts", ()), values, errs, corners, rounding
            )
        elif all(e is None for e in errs):
            out = eqn.primitive.bind(*values, **eqn.params)
            outs = list(out) if eqn.primitive.multiple_results else [out]
            total = [None] * len(outs)
        else:
            outs, total = _carried(eqn.primitive, eqn.params, values, errs)
        nested = name in _NESTED and _NESTED[name] in eqn.params
        if rounding and name not in EXACT and not nested:
            total = [
                (UNIT * jnp.abs(o) if t is None else t + UNIT * jnp.abs(o)) if _inexact(o) else t
                for o, t in zip(outs, total, strict=True)
            ]
        for var, o, t in zip(eqn.outvars, outs, total, strict=True):
            env[var] = (o, t)
    results = [read(v) for v in jaxpr.outvars]
    return [r[0] for r in results], [r[1] for r in results]


def with_bound(fn, *args):
    """``(f(args), E)``: the value of ``fn`` (one array output) and the first-order bound
    ``E`` on its absolute round-off (module docstring), the inputs taken as exact.
    Traceable (``args`` may be tracers: the function is traced to a jaxpr once per call)."""
    args = [jnp.asarray(a) for a in args]
    shapes = [jax.ShapeDtypeStruct(jnp.shape(a), jnp.result_type(a)) for a in args]
    closed = jax.make_jaxpr(fn)(*shapes)
    outs, errs = _run(closed.jaxpr, closed.consts, args, [None] * len(args))
    value = outs[0]
    error = errs[0]
    return value, jnp.zeros(jnp.shape(value), jnp.result_type(value)) if error is None else error


#: operations with a corner (a kink or a jump of their result) where an argument, or the
#: difference of their two arguments, is 0: ``abs``, ``sign``, ``max``/``min``, the
#: comparisons (a select's predicate), ``clamp`` (its value against either limit)
CORNERS = frozenset({"abs", "sign", "max", "min", "gt", "ge", "lt", "le", "clamp"})


def _corner(name, values, errors):
    """The arguments ``g`` (one or two) whose sign change is this operation's corner,
    each with its carried bound (a difference's: the sum of its operands'), as
    ``(g, bound)`` pairs of flat arrays; none for operands that are not floats."""
    if not all(_inexact(v) for v in values):
        return []

    def err(j):
        e = errors[j]
        return jnp.zeros(jnp.shape(values[j])) if e is None else e

    def flat(g, e):
        g = jnp.ravel(jnp.asarray(g, jnp.float64))
        return g, jnp.broadcast_to(jnp.ravel(jnp.asarray(e, jnp.float64)), g.shape)

    if name in ("abs", "sign"):
        return [flat(values[0], err(0))]
    if name == "clamp":  # clamp(lo, x, hi)
        lo, x, hi = values
        return [flat(x - lo, err(1) + err(0)), flat(x - hi, err(1) + err(2))]
    a, b = values
    return [flat(jnp.asarray(a) - jnp.asarray(b), err(0) + err(1))]


def corner_arguments(fn, args, seeds):
    """``(g, B)``: the corner arguments of ``fn`` at ``args`` (per operation of
    :data:`CORNERS` met in its evaluation, its argument or the difference of its two;
    flat, in the jaxpr's order, a static count per function) and beside each the bound
    ``B = Σ |∂g/∂x_j| seed_j`` by which inputs perturbed by ``seeds`` (one per argument,
    its shape) can move it, carried operation by operation without cancellation (as
    :func:`with_bound` carries round-off, with no rounding of its own). Seeded with the
    inputs' magnitudes ``|x|``, ``B`` is the argument's *terms*: the scale it is known
    to relative to (``y − V_t``: ``|y|``); seeded with their absolute tolerances, how far
    it is known at all. Traceable."""
    args = [jnp.asarray(a) for a in args]
    shapes = [jax.ShapeDtypeStruct(jnp.shape(a), jnp.result_type(a)) for a in args]
    closed = jax.make_jaxpr(fn)(*shapes)
    found: list = []
    seeds = [jnp.asarray(s, jnp.result_type(a)) for s, a in zip(seeds, args, strict=True)]
    _run(closed.jaxpr, closed.consts, args, seeds, corners=found, rounding=False)
    if not found:
        return jnp.zeros(0), jnp.zeros(0)
    return jnp.concatenate([g for g, _ in found]), jnp.concatenate([e for _, e in found])


def corner_rows(fn, args, tolerances):
    """``K = [g; A; T]``, the ``(3, k)`` rows of a part's ``law_corners``
    (:class:`~diracvi.components.ControlledPart`): the corner arguments ``g`` of ``fn`` at
    ``args``, the bound ``A`` by which the inputs' absolute ``tolerances`` (one per
    argument, its shape) move each, and each argument's terms ``T`` (the bound seeded
    with ``|args|``), by :func:`corner_arguments`. A tolerance not set — ``inf`` on a
    coordinate the step control leaves out — moves nothing: that corner is then known to
    its terms only. Traceable."""
    args = [jnp.asarray(a) for a in args]
    g, terms = corner_arguments(fn, args, [jnp.abs(a) for a in args])
    seeds = [jnp.where(jnp.isfinite(s), s, 0.0) for s in tolerances]
    _, atol = corner_arguments(fn, args, seeds)
    return jnp.stack([g, atol, terms])


__all__ = ["CORNERS", "EXACT", "UNIT", "corner_arguments", "corner_rows", "with_bound"]
