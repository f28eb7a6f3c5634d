r"""Linear controlled sources (SPICE ``E``, ``F``, ``G``, ``H``) as Lagrange–Dirac parts.

A controlled source is **non-reciprocal**: its output depends on the controlling branch,
the controlling branch does not feel the output. No Lagrangian and no constraint
one-form can express that (a reaction ``Aᵀμ`` acts on every coordinate the one-form
touches, which would load the controlling branch), so the coupling enters as a
**resistive-like port**: an external force ``F(q, q̇)`` on the part's own coordinates
whose velocity Jacobian is not symmetric. The Dirac structure (KCL and the parts'
Lagrangians) is untouched and power-conserving; the force's power ``⟨F, q̇⟩ = −V_o i_o``
is the work the source delivers at its output port, and the power balance
``dE/dt = ⟨F, q̇⟩`` accounts for it (``docs/circuits.md``).

The controlling quantities are velocities of the part's coordinates:

* a **voltage** ``V_c = φ_cp − φ_cn`` is the velocity of a flux coordinate ``w`` on a
  sensing branch ``s`` between the control pins, with the gyrator Lagrangian ``L = w ṡ``
  (as in :mod:`~diracvi.components.diode`): the ``s``-line reads ``ẇ = V_c`` and the
  ``w``-line ``0 = ṡ``, so the sensing branch draws no current and absorbs no power;
* a **current** (``F``, ``H``) is the velocity of a pin-less coordinate ``c`` tied to the
  controlling element's branch charge ``q_V`` by the row ``ċ − q̇_V = 0`` that
  :class:`~diracvi.components.Circuit` adds (multiplier ``ν``). The part's ``c``-line is
  ``0 = ν`` (``L`` and ``F`` do not depend on ``c``), so the row carries no reaction into
  the controlling branch.

The output is a voltage (``E``, ``H``: the force ``F_o = −u`` on the output charge, as a
:func:`~diracvi.components.VoltageSource` with ``u`` the controlled value) or a current
(``G``, ``F``: an output flux ``w_o`` with ``L = w_o q̇_o`` and the force
``F_{w_o} = −u``, whose ``w_o``-line reads ``q̇_o = u``). Signs are SPICE's: the output
current flows into ``p``, through the source, out of ``n``.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.system import _UserFunction, _wrap
from ..runtime.program import lift
from ._part import Part

_OUT = (("p", "q", 1), ("n", "q", -1))
_SENSE = (("cp", "s", 1), ("cn", "s", -1))


class ControlledPart(Part):
    r"""A :class:`Part` whose branches play different roles, and which may read the
    current of another part's branch.

    Args (beside :class:`Part`'s):
        branch_roles: ``(coordinate, role)`` pairs overriding ``role`` per branch for the
            circuit's topology checks (``"voltage"``: fixes its voltage; ``"current"``:
            fixes its current, an open circuit for the checks).
        senses: ``(coordinate, element)`` pairs: the circuit adds the row
            ``d coordinate − d q_element = 0`` tying the pin-less ``coordinate`` to the
            branch charge of the element whose current is reported as ``i(element)``.
        mirrors: pin-less coordinates whose values copy another coordinate's velocity
            (the MOSFET's Meyer voltages ``y = ẇ`` and their multipliers ``z``): a
            variable step's error control leaves them out, as it controls the velocity
            they copy (their node values carry the midpoint rule's ±alternation, like
            node potentials, which step doubling would read as an error).
        pinned: pin-less positions held by a line that fixes only their step midpoint
            (a behavioural source's ``ddt`` position ``y``, ``ȳ = τ g``), whose node
            values a variable-step driver re-pins between steps
            (:mod:`diracvi.driver.pinned`): the midpoint leaves them an undamped −1 mode.
        law_roundoff: ``E(q, v, t)``, per coordinate of the part, a bound on the
            absolute round-off of its force (an I-form behavioural source: its law's
            running error bound, :mod:`diracvi.runtime.roundoff`, on the output flux,
            whose line sets the output current), or None. Newton accepts a residual at
            it and a variable step's error control judges no branch current below it
            (:mod:`diracvi.model.roundoff`).
        law_corners: ``K(q, v, dv, t)``, a ``(3, k)`` array: the arguments ``g`` of the
            ``k`` corners of the part's law (an ``abs``, a comparison, a ``max`` … of
            :data:`~diracvi.runtime.roundoff.CORNERS`: the law has a kink or a jump where
            ``g`` changes sign), the bound by which the velocities' absolute tolerances
            ``dv`` move each, and its terms (the scale it is known to relative to); or
            None for a law without corners. A variable step locates a corner's instant
            as a switch's (:mod:`diracvi.driver.law_corners`).
    """

    branch_roles: tuple[tuple[str, str], ...] = eqx.field(static=True)
    senses: tuple[tuple[str, str], ...] = eqx.field(static=True)
    mirrors: tuple[str, ...] = eqx.field(static=True)
    pinned: tuple[str, ...] = eqx.field(static=True)
    law_roundoff: object = None
    law_corners: object = None

    def __init__(
        self,
        *args,
        branch_roles=(),
        senses=(),
        mirrors=(),
        pinned=(),
        law_roundoff=None,
        law_corners=None,
        **kwargs,
    ):
        self.branch_roles = tuple((str(c), str(r)) for c, r in branch_roles)
        self.senses = tuple((str(c), str(e)) for c, e in senses)
        self.mirrors = tuple(str(c) for c in mirrors)
        self.pinned = tuple(str(c) for c in pinned)
        super().__init__(*args, **kwargs)
        self.law_roundoff = None if law_roundoff is None else _lifted(law_roundoff, self.n)
        self.law_corners = (
            None
            if law_corners is None
            else _lifted(law_corners, self.n, [(self.n,), (self.n,), (self.n,), ()])
        )


def _lifted(fn, n: int, shapes=None):
    """``fn(q, v, t)`` traced once to a program with its constants as arrays (as a
    part's force is, :class:`~diracvi.model.system.LagrangeDiracSystem`): a closure kept
    whole cannot be printed into the program store's key, and every process would trace
    and compile the variable-step loop again (measured: es_halfwave_scr 1.5 -> 6.9 s CPU
    warm). Called as ``law_roundoff(q, v, t=t)`` (``shapes``: the arguments', the time's
    last)."""
    lifted = lift(fn, [(n,), (n,), ()] if shapes is None else shapes)
    if lifted is None:
        return _wrap(fn, driven=True)
    program, consts, _ = lifted
    return _UserFunction(consts, program, True)


def coefficient(where: str, arg: str, value):
    """A finite number (or a traced JAX value, passed through unchecked so that
    ``jax.grad`` reaches it); anything else is a :class:`ModelError` naming it."""
    if isinstance(value, jax.core.Tracer):
        return value
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{where}: {arg}={value!r} is not a number; pass a float.") from None
    if not np.isfinite(x):
        raise ModelError(f"{where}: {arg}={value!r} must be finite.")
    return x


def _parameters(**values):
    return {k: v for k, v in values.items() if isinstance(v, float)}


def _control(where: str, control) -> str:
    if not isinstance(control, str) or not control:
        raise ModelError(
            f"{where}: control={control!r} must name the element whose current controls "
            "the source (e.g. control='Vsense', a voltage source in the circuit)."
        )
    return control


def VCVS(gain, *, name: str) -> ControlledPart:
    r"""SPICE ``E``: ``φ_p − φ_n = gain · (φ_cp − φ_cn)``.

    Coordinates ``(q, s, w)``: output charge, sensing branch, its flux;
    ``L = w ṡ``, ``F = (−gain·ẇ, 0, 0)``. Pins ``p, n`` (output), ``cp, cn`` (control).
    """
    a = coefficient(f"VCVS {name!r}", "gain", gain)

    def lagrangian(q, v):
        return q[2] * v[1] + 0.0 * v[0]

    def force(q, v):
        return jnp.stack([-a * v[2], 0.0 * v[1], 0.0 * v[2]])

    return ControlledPart(
        ("q", "s", "w"),
        lagrangian,
        force=force,
        name=name,
        pins=_OUT + _SENSE,
        currents=(("", "q"),),
        role="voltage",
        branch_roles=(("q", "voltage"), ("s", "current")),
        parameters=_parameters(gain=a),
    )


def VCCS(transconductance, *, name: str) -> ControlledPart:
    r"""SPICE ``G``: the current ``gm · (φ_cp − φ_cn)`` flows into ``p``, through the
    source, out of ``n``.

    Coordinates ``(q, w_o, s, w)``: output charge and flux, sensing branch and flux;
    ``L = w_o q̇ + w ṡ``, ``F = (0, −gm·ẇ, 0, 0)``. Pins ``p, n``, ``cp, cn``.
    """
    g = coefficient(f"VCCS {name!r}", "transconductance", transconductance)

    def lagrangian(q, v):
        return q[1] * v[0] + q[3] * v[2]

    def force(q, v):
        return jnp.stack([0.0 * v[0], -g * v[3], 0.0 * v[2], 0.0 * v[3]])

    return ControlledPart(
        ("q", "wo", "s", "w"),
        lagrangian,
        force=force,
        name=name,
        pins=_OUT + _SENSE,
        currents=(("", "q"),),
        role="current",
        branch_roles=(("q", "current"), ("s", "current")),
        parameters=_parameters(transconductance=g),
    )


def CCCS(gain, *, control: str, name: str) -> ControlledPart:
    r"""SPICE ``F``: the current ``gain · i(control)`` flows into ``p``, through the
    source, out of ``n``; ``i(control)`` is the controlling element's branch current
    (for a voltage source: into its ``+`` node, through it, out of its ``−`` node).

    Coordinates ``(q, w_o, c)``: output charge and flux, the copy of the controlling
    charge; ``L = w_o q̇``, ``F = (0, −gain·ċ, 0)``. Pins ``p, n``.
    """
    where = f"CCCS {name!r}"
    a = coefficient(where, "gain", gain)

    def lagrangian(q, v):
        return q[1] * v[0] + 0.0 * v[2]

    def force(q, v):
        return jnp.stack([0.0 * v[0], -a * v[2], 0.0 * v[2]])

    return ControlledPart(
        ("q", "wo", "c"),
        lagrangian,
        force=force,
        name=name,
        pins=_OUT,
        currents=(("", "q"),),
        role="current",
        senses=(("c", _control(where, control)),),
        parameters=_parameters(gain=a),
    )


def CCVS(transresistance, *, control: str, name: str) -> ControlledPart:
    r"""SPICE ``H``: ``φ_p − φ_n = transresistance · i(control)`` (``i(control)`` as for
    :func:`CCCS`).

    Coordinates ``(q, c)``: output charge, the copy of the controlling charge; ``L = 0``,
    ``F = (−r·ċ, 0)``. Pins ``p, n``.
    """
    where = f"CCVS {name!r}"
    r = coefficient(where, "transresistance", transresistance)

    def lagrangian(q, v):
        return 0.0 * v[0]

    def force(q, v):
        return jnp.stack([-r * v[1], 0.0 * v[1]])

    return ControlledPart(
        ("q", "c"),
        lagrangian,
        force=force,
        name=name,
        pins=_OUT,
        currents=(("", "q"),),
        role="voltage",
        senses=(("c", _control(where, control)),),
        parameters=_parameters(transresistance=r),
    )
