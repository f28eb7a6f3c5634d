r"""A part: an ordinary :class:`~diracvi.LagrangeDiracSystem` with named pins and flanges.

A **pin** is where an electrical branch meets a node. Every branch carries a charge
coordinate ``q`` whose velocity is the branch current, flowing *into* the part at its
``+`` pin and out at its ``−`` pin (the passive sign convention, as SPICE reports
``i(R1)``). Kirchhoff's current law at a node is the one-form
``Σ_{+ pins at n} dq − Σ_{− pins at n} dq``; :class:`~diracvi.components.Circuit`
stacks one such row per node. A **flange** is a mechanical port: its coordinate is a
position (or an angle), and flanges at one mechanical node are joined by
:func:`diracvi.connect` (equal velocities, the paper's port variables).
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import numpy as np

from ..errors import ModelError
from ..model.system import LagrangeDiracSystem
from ..model.validate import check_name

# A part built inside jax.grad may keep a traced number in a static field (a capacitor's
# initial charge C·v0, a waveform's amplitude): it is read while the model is built or
# inside the same trace, never baked into a compiled program, so equinox's warning for
# it is silenced — only where diracvi's own modules build parts (user code still warns).
warnings.filterwarnings("ignore", message="A JAX array is being set as static", module=r"diracvi\.")

TRANSLATIONAL = "translational"
ROTATIONAL = "rotational"


class Part(LagrangeDiracSystem):
    r"""A Lagrange–Dirac system ``(L, Δ, F)`` with pins and flanges.

    Args:
        coords: coordinate names, as for :class:`~diracvi.LagrangeDiracSystem`.
        lagrangian: ``L(q, v)`` or ``L(q, v, t)``, as for
            :class:`~diracvi.LagrangeDiracSystem`.
        name: the part's name (its coordinates are ``"name.coordinate"`` in a circuit).
        pins: ``(pin, coordinate, sign)`` triples: the branch charge ``coordinate``
            enters KCL at the node joined to ``pin`` with ``sign`` (+1 where the current
            enters the part, −1 where it leaves).
        flanges: ``(flange, coordinate, kind)`` triples, ``kind`` ``"translational"``
            or ``"rotational"``.
        currents: ``(label, coordinate)`` pairs: the branch currents reported as
            ``i(label)`` (``""`` means the part's own name). Default: ``i(name)`` for a
            one-branch part, ``i(name.1)``, ``i(name.2)``, … for several.
        initial_q, initial_v: the part's own initial coordinates and velocities
            (a capacitor's charge, an inductor's current); flange values are set by
            the network's mechanical nodes instead.
        junctions, junction_limits: coordinate names whose velocity is a junction
            voltage, and a ``(len(junctions), 3)`` array of ``(nV_T, V_crit, BV)``:
            Newton limits those voltages between iterates (SPICE's ``pnjlim``).
        role: what the part is (``"resistor"``, ``"voltage"``, ``"current"``, …); the
            network's topology checks read it.
        parameters: the part's defining values, e.g. ``{"inductance": 1e-3}``.
        waveforms: the source waveforms the part is driven by (their
            :meth:`~diracvi.components.Waveform.breakpoints` are where a variable-step
            run must end a step).
        **system_kwargs: ``constraints``, ``force``, ``constraint_names``,
            ``constraint_offset`` of :class:`~diracvi.LagrangeDiracSystem`.
    """

    pins: tuple[tuple[str, str, int], ...] = eqx.field(static=True)
    flanges: tuple[tuple[str, str, str], ...] = eqx.field(static=True)
    currents: tuple[tuple[str, str], ...] = eqx.field(static=True)
    initial_q: tuple[float, ...] = eqx.field(static=True)
    initial_v: tuple[float, ...] = eqx.field(static=True)
    role: str = eqx.field(static=True)
    parameters: tuple[tuple[str, float], ...] = eqx.field(static=True)
    #: coordinates whose velocity is a junction voltage, limited between Newton iterates
    #: (:mod:`diracvi.solvers.limiting`), and their ``(nV_T, V_crit, BV)`` rows
    junctions: tuple[int, ...] = eqx.field(static=True)
    junction_limits: object
    #: (data, not static: their numbers are array leaves, so a source of another value
    #: leaves the model's structure, and its compiled programs, as they are)
    waveforms: tuple

    def __init__(
        self,
        coords,
        lagrangian,
        *,
        name,
        pins=(),
        flanges=(),
        currents=None,
        initial_q=None,
        initial_v=None,
        role="part",
        parameters=(),
        junctions=(),
        junction_limits=None,
        waveforms=(),
        **system_kwargs,
    ):
        super().__init__(coords, lagrangian, name=name, **system_kwargs)
        n = len(self.coords)
        self.pins = tuple((str(p), str(c), int(s)) for p, c, s in pins)
        self.flanges = tuple((str(f), str(c), str(k)) for f, c, k in flanges)
        if currents is None:  # i(name) for one branch, i(name.1), i(name.2), … for several
            branch = tuple(dict.fromkeys(c for _, c, _ in self.pins))
            labels = [""] if len(branch) == 1 else [f"{name}.{j + 1}" for j in range(len(branch))]
            currents = tuple(zip(labels, branch, strict=True))
        self.currents = tuple((str(a), str(c)) for a, c in currents)
        self.initial_q = _initial("initial_q", initial_q, n, name)
        self.initial_v = _initial("initial_v", initial_v, n, name)
        self.role = str(role)
        self.junctions = tuple(self.coords.index(c) for c in junctions)
        self.junction_limits = junction_limits
        # (a traced value is not kept: the table is static, and only K reads it)
        self.parameters = tuple(
            (str(k), float(x)) for k, x in dict(parameters).items() if not traced(x)
        )
        self.waveforms = tuple(waveforms)
        for _, coord, _ in (*self.pins, *self.flanges):
            if coord not in self.coords:
                raise ModelError(
                    f"part {name!r}: pin/flange coordinate {coord!r} not in {self.coords}"
                )

    @property
    def pin_names(self) -> tuple[str, ...]:
        """The part's electrical pins, in order (a pin may touch several branches)."""
        return tuple(dict.fromkeys(p for p, _, _ in self.pins))

    @property
    def flange_names(self) -> tuple[str, ...]:
        """The part's mechanical flanges, in order."""
        return tuple(f for f, _, _ in self.flanges)


def fields(part) -> dict:
    """A part's fields as stored (its instance dictionary), read past equinox's
    ``__getattribute__``, a Python hook of about a microsecond per read: a circuit reads
    each part's name, pins and role a few times over while it is built, which for a
    netlist of 10⁵ elements was most of the time. Read only, never written."""
    return object.__getattribute__(part, "__dict__")


def replaced(obj, **changes):
    """A shallow copy of the dataclass ``obj`` (a Module: no construction, no checks) with
    the fields ``changes``; everything else shared."""
    copy = object.__new__(type(obj))
    # the dictionaries read past equinox's __getattribute__ (a Python hook per read);
    # a dataclass keeps every field there, so one update copies them all
    fields(copy).update(fields(obj), **changes)
    return copy


def copy_with(obj, path: tuple[str, ...], value):
    """A shallow copy of ``obj`` whose attribute chain ``path`` ends in ``value`` (each
    object on the chain copied by :func:`replaced`, everything else shared)."""
    if not path:
        return value
    return replaced(obj, **{path[0]: copy_with(fields(obj)[path[0]], path[1:], value)})


def renamable(part: Part) -> bool:
    """Whether :func:`renamed` gives ``part`` under another name: no field but ``name``
    depends on the name (:class:`Part`'s default currents for several branches,
    ``i(name.1)``, ``i(name.2)``…, do)."""
    old = fields(part)["name"]
    return not any(label.startswith(f"{old}.") for label, _ in fields(part)["currents"])


def renamed(part: Part, name: str) -> Part:
    """``part`` under the name ``name``: the same object field for field but ``name``.

    Equal to the part its constructor builds from the same arguments with ``name``
    exactly when no other field depends on the name (:func:`renamable`; a part that is
    not is refused). A netlist's alike transistors (one line of a subcircuit
    instantiated 10⁴ times) are each built once this way instead of being constructed
    again (≈ 1 ms a transistor, most of it Equinox's module construction and the
    closures' checks)."""
    if not renamable(part):
        raise ModelError(
            f"renamed: part {fields(part)['name']!r} reports currents under its own name "
            f"{fields(part)['currents']}; build the part {name!r} with its constructor."
        )
    out = object.__new__(type(part))
    object.__getattribute__(out, "__dict__").update(fields(part), name=check_name("name", name))
    return out


def _initial(arg: str, values, n: int, name: str) -> tuple[float, ...]:
    if values is None:
        return (0.0,) * n
    if any(traced(x) for x in values):  # a traced initial state: kept as given
        if len(values) != n:
            raise ModelError(f"part {name!r}: {arg} must be {n} numbers.")
        return tuple(values)
    out = np.asarray(values, dtype=np.float64).reshape(-1)
    if out.shape != (n,) or not np.all(np.isfinite(out)):
        raise ModelError(f"part {name!r}: {arg}={values!r} must be {n} finite numbers.")
    return tuple(float(x) for x in out)


def traced(value) -> bool:
    """Whether ``value`` is a JAX tracer (a parameter being differentiated or mapped):
    such a value is used as it is, unchecked (its number is not known yet)."""
    return isinstance(value, jax.core.Tracer)


def array_module(*values):
    """The array module for a part's tables computed from its parameters ``values``
    (a junction's ``V_crit`` row): ``jax.numpy`` when one of them is traced, so the
    derivative or the map flows through, else NumPy. An eager ``jax.numpy`` operation
    compiles an XLA program per operation and shape, once per process and whatever the
    disk cache holds: reading a deck with one BJT model cost 8 of them."""
    import jax.numpy as jnp

    return jnp if any(traced(v) for v in values) else np


def positive(part: str, arg: str, value) -> float:
    """``float(value)`` if it is finite and > 0, else a :class:`ModelError` naming it
    (a traced value passes through unchecked, so parts are differentiable)."""
    if type(value) is float and value > 0.0 and value - value == 0.0:
        return value  # (the common case first: a netlist's 10⁴ devices check 10⁵ numbers)
    if traced(value):
        return value
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(
            f"{part}: {arg}={value!r} is not a number; pass a positive float."
        ) from None
    if not np.isfinite(x) or x <= 0.0:
        raise ModelError(f"{part}: {arg}={value!r} must be a finite positive number.")
    return x


def nonzero(part: str, arg: str, value) -> float:
    """``float(value)`` if it is finite and not 0, else a :class:`ModelError` naming it
    (a traced value passes through unchecked). For the linear R, L and C that SPICE
    lets be negative (a vendor macromodel's ``C4 26 27 -39.75E-9``)."""
    x = finite(part, arg, value)
    if not traced(x) and x == 0.0:
        raise ModelError(f"{part}: {arg}={value!r} must be a finite nonzero number.")
    return x


def finite(part: str, arg: str, value) -> float:
    """``float(value)`` if it is finite, else a :class:`ModelError` naming it (a traced
    value passes through unchecked)."""
    if type(value) is float and value - value == 0.0:
        return value  # (the common case first, as in positive)
    if traced(value):
        return value
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{part}: {arg}={value!r} is not a number.") from None
    if not np.isfinite(x):
        raise ModelError(f"{part}: {arg}={value!r} must be finite.")
    return x
