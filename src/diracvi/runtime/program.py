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

import functools
import re
import sys
import types
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
    # evaluated now even inside another trace (a model built in a function under
    # jax.grad or jit): the result is cached across calls (``_LIFTED``), and a staged
    # device_put would leave a tracer of that trace in the cache for the next call
    with jax.ensure_compile_time_eval():
        if isinstance(value, np.ndarray | np.generic):
            return jax.device_put(value)
        return jnp.asarray(value)


class _Unkeyable(Exception):
    """A value :func:`trace_key` cannot compare by content."""


_SCALARS = (str, bytes, int, bool, type(None), type(Ellipsis))
#: ``Py_TPFLAGS_HEAPTYPE``: a class defined in Python (not a built-in type)
_HEAPTYPE = 1 << 9
#: the deepest nesting of captured containers and closures a key follows
_KEY_DEPTH = 64


def _named(obj) -> bool:
    """Whether ``obj`` is its module's attribute of its own name (a ``custom_jvp``
    function, a ``jnp`` function): it is then compared by identity, as the code of a
    module is taken to be fixed once imported."""
    module = sys.modules.get(getattr(obj, "__module__", None) or "")
    name = getattr(obj, "__name__", None)
    return module is not None and isinstance(name, str) and getattr(module, name, None) is obj


def _trusted(fn) -> bool:
    """Whether ``fn`` is a top-level function of diracvi or of JAX (compared by
    identity: the module globals such code reads are its constants and helpers, set at
    import; a user's function is compared by the globals it reads, which may be rebound)."""
    return _named(fn) and fn.__module__.split(".")[0] in (__name__.split(".")[0], "jax")


#: the global names each code object may read (a model of 10⁴ parts asks 10⁴ times)
_NAMES: dict = {}
_NAMES_LIMIT = 4096


def _global_names(code) -> tuple[str, ...]:
    """The names ``code`` and the code nested in it (local functions, lambdas,
    comprehensions) may read as globals, sorted."""
    hit = _NAMES.get(code)
    if hit is None:
        found: set = set()
        stack = [code]
        while stack:
            c = stack.pop()
            found.update(c.co_names)
            stack.extend(x for x in c.co_consts if isinstance(x, types.CodeType))
        if len(_NAMES) >= _NAMES_LIMIT:
            _NAMES.clear()
        hit = _NAMES[code] = tuple(sorted(found))
    return hit


def _key(obj, depth: int, seen: dict):
    """The content key of ``obj`` (see :func:`trace_key`)."""
    if depth > _KEY_DEPTH:
        raise _Unkeyable
    kind = type(obj)
    if kind is float or kind is complex or isinstance(obj, np.generic):
        # repr tells −0.0 from 0.0 and is exact; the type tells 1.0 from np.float32(1.0)
        return (kind, repr(obj))
    if isinstance(obj, _SCALARS) and kind in _SCALARS:
        return (kind, obj)
    if kind in (tuple, list) or (isinstance(obj, tuple) and hasattr(obj, "_fields")):
        return (kind, tuple(_key(x, depth + 1, seen) for x in obj))
    if kind is dict:  # in order: a trace iterates the dict in that order
        return (dict, tuple((_key(k, depth + 1, seen), _key(x, depth + 1, seen))
                            for k, x in obj.items()))  # fmt: skip
    if kind is np.ndarray:
        return (np.ndarray, obj.dtype.str, obj.shape, obj.tobytes())
    if isinstance(obj, jax.Array):
        if isinstance(obj, jcore.Tracer):
            raise _Unkeyable
        host = np.asarray(obj)
        return (jax.Array, host.dtype.str, host.shape, host.tobytes())
    if kind is types.FunctionType:
        if obj.__closure__ is None and _trusted(obj):
            return ("object", obj)
        return _function_key(obj, depth, seen)
    if isinstance(obj, types.ModuleType | type) or _named(obj):
        return ("object", obj)
    if kind is types.MethodType:
        return (kind, _key(obj.__func__, depth + 1, seen), _key(obj.__self__, depth + 1, seen))
    if kind is functools.partial:
        return (functools.partial, _key(obj.func, depth + 1, seen),
                _key(obj.args, depth + 1, seen), _key(obj.keywords, depth + 1, seen))  # fmt: skip
    if (
        type(kind) is type
        and all(c is object or c.__flags__ & _HEAPTYPE for c in kind.__mro__)
        and kind.__getattribute__ is object.__getattribute__
        and isinstance(getattr(obj, "__dict__", None), dict)
        and not any("__slots__" in vars(c) for c in kind.__mro__)
    ):
        # a plain object (a diode's junction): its class's code on its attributes; a
        # subclass of a built-in type (a Counter, a list) holds more than its __dict__
        return (kind, _key(obj.__dict__, depth + 1, seen))
    raise _Unkeyable


def _function_key(fn, depth: int, seen: dict):
    """A local function or lambda: its code, defaults, captured cells and the globals it
    reads, each by content."""
    if id(fn) in seen:
        if seen[id(fn)] is None:  # a function that captures itself: give up, no cycle
            raise _Unkeyable
        return seen[id(fn)]
    seen[id(fn)] = None
    cells = []
    for cell in fn.__closure__ or ():
        try:
            cells.append(_key(cell.cell_contents, depth + 1, seen))
        except ValueError:  # an empty cell
            cells.append(("empty cell",))
    glob = fn.__globals__
    names = [n for n in _global_names(fn.__code__) if n in glob]
    key = (
        types.FunctionType,
        fn.__code__,
        id(glob),
        _key(fn.__defaults__, depth + 1, seen),
        _key(fn.__kwdefaults__, depth + 1, seen),
        tuple(cells),
        tuple((n, _key(glob[n], depth + 1, seen)) for n in names),
    )
    seen[id(fn)] = key
    return key


def trace_key(fn: Callable, shapes: Sequence[tuple[int, ...]]):
    """A hashable key such that two functions with equal keys trace to the same jaxpr and
    constants on float64 arrays of ``shapes`` — or ``None`` when ``fn`` holds something
    that cannot be compared by content.

    A local function is what its code computes on what it captures: the code object, its
    defaults, its closure's cells and the module globals its code reads, each compared
    by value (floats by ``repr``, arrays by dtype, shape and bytes, containers item by
    item in order, a user's functions, top-level ones too, recursively, a plain object by
    its class and its ``__dict__``, a bound method by both). Modules, classes, the
    top-level functions of diracvi and JAX, and the other callables that are their
    module's attribute of their own name (``jnp`` functions, ``custom_jvp`` ones) are
    compared by identity: a module's code is taken to be fixed once imported (what a
    trace reads as ``module.attribute``, patched after it, is not seen). A JAX tracer, a
    function that reaches itself, or any other object makes the function unkeyable (it
    is traced as before)."""
    try:
        return _Key((_key(fn, 0, {}), tuple(tuple(s) for s in shapes)))
    except (_Unkeyable, TypeError, RecursionError):
        return None


class _Key:
    """A :func:`trace_key`, hashed once (a tuple hashes its whole nesting at every
    lookup)."""

    __slots__ = ("_hash", "key")

    def __init__(self, key):
        self.key, self._hash = key, hash(key)

    def __eq__(self, other) -> bool:
        return isinstance(other, _Key) and self._hash == other._hash and self.key == other.key

    def __hash__(self) -> int:
        return self._hash


#: ``lift``'s results by :func:`trace_key`: a netlist's alike transistors (one line of a
#: subcircuit instantiated many times) build closures equal by content, each of which
#: would otherwise be traced and printed again (0.05–0.3 CPU s for a MOSFET or a BJT)
_LIFTED: dict = {}
_LIFTED_LIMIT = 1024


def lift(fn: Callable, shapes: Sequence[tuple[int, ...]]):
    """``(program, consts, out_aval)`` for ``fn`` traced on float64 arrays of ``shapes``,
    or ``None`` when it cannot be traced that way (the caller keeps the function whole).

    A function equal by content (:func:`trace_key`) to one already lifted takes that
    one's result without a trace."""
    key = trace_key(fn, shapes)
    hit = _LIFTED.get(key) if key is not None else None
    if hit is not None:
        return hit
    lifted = _lift(fn, shapes)
    if key is not None and lifted is not None:
        if len(_LIFTED) >= _LIFTED_LIMIT:
            _LIFTED.clear()
        _LIFTED[key] = lifted
    return lifted


def _lift(fn: Callable, shapes: Sequence[tuple[int, ...]]):
    """:func:`lift` without the cache."""
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
