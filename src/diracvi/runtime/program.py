r"""User functions compared by what they compute: traced programs with lifted constants.

A model built the natural way makes a fresh closure per piece (``def L(q, v, m=m[i])``
in a loop, a lambda per part). As Python objects they are all different, so pieces that
compute the same thing with different numbers would each be traced, compiled and stepped
on their own. Here a plain function ``f`` is traced once, at model construction, to its
jaxpr on float64 arguments of the declared shapes, and rewritten as

    f(*args) = P(c, *args),     c = (captured arrays, scalar float literals)

where ``P`` has no constants of its own. Two functions whose ``P`` print the same
(equation by equation, names aside) are the same program: one :class:`Program` object
is shared between them (interned), and their ``c`` are ordinary PyTree leaves — stacked
and vmapped by the partitioned solver, passed as arguments (not baked in) to compiled
code. Anything this cannot represent faithfully (a traced captured value, a primitive
whose parameters hold Python callables — callbacks, a custom derivative rule that is a
closure or a lambda) keeps the function's identity in the key, so such functions group
only with themselves. A custom derivative rule that is a top-level function of diracvi
or JAX (:func:`rule_name`: the diode's junction charge) is printed by its name instead.
"""

from __future__ import annotations

import re
import sys
import weakref
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jax._src import core as jcore

_MESHES = (jax.sharding.Mesh, jax.sharding.AbstractMesh)
#: equal programs are one object: equality is then mostly identity, hashing is cached
_INTERNED: weakref.WeakValueDictionary = weakref.WeakValueDictionary()


class Program:
    """A closed-over-nothing jaxpr: ``P(consts, *args)`` with one array result."""

    __slots__ = ("__weakref__", "_hash", "arg_shapes", "jaxpr", "keep", "key", "name")

    def __init__(self, jaxpr, key: str, arg_shapes, name: str, keep):
        self.jaxpr, self.key, self.arg_shapes, self.name = jaxpr, key, arg_shapes, name
        self.keep = keep  # objects whose id() is part of the key stay alive with it
        self._hash = hash(key)

    def __call__(self, consts, *args):
        values = []
        for arg, shape in zip(args, self.arg_shapes, strict=True):
            value = jnp.asarray(arg, dtype=jnp.float64)
            if value.shape != shape:
                raise ValueError(
                    f"{self.name} was traced for arguments of shape {self.arg_shapes} when "
                    f"the model was built, but is now called with shape {value.shape}."
                )
            values.append(value)
        return jcore.eval_jaxpr(self.jaxpr, consts, *values)[0]

    def __eq__(self, other) -> bool:
        return self is other or (isinstance(other, Program) and other.key == self.key)

    def __hash__(self) -> int:
        return self._hash

    def __repr__(self) -> str:
        return f"<{self.name}>"


def _opaque_params(jaxpr, found: list) -> None:
    """Collect parameter values that print without their content (Python callables)."""
    for eqn in jaxpr.eqns:
        for value in eqn.params.values():
            for item in value if isinstance(value, tuple | list) else (value,):
                if isinstance(item, jcore.ClosedJaxpr):
                    _opaque_params(item.jaxpr, found)
                elif isinstance(item, jcore.Jaxpr):
                    _opaque_params(item, found)
                elif isinstance(item, _MESHES):
                    # a nested jit's device mesh (callable as a context manager): data,
                    # not code; every jnp function implemented with jit carries one
                    continue
                elif (callable(item) and not isinstance(item, type)) or hasattr(item, "f"):
                    found.append(item)


#: JAX's wrapped derivative rules, by what they were traced for
_RULES = ("custom_jvp jvp", "custom_vjp fwd", "custom_vjp bwd")
_SOURCE = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z_0-9]*) at (?P<file>.+):(?P<line>[0-9]+)$")


def rule_name(item) -> str | None:
    """``module.function`` of a ``custom_jvp``/``custom_vjp`` rule that is a function
    defined at the top level of an imported module of diracvi or of a library (no
    closure: it is what its code says, and the code is in the store key's source hash or
    the libraries' versions), else ``None``.

    JAX traces the rule into a fresh wrapper at every trace of the function it belongs
    to, so the wrapper's identity differs between two builds of the same model (two
    reads of one netlist with a diode) although the rule is the same code. The wrapper's
    debug information names the rule's function, file and line; the function is found
    again as the module's attribute of that name, and accepted only if its code starts
    at that line of that file (a nested function of the same name is another object).

    What the name leaves out: a ``custom_jvp``'s ``nondiff_argnums`` values are baked
    into the wrapper, not into the rule; two calls differing only in a non-differentiated
    argument that the primal ignores would share a key. diracvi's rules take none."""
    info = getattr(item, "debug_info", None)
    if info is None or getattr(info, "traced_for", None) not in _RULES:
        return None
    match = _SOURCE.match(getattr(info, "func_src_info", None) or "")
    if match is None:
        return None
    module = _module_of(match["file"])
    if module is None:
        return None
    fn = getattr(module, match["name"], None)
    code = getattr(fn, "__code__", None)
    if (
        code is None
        or getattr(fn, "__closure__", None)
        or code.co_filename != match["file"]
        or code.co_firstlineno != int(match["line"])
    ):
        return None
    return f"{module.__name__}.{match['name']}"


#: modules by file (a model with 10⁴ diodes asks 10⁴ times)
_MODULES: dict = {}


def _module_of(path: str):
    """The imported module of diracvi or of JAX whose file is ``path``."""
    module = _MODULES.get(path)
    if module is None:
        top = __name__.split(".")[0]
        for name, candidate in list(sys.modules.items()):
            if getattr(candidate, "__file__", None) == path and name.split(".")[0] in (top, "jax"):
                module = _MODULES[path] = candidate
                break
    return module


def _lift_literals(jaxpr):
    """Replace the scalar float literals of the top-level equations by new constvars."""
    new_vars, values, eqns = [], [], []
    for eqn in jaxpr.eqns:
        invars = list(eqn.invars)
        for i, v in enumerate(invars):
            if (
                isinstance(v, jcore.Literal)
                and v.aval.shape == ()
                and jnp.issubdtype(v.aval.dtype, jnp.floating)
            ):
                var = jcore.Var(jcore.ShapedArray((), v.aval.dtype))
                new_vars.append(var)
                values.append(np.asarray(v.val, dtype=v.aval.dtype))
                invars[i] = var
        eqns.append(eqn.replace(invars=invars))
    lifted = jaxpr.replace(constvars=[*jaxpr.constvars, *new_vars], eqns=eqns)
    return lifted, values


def _on_device(value):
    """``jnp.asarray(value)``, NumPy data put on the device as it is: JAX's ``asarray``
    of NumPy data is an eager ``stage`` program, compiled once per shape and process
    whatever the disk cache holds (a model's constants: a few of them per deck)."""
    if isinstance(value, np.ndarray | np.generic):
        return jax.device_put(value)
    return jnp.asarray(value)


def lift(fn: Callable, shapes: Sequence[tuple[int, ...]]):
    """``(program, consts, out_aval)`` for ``fn`` traced on float64 arrays of ``shapes``,
    or ``None`` when it cannot be traced that way (the caller keeps the function whole)."""
    specs = [jax.ShapeDtypeStruct(tuple(s), jnp.float64) for s in shapes]
    try:
        closed = jax.make_jaxpr(fn)(*specs)
    except Exception:  # the caller's own check traces it again and reports the error
        return None
    if len(closed.out_avals) != 1 or any(isinstance(c, jax.core.Tracer) for c in closed.consts):
        return None
    jaxpr, literals = _lift_literals(closed.jaxpr)
    consts = [_on_device(c) for c in closed.consts] + [_on_device(v) for v in literals]
    found: list = []
    _opaque_params(jaxpr, found)
    # a derivative rule that is a module's own function is named by it; any other
    # callable prints by name only (the same name may hide different code): its id
    named = [(o, rule_name(o)) for o in found]
    opaque = [o for o, name in named if name is None]
    key = str(jaxpr)
    if found:
        key += "\n# rules: " + " ".join(name or str(id(o)) for o, name in named)
    program = _INTERNED.get(key)
    if program is None:
        name = getattr(fn, "__qualname__", None) or type(fn).__name__
        program = Program(jaxpr, key, tuple(tuple(s) for s in shapes), name, tuple(opaque))
        _INTERNED[key] = program
    return program, tuple(consts), closed.out_avals[0]
