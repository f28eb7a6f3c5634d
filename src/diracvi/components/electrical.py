r"""Electrical parts. Each branch is a charge coordinate ``q`` (current ``i = q̇``,
passive sign convention: ``i`` enters at pin ``p`` and leaves at pin ``n``).

With ``V = φ_p − φ_n`` the branch voltage (the node potentials are the multipliers of
the KCL one-forms), the parts' Euler–Lagrange equations read

    resistor   0 = −R i + V               L = 0,            F = −R q̇
    capacitor  0 = −q/C + V               L = −q²/(2C)
    inductor   l di/dt = V                L = ½ l q̇²
    V source   0 = −u(t) + V              L = 0,            F = −u(t)
    I source   q̇ − u(t) = 0               A = (1), b = −u(t)  (μ is −V)
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.tree_util import GetAttrKey

from ..errors import ModelError
from ..model.stacked import ALIKE
from ..model.validate import check_name
from ._part import Part, copy_with, finite, nonzero, positive, traced
from .waveforms import as_waveform

_TWO_PINS = (("p", "q", 1), ("n", "q", -1))


class _NoLagrangian(eqx.Module):
    """``L = 0`` (a resistor, a source: no energy stored)."""

    def __call__(self, q, v):
        return 0.0 * v[0]


_zero_l = _NoLagrangian()


# The linear parts' functions are small Module classes with their value as an array
# leaf, not closures: a Module's form is read once per class (a closure is traced once
# per part to lift its constants, ~3 ms each), so a netlist of 10⁴ elements builds in
# time linear in its length with a small constant, and alike parts still group and stack.
class _Damping(eqx.Module):
    """``F = −R q̇``."""

    resistance: jax.Array

    def __call__(self, q, v):
        return -self.resistance * v


class _Elastance(eqx.Module):
    """``L = −q²/(2C)``."""

    capacitance: jax.Array

    def __call__(self, q, v):
        return -(q[0] ** 2) / (2.0 * self.capacitance) + 0.0 * v[0]


class _Inertia(eqx.Module):
    """``L = ½ l q̇²``."""

    inductance: jax.Array

    def __call__(self, q, v):
        return 0.5 * self.inductance * v[0] ** 2 + 0.0 * q[0]


class _Source(eqx.Module):
    """``F = −u(t)``."""

    wave: object

    def __call__(self, q, v, t):
        return -jnp.atleast_1d(self.wave(t)) + 0.0 * v


def _value(x):
    # a traced parameter (jax.grad through a circuit) stays the tracer it is
    return x if traced(x) else np.asarray(x, dtype=np.float64)


#: the first linear R, L or C built: later ones are copies of it with their own name,
#: value and initial state (what ``Part.__init__`` would compute for them is the same
#: but for those: a netlist of 10⁴ elements pays ~20 µs per element instead of ~0.5 ms)
_TEMPLATES: dict = {}


def _like(kind: str, name, value: float, build, **statics) -> Part:
    """A linear part of ``kind``: ``build()`` the first time, else the template copied
    with ``name``, the parameter leaf ``value`` and the static fields ``statics``."""
    template = _TEMPLATES.get(kind)
    if traced(value) or _any_traced(statics.values()):
        return build()  # a traced value is no template's copy (nor a template)
    if template is None:
        part = build()
        leaves = jax.tree_util.tree_flatten_with_path(part)[0]
        # one parameter leaf, reached through attributes: a template
        if len(leaves) == 1 and all(isinstance(k, GetAttrKey) for k in leaves[0][0]):
            _TEMPLATES[kind] = (part, tuple(k.name for k in leaves[0][0]))
            # marked as its copies are: the marker is part of a Module's PyTree
            # structure, so an unmarked first part would make a netlist's first read a
            # different structure from every later read (a retrace, a new program key)
            fields = object.__getattribute__(part, "__dict__")
            fields[ALIKE] = ((kind, id(part), tuple(statics.items())), leaves[0][1])
        return part
    template, path = template
    # copies of the objects on the path to the leaf only (a flatten and unflatten of the
    # whole part cost ~50 µs per element, most of a 10⁴-element netlist's reading)
    leaf = _value(value)
    part = copy_with(template, path, leaf)
    fields = object.__getattribute__(part, "__dict__")
    fields["name"] = check_name("name", name)
    fields.update(statics)
    # the copy says what it is, so that packing alike parts need not flatten it: its
    # structure is the template's with these static fields, its one array leaf ``leaf``
    fields[ALIKE] = ((kind, id(template), tuple(statics.items())), leaf)
    return part


def template_momentum(part_fields: dict, velocity: float) -> float | None:
    r"""``p = ∂L/∂q̇`` of a template copy of a linear R, L or C (its field dictionary
    ``part_fields``, its branch current ``velocity``) in closed form: ``0`` for a
    resistor and a capacitor (their ``L`` has no ``q̇``), ``l q̇`` for an inductor
    (``L = ½ l q̇²``), and ``0`` for any part whose Lagrangian is :class:`_NoLagrangian`
    (a source, a resistor not in a template: ``L = 0``). ``None`` for any other part,
    whose Lagrangian the caller differentiates: for 10⁴ parts that is a compiled call
    whose program depends on the part count (about 0.3 s), paid by the netlist reader
    for every new size; for one source it was five eager JAX operations, each compiled
    in a fresh process (0.3 s of a cold ``diracvi run`` of the 1000-stage ladder)."""
    if isinstance(getattr(part_fields.get("_lagrangian"), "rest", None), _NoLagrangian):
        return 0.0  # (∂(0·q̇)/∂q̇ = 0 exactly, as the derivative JAX would take)
    alike = part_fields.get(ALIKE)
    if alike is None or type(alike[1]) is not np.ndarray:
        return None
    kind = alike[0][0]
    if kind == "inductor":
        return float(alike[1]) * velocity
    return 0.0 if kind in ("resistor", "capacitor") else None


def _any_traced(values) -> bool:
    """Whether a static field's value (tuples of numbers, or of name–number pairs)
    holds a tracer."""
    for v in values:
        if type(v) is tuple:
            if _any_traced(v):
                return True
        elif type(v) is not float and type(v) is not str and traced(v):
            return True
    return False


class Ground:
    """Marks a node as the reference (potential 0): ``circuit.add(Ground(), p="n0")``.

    Not a system: the ground node simply has no KCL row (its row is the sum of the
    others'), and nodes named ``"0"`` or ``"gnd"`` are ground already.
    """

    pin_names = ("p",)
    name = "ground"


def Resistor(resistance=None, *, name: str, voltage=None, negative: bool = False) -> Part:
    r"""A resistor: ``F = −R q̇`` (or ``F = −voltage(q̇)`` for a nonlinear ``V(i)``).

    It removes energy at the rate ``R i²``. Pass either ``resistance`` or a traceable
    ``voltage(i)``. ``negative=True`` lets ``R`` be any nonzero number, as SPICE does
    (a negative resistance *supplies* energy at the rate ``|R| i²``: an active element).
    """
    if (resistance is None) == (voltage is None):
        raise ModelError(f"Resistor {name!r}: pass exactly one of resistance=R or voltage=f(i).")
    if voltage is None:
        r = (nonzero if negative else positive)(f"Resistor {name!r}", "resistance", resistance)
        return _like(
            "resistor", name, r,
            lambda: Part(("q",), _zero_l, force=_Damping(_value(r)), name=name, pins=_TWO_PINS,
                         role="resistor"),
        )  # fmt: skip

    else:

        def force(q, v):
            return -jnp.atleast_1d(voltage(v[0]))

    return Part(("q",), _zero_l, force=force, name=name, pins=_TWO_PINS, role="resistor")


def Capacitor(
    capacitance=None,
    *,
    name: str,
    v0: float = 0.0,
    energy=None,
    q0: float = 0.0,
    negative: bool = False,
) -> Part:
    r"""A capacitor: ``L = −q²/(2C)`` (or ``L = −energy(q)``), initial voltage ``v0``.

    A nonlinear capacitor is given by its stored energy ``W(q)`` (voltage ``W′(q)``) and
    its initial charge ``q0`` (its voltage would need ``W′`` inverted).
    ``negative=True`` lets ``C`` be any nonzero number, as SPICE does (vendor op-amp
    macromodels shape a pole–zero pair with one): then ``q²/(2C)`` is an energy of
    either sign, the circuit's energy is indefinite, and its power balance
    ``dE/dt = ⟨F, q̇⟩`` still holds, with no bound on ``|q|`` from it.
    """
    where = f"Capacitor {name!r}"
    if (capacitance is None) == (energy is None):
        raise ModelError(f"{where}: pass exactly one of capacitance=C or energy=W(q).")
    if energy is None:
        c = (nonzero if negative else positive)(where, "capacitance", capacitance)
        if q0 != 0.0:
            raise ModelError(f"{where}: give a linear capacitor's initial state as v0=, not q0=.")
        q0 = c * finite(where, "v0", v0)
        return _like(
            "capacitor", name, c,
            lambda: Part(("q",), _Elastance(_value(c)), name=name, pins=_TWO_PINS,
                         initial_q=[q0], role="capacitor"),
            initial_q=(q0 if traced(q0) else float(q0),),
        )  # fmt: skip

    else:
        if v0 != 0.0:
            raise ModelError(
                f"{where}: v0={v0!r} needs W′ inverted; give a nonlinear capacitor's "
                "initial charge as q0= instead."
            )
        q0 = finite(where, "q0", q0)

        def lagrangian(q, v):
            return -energy(q[0]) + 0.0 * v[0]

    return Part(("q",), lagrangian, name=name, pins=_TWO_PINS, initial_q=[q0], role="capacitor")


def Inductor(
    inductance=None, *, name: str, i0: float = 0.0, coenergy=None, negative: bool = False
) -> Part:
    r"""An inductor: ``L = ½ l q̇²`` (or ``L = coenergy(q̇)``), initial current ``i0``.

    A nonlinear inductor is given by its magnetic co-energy ``W*(i)`` (flux ``W*′(i)``).
    ``negative=True`` lets ``l`` be any nonzero number, as SPICE does (``½ l q̇²`` is
    then a co-energy of either sign; ``∂²L/∂q̇² = l`` stays invertible, so the step
    equations keep their form).
    """
    if (inductance is None) == (coenergy is None):
        raise ModelError(f"Inductor {name!r}: pass exactly one of inductance=l or coenergy=W(i).")
    i0 = finite(f"Inductor {name!r}", "i0", i0)
    if coenergy is None:
        ell = (nonzero if negative else positive)(f"Inductor {name!r}", "inductance", inductance)
        return _like(
            "inductor", name, ell,
            lambda: Part(("q",), _Inertia(_value(ell)), name=name, pins=_TWO_PINS,
                         initial_v=[i0], role="inductor", parameters={"inductance": ell}),
            initial_v=(i0,), parameters=(("inductance", ell),),
        )  # fmt: skip

    else:

        def lagrangian(q, v):
            return coenergy(v[0]) + 0.0 * q[0]

    return Part(
        ("q",),
        lagrangian,
        name=name,
        pins=_TWO_PINS,
        initial_v=[i0],
        role="nonlinear inductor",
    )


def CoupledInductors(inductances, coupling, *, name: str, labels=None, i0=(0.0, 0.0)) -> Part:
    r"""Two magnetically coupled inductors: ``L = ½ l₁ q̇₁² + ½ l₂ q̇₂² + M q̇₁ q̇₂``,
    ``M = k √(l₁ l₂)``, ``|k| < 1`` (SPICE's ``K``; the dotted ends are ``p1``, ``p2``).

    Pins ``p1``, ``n1`` (branch ``q1``) and ``p2``, ``n2`` (branch ``q2``); ``labels``
    names the two currents (default ``"<name>.1"``, ``"<name>.2"``).
    """
    where = f"CoupledInductors {name!r}"
    l1, l2 = (positive(where, f"inductances[{j}]", x) for j, x in enumerate(inductances))
    k = finite(where, "coupling", coupling)
    if not abs(k) < 1.0:
        raise ModelError(
            f"{where}: coupling k={coupling!r} must satisfy |k| < 1 (k = 1 makes the "
            "inductance matrix singular; use IdealTransformer for perfect coupling)."
        )
    m = k * np.sqrt(l1 * l2)
    labels = labels or (f"{name}.1", f"{name}.2")

    def lagrangian(q, v):
        return 0.5 * l1 * v[0] ** 2 + 0.5 * l2 * v[1] ** 2 + m * v[0] * v[1] + 0.0 * q[0]

    return Part(
        ("q1", "q2"),
        lagrangian,
        name=name,
        pins=(("p1", "q1", 1), ("n1", "q1", -1), ("p2", "q2", 1), ("n2", "q2", -1)),
        currents=((labels[0], "q1"), (labels[1], "q2")),
        initial_v=[finite(where, "i0[0]", i0[0]), finite(where, "i0[1]", i0[1])],
    )


class MutualInductance:
    """SPICE ``K``: couples two :func:`Inductor` parts already in a circuit, ``k`` as in
    :func:`CoupledInductors` (the circuit replaces the pair by one coupled part)."""

    def __init__(self, first: str, second: str, coupling: float, *, name: str):
        self.name, self.first, self.second = str(name), str(first), str(second)
        self.coupling = finite(f"MutualInductance {name!r}", "coupling", coupling)


def IdealTransformer(ratio, *, name: str) -> Part:
    r"""``V₁ = n V₂``, ``n i₁ + i₂ = 0``: the one-form ``n dq₁ + dq₂`` (``L = 0``), lossless.

    Pins ``p1``, ``n1`` (primary) and ``p2``, ``n2`` (secondary).
    """
    n = finite(f"IdealTransformer {name!r}", "ratio", ratio)
    if n == 0.0:
        raise ModelError(f"IdealTransformer {name!r}: ratio=0 connects nothing; pass n ≠ 0.")
    return Part(
        ("q1", "q2"),
        lambda q, v: 0.0 * v[0],
        constraints=np.array([[n, 1.0]]),
        constraint_names=("ratio",),
        name=name,
        pins=(("p1", "q1", 1), ("n1", "q1", -1), ("p2", "q2", 1), ("n2", "q2", -1)),
    )


def VoltageSource(value, *, name: str) -> Part:
    r"""``φ_p − φ_n = u(t)``: the force ``F = −u(t)`` on the branch charge.

    ``value``: a number, a waveform (:class:`~diracvi.components.Sine`, …) or
    ``u(t)``. The branch current is SPICE's ``i(V1)``: into ``p``, through the source,
    out of ``n`` (negative while the source delivers power).
    """
    wave = as_waveform(value, f"VoltageSource {name!r}")
    return Part(
        ("q",),
        _zero_l,
        force=_Source(wave),
        name=name,
        pins=_TWO_PINS,
        role="voltage",
        waveforms=(wave,),
    )


def CurrentSource(value, *, name: str) -> Part:
    r"""The affine constraint ``q̇ − u(t) = 0``: ``u`` flows from ``p`` through the source
    to ``n`` (SPICE's ``I`` convention), whatever the voltage."""
    wave = as_waveform(value, f"CurrentSource {name!r}")
    return Part(
        ("q",),
        _zero_l,
        constraints=np.array([[1.0]]),
        constraint_offset=lambda q, t: -jnp.atleast_1d(wave(t)),
        constraint_names=("I",),
        name=name,
        pins=_TWO_PINS,
        role="current",
        waveforms=(wave,),
    )
