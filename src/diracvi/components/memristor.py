r"""A memristor with threshold (XSPICE's ``memristor`` code model): a resistor whose value
is a state integrated from the voltage across it.

    i = V / R,     dR/dt = g(f(V), R),     f(V) = α·c + β·(V − c),
    c = sign(v_t)·clip(V, −|v_t|, |v_t|)

(Pershin & Di Ventra, *SPICE model of memristive devices with threshold*, 2012, as
ngspice 39's ``xtradev/memristor`` computes it: ``f`` is its ``β V + ½(α − β)(|V + v_t| −
|V − v_t|)``, written here without that form's cancellation of two ``β V`` terms, which
for ``β`` = 2e12 is round-off of up to 5e-4 Ω/s below the threshold). The rate stops at
the limits: ``g = f`` unless ``R ≥ R_max`` and ``f > 0`` or ``R ≤ R_min`` and ``f < 0``,
where ``g = 0``.

**In the Lagrange–Dirac structure.** The state ``R`` is the voltage of a node ``h`` (pins
``h``, ``g``) that a 1 F capacitor holds (its charge is ``R``; the builder adds it, so an
operating point holds the node as it holds a ``.ic`` node, and UIC starts it at ``R₀``).
The part's coordinates are ``(q, r, o, s, w)`` with

    L = o·ṙ + w·ṡ,      F = (−R q̇, 0, −g, 0, 0),      R = ẇ:

* ``q`` is the port's branch charge (pins ``p``, ``n``): its line reads
  ``φ_p − φ_n = R q̇``, a resistor of value ``R``;
* ``r`` is a feed branch from ``g`` into ``h`` with its flux ``o`` (an I-form behavioural
  source, :mod:`~diracvi.components.behavioural`): the ``o``-line reads ``ṙ = g``, so
  the capacitor's charge ``R`` has the rate ``g``;
* ``s``, ``w`` sense the state (``L = w ṡ``, a voltage switch's sensing branch,
  :mod:`~diracvi.components.switch`): the ``s``-line reads ``ẇ = φ_h − φ_g = R``, and
  the sensing branch draws no current.

The power ``⟨F, q̇⟩ = −R q̇² − g ȯ``: the port dissipates ``V²/R`` as a resistor does,
and ``−g ȯ = g R`` (the ``r``-line reads ``ȯ = φ_g − φ_h = −R``) is the feed's power
into the state capacitor, ``d(½R²)/dt``, which its energy stores — a bookkeeping energy
of the state (as XSPICE's ``int``'s integral is), so the discrete power balance
``E_{k+1} − E_k = h⟨F, q̇⟩`` holds step by step with the dissipation of the port and the
feed's work on the state.

**The limits are located events.** ``g`` jumps from ``f`` to 0 where ``R`` reaches a
limit, a corner of the state's trajectory that a step across it would smear (and no
midpoint step solves: just below the limit the step overshoots it, just above it stays
short). Two hysteresis relays (:class:`~diracvi.components.switch.Relay`) carry which
limit holds, read from ``R`` as a voltage switch reads its control (the sensing branch's
impulse), and the variable-step driver locates their flips (:mod:`diracvi.driver.events`):

* ``upper`` closes when ``R > R_max`` (then ``g = min(f, 0)``: the state stays unless
  the drive turns it back), and opens below ``R_max − δ``;
* ``lower`` is closed while free: it opens when ``R < R_min`` (then ``g = max(f, 0)``)
  and closes again above ``R_min + δ``.

Between the flips ``g`` is smooth. A flip is taken within half its event tolerance of
the level, either side (``0.015·rtol·R_max + vntol/2``: 0.15 Ω at ``R_max`` = 10 kΩ and
``rtol`` = 1e-3), and the state then stays where it is; the release level
``δ = 1e-4·max(|R_min|, |R_max|)`` (1 Ω there) lies beyond that, up to ``rtol`` ≈ 6e-3,
so a held state is not released at once. A drive that turns back and forth within ``δ``
of a limit leaves the state up to ``δ`` short of it where ngspice would return to it.

**ngspice's state is first order.** Its ``cm_analog_integrate`` under the trapezoidal
method at order 2 (``cm_static_integrate``, marked "needs to be redone") is backward
Euler, ``R_{k+1} = R_k + h f(V_{k+1})``, and it tests the limits on the last Newton
iterate, so its state passes a limit by up to a step's increase: its runs converge first
order in the step (measured, ``tests/test_memristor.py``), to what this part's midpoint
steps converge to at second order.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from ..errors import ModelError
from ._part import finite, positive
from .controlled import ControlledPart
from .switch import Relay

#: the release level's distance from a limit, relative to the larger limit (module doc)
RELEASE = 1e-4


def threshold_rate(v, alpha, beta, vt):
    r"""ngspice's window ``f(V) = β V + ½(α − β)(|V + v_t| − |V − v_t|)``, computed as
    ``α c + β (V − c)`` with ``c = sign(v_t)·clip(V, −|v_t|, |v_t|)`` (the same function,
    without the cancellation of the two ``β V`` terms beyond the threshold's inside)."""
    a = jnp.abs(vt)
    c = jnp.sign(vt) * jnp.clip(v, -a, a)
    return alpha * c + beta * (v - c)


class _MemristorForce(eqx.Module):
    """``F = (−R q̇, 0, −g, 0, 0)`` with ``R = ẇ`` (module docstring)."""

    alpha: jax.Array
    beta: jax.Array
    vt: jax.Array
    upper: Relay
    lower: Relay

    def __call__(self, q, v):
        r = v[4]
        f = threshold_rate(r * v[0], self.alpha, self.beta, self.vt)
        g = jnp.where(
            self.upper.closed > 0.5,
            jnp.minimum(f, 0.0),
            jnp.where(self.lower.closed > 0.5, f, jnp.maximum(f, 0.0)),
        )
        zero = 0.0 * v[1]
        return jnp.stack([-r * v[0], zero, -g, zero, zero])


class _Lagrangian(eqx.Module):
    """``L = o ṙ + w ṡ``."""

    def __call__(self, q, v):
        return q[2] * v[1] + q[4] * v[3] + 0.0 * v[0]


def Memristor(
    r_min=10.0,
    r_max=1e4,
    r_init=7e3,
    alpha=0.0,
    beta=1.0,
    vt=0.0,
    *,
    name: str,
) -> ControlledPart:
    r"""XSPICE's ``memristor`` (module docstring; defaults as ngspice 39's ``rmin``,
    ``rmax``, ``rinit``, ``alpha``, ``beta``, ``vt``).

    Pins ``p``, ``n`` (the port: ``i = V/R`` from ``p`` through the part to ``n``) and
    ``h``, ``g`` (the state node pair: connect a 1 F capacitor from ``h`` to ``g``
    charged to ``r_init``, whose voltage is ``R``). ``r_init`` sets only the relays'
    first states (a limit holds from the start if ``r_init`` is at or beyond it).
    """
    where = f"Memristor {name!r}"
    lo = positive(where, "rmin", r_min)
    hi = positive(where, "rmax", r_max)
    r0 = positive(where, "rinit", r_init)
    if not lo < hi:
        raise ModelError(
            f"{where}: rmin={lo:g} must be below rmax={hi:g} (the state's limits); "
            "swap them or widen the range."
        )
    alpha = finite(where, "alpha", alpha)
    beta = finite(where, "beta", beta)
    vt = finite(where, "vt", vt)
    d = RELEASE * max(abs(lo), abs(hi))
    upper = Relay(jnp.asarray(1.0 if r0 >= hi else 0.0), hi, hi - d, "s", impulse=True)
    lower = Relay(jnp.asarray(1.0 if r0 > lo else 0.0), lo + d, lo, "s", impulse=True)
    force = _MemristorForce(
        jnp.asarray(alpha, float), jnp.asarray(beta, float), jnp.asarray(vt, float), upper, lower
    )
    return ControlledPart(
        ("q", "r", "o", "s", "w"),
        _Lagrangian(),
        force=force,
        name=name,
        pins=(
            ("p", "q", 1),
            ("n", "q", -1),
            ("g", "r", 1),
            ("h", "r", -1),
            ("h", "s", 1),
            ("g", "s", -1),
        ),
        currents=(("", "q"),),
        role="resistor",
        branch_roles=(("q", "resistor"), ("r", "current"), ("s", "current")),
        # the feed's charge r is the state's increment R − R₀ (KCL at h): a step control
        # judges it through the capacitor's charge R, at R's size. Judged as a charge of
        # its own (from 0, against chgtol + reltol·|r|), the rate's kink at the threshold
        # is an O(1) relative error of a charge that has just started, at any step: at
        # reltol 1e-6 the steps fell to hmin at the first threshold crossing
        mirrors=("r",),
        parameters={
            "rmin": lo,
            "rmax": hi,
            "rinit": r0,
            "alpha": alpha,
            "beta": beta,
            "vt": vt,
        },
    )
