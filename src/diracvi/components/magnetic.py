r"""Windings on one magnetic core: a nonlinear coupled inductor given by its co-energy.

Windings of ``N_k`` turns on one core carry the magnetomotive force (MMF)
``F = Σ_k N_k i_k``; the core answers with the flux ``Φ(F)`` and each winding sees
``v_k = N_k dΦ/dt``. With the branch currents ``i_k = q̇_k`` this is the Lagrangian

    L(q, q̇) = W*(F),   F = Σ_k N_k q̇_k,   W*(F) = ∫₀^F Φ(f) df     (magnetic co-energy)

whose momenta are the flux linkages ``p_k = ∂L/∂q̇_k = N_k Φ(F)``, so the Euler–Lagrange
line of winding k is ``d(N_k Φ)/dt = V_k``. Its energy ``⟨p, q̇⟩ − L = FΦ − W*(F) =
∫₀^Φ F dφ`` is the energy stored in the core, so the circuit's power balance holds with
it. The inductance matrix ``∂²L/∂q̇_j∂q̇_k = N_j N_k Φ′(F)`` has rank one: the
windings are perfectly coupled (an ideal transformer in parallel with a magnetizing
inductance), and the Lagrangian is degenerate in the other directions, as a circuit's is.

A core is a :class:`CoreLaw` — ``flux(F)`` and ``coenergy(F)`` with ``coenergy′ = flux``:

- :class:`Reluctance`: a linear magnetic path, ``Φ = F/ℛ``, ``W* = F²/(2ℛ)``; the
  windings are the inductances ``L_jk = N_j N_k / ℛ`` (``ℛ = l/(μA)`` for a core of
  permeability μ, area A, length l).
- :class:`PiecewiseLinearCore`: ngspice XSPICE's ``core`` model in its PWL mode:
  ``Φ = A·B(F/l)`` with ``B(H)`` piecewise linear through ``(H_j, B_j)``, its inner
  corners rounded by parabolas, extended beyond the table by its end segments.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..runtime.roundoff import corner_arguments, corner_rows
from ._part import Part, finite, positive, traced
from .controlled import ControlledPart


class CoreLaw(eqx.Module):
    """The magnetic path the windings share: its flux and co-energy as functions of
    the MMF ``F`` (ampere-turns). ``coenergy(0) = 0`` and ``d coenergy/dF = flux``."""

    @abc.abstractmethod
    def flux(self, mmf):
        """``Φ(F)`` in webers."""

    @abc.abstractmethod
    def coenergy(self, mmf):
        """``W*(F) = ∫₀^F Φ(f) df`` in joules."""


class Reluctance(CoreLaw):
    r"""A linear magnetic path of reluctance ``ℛ`` (A-turns/Wb): ``Φ = F/ℛ``,
    ``W* = F²/(2ℛ)``. (SPICE writes it as a resistor between two MMF nodes.)"""

    reluctance: object

    def __init__(self, reluctance):
        self.reluctance = positive("Reluctance", "reluctance", reluctance)

    def flux(self, mmf):
        return mmf / self.reluctance

    def coenergy(self, mmf):
        return 0.5 * mmf**2 / self.reluctance


class PiecewiseLinearCore(CoreLaw):
    r"""ngspice XSPICE's ``core`` in PWL mode: ``Φ = A·B(H)``, ``H = F/l``.

    ``B(H)`` is the broken line through ``(h[j], b[j])`` (``h`` increasing), extended
    beyond both ends by its first and last segments. Each inner corner ``h[j]`` is
    rounded over ``|H − h[j]| < d_j`` by the parabola tangent to both segments, with
    ``d_j = input_domain · min(h[j] − h[j−1], h[j+1] − h[j])`` (``fraction=True``, the
    default) or ``d_j = input_domain`` (``fraction=False``). Written as ramps,

        B(H) = b₀ + s₀ (H − h₀) + Σ_j (s_j − s_{j−1}) ρ_{d_j}(H − h_j),
        ρ_d(u) = 0 (u < −d),  (u + d)²/(4d) (|u| ≤ d),  u (u > d),

    with ``s_j`` the slope of segment j, so ``B`` has a continuous slope and its
    integral is closed-form: ``∫ρ_d = 0``, ``(u + d)³/(12d)``, ``u²/2 + d²/6``. The
    co-energy is ``W*(F) = A·l·∫₀^H B(h) dh``.

    Args:
        h, b: the ``H_array`` (A/m, strictly increasing, at least 2) and ``B_array`` (T).
        area: cross-section ``A`` (m²). length: mean magnetic path ``l`` (m).
        input_domain: the rounding's half-width, a fraction of the shorter neighbouring
            segment in ``[1e-12, 0.5]`` (``fraction=True``) or absolute (``False``: each
            segment must be at least ``2·input_domain`` long, ngspice's "50% rule").
        fraction: how ``input_domain`` is read (ngspice's default ``True``).
    """

    area: object
    length: object
    h0: object
    b0: object
    s0: object
    corners: object  # the inner corners h_j
    jumps: object  # s_j − s_{j−1}
    domains: object  # d_j
    offset: object  # the antiderivative at H = 0, so that W*(0) = 0

    def __init__(self, h, b, *, area, length, input_domain=0.01, fraction=True):
        where = "PiecewiseLinearCore"
        self.area = positive(where, "area", area)
        self.length = positive(where, "length", length)
        h, b = _table(where, h, b)
        slopes = (b[1:] - b[:-1]) / (h[1:] - h[:-1])
        seg = h[1:] - h[:-1]
        domain = finite(where, "input_domain", input_domain)
        if fraction:
            if not traced(domain) and not 1e-12 <= domain <= 0.5:
                raise ModelError(
                    f"{where}: input_domain={input_domain!r} with fraction=True must lie in "
                    "[1e-12, 0.5] (a fraction of the shorter segment at each corner; over "
                    "0.5 the roundings of neighbouring corners would overlap)."
                )
            domains = domain * jnp.minimum(seg[:-1], seg[1:])
        else:
            short = np.asarray(seg) < 2.0 * domain if not _any_traced(seg, domain) else []
            if np.any(short) or (not traced(domain) and domain <= 0.0):
                raise ModelError(
                    f"{where}: input_domain={input_domain!r} with fraction=False must be "
                    "positive and at most half of every segment (ngspice's 50% rule: "
                    f"the shortest segment is {float(np.min(np.asarray(seg))):g}); lower it, "
                    "or give it as a fraction (fraction=True)."
                )
            domains = domain * jnp.ones_like(seg[:-1])
        self.h0, self.b0, self.s0 = h[0], b[0], slopes[0]
        self.corners, self.jumps, self.domains = h[1:-1], slopes[1:] - slopes[:-1], domains
        self.offset = _primitive(0.0, self.h0, self.b0, self.s0, h[1:-1], self.jumps, domains)

    def flux_density(self, field):
        """``B(H)`` (tesla) at the field ``H`` (A/m)."""
        u = field - self.corners
        d = self.domains
        ramp = jnp.where(u < -d, 0.0, jnp.where(u > d, u, (u + d) ** 2 / (4.0 * d)))
        return self.b0 + self.s0 * (field - self.h0) + jnp.sum(self.jumps * ramp)

    def _integral(self, field):
        """``∫₀^H B(h) dh``."""
        args = (self.h0, self.b0, self.s0, self.corners, self.jumps, self.domains)
        return _primitive(field, *args) - self.offset

    def flux(self, mmf):
        return self.area * self.flux_density(mmf / self.length)

    def coenergy(self, mmf):
        return self.area * self.length * self._integral(mmf / self.length)


def _primitive(field, h0, b0, s0, corners, jumps, domains):
    """An antiderivative of ``B`` (the ramps integrated, see the class docstring)."""
    u = field - corners
    d = domains
    ramp = jnp.where(
        u < -d, 0.0, jnp.where(u > d, 0.5 * u**2 + d**2 / 6.0, (u + d) ** 3 / (12.0 * d))
    )
    return b0 * field + 0.5 * s0 * (field - h0) ** 2 + jnp.sum(jumps * ramp)


def _any_traced(*values) -> bool:
    return any(traced(v) for v in values)


def _table(where: str, h, b):
    """The ``(H, B)`` table as float arrays, checked: same length ≥ 2, finite, ``H``
    strictly increasing (a traced table passes unchecked)."""
    if _any_traced(h, b):
        return jnp.asarray(h, dtype=float), jnp.asarray(b, dtype=float)
    h = np.asarray(h, dtype=np.float64).reshape(-1)
    b = np.asarray(b, dtype=np.float64).reshape(-1)
    if h.shape != b.shape or h.size < 2:
        raise ModelError(
            f"{where}: H_array and B_array must have the same length, at least 2 "
            f"(got {h.size} and {b.size} values)."
        )
    if not (np.all(np.isfinite(h)) and np.all(np.isfinite(b))):
        raise ModelError(f"{where}: H_array and B_array must be finite numbers.")
    if np.any(np.diff(h) <= 0.0):
        j = int(np.argmax(np.diff(h) <= 0.0))
        raise ModelError(
            f"{where}: H_array must increase strictly (H[{j}] = {h[j]:g}, H[{j + 1}] = "
            f"{h[j + 1]:g}); list the B(H) points in order of H."
        )
    return h, b


_ENDS = (("p", 1), ("n", -1))


class _Coenergy(eqx.Module):
    """``L = W*(Σ_k N_k q̇_k)``."""

    core: CoreLaw
    turns: object

    def __call__(self, q, v):
        return self.core.coenergy(jnp.dot(self.turns, v)) + 0.0 * q[0]


def WoundCore(core: CoreLaw, turns, *, name: str, labels=None, i0=None) -> Part:
    r"""Windings of ``turns[k]`` turns on one ``core``: ``L = W*(Σ_k N_k q̇_k)``.

    A turn count's sign is its winding's sense: the MMF is ``Σ N_k i_k`` with ``i_k``
    entering pin ``p<k>``. Pins ``p1``, ``n1``, ``p2``, ``n2``, … (branch ``q<k>``);
    ``labels`` name the currents (default ``"<name>.1"``, …); ``i0`` the initial
    currents (default 0). See the module docstring for the equations.
    """
    where = f"WoundCore {name!r}"
    if not isinstance(core, CoreLaw):
        raise ModelError(
            f"{where}: core={core!r} is not a core law; pass Reluctance(ℛ) or "
            "PiecewiseLinearCore(h, b, area=…, length=…)."
        )
    turns = list(turns) if not traced(turns) and np.ndim(turns) else turns
    count = len(turns)
    if count == 0:
        raise ModelError(f"{where}: turns=() winds nothing; give one turn count per winding.")
    values = [finite(where, f"turns[{k}]", n) for k, n in enumerate(turns)]
    if any(not traced(n) and n == 0.0 for n in values):
        raise ModelError(f"{where}: a winding of 0 turns couples nothing; remove it.")
    coords = tuple(f"q{k + 1}" for k in range(count))
    pins = [
        pin for k, c in enumerate(coords) for pin in ((f"p{k + 1}", c, 1), (f"n{k + 1}", c, -1))
    ]
    labels = labels or tuple(f"{name}.{k + 1}" for k in range(count))
    if len(labels) != count:
        raise ModelError(f"{where}: labels={labels!r} must name the {count} windings' currents.")
    i0 = (0.0,) * count if i0 is None else tuple(i0)
    coenergy = _Coenergy(core, jnp.stack([jnp.asarray(n, dtype=float) for n in values]))
    return ControlledPart(
        coords,
        coenergy,
        name=name,
        pins=pins,
        currents=tuple(zip(labels, coords, strict=True)),
        initial_v=[finite(where, f"i0[{k}]", x) for k, x in enumerate(i0)],
        role="wound core",
        law_corners=_core_corners(coenergy),
    )


def _core_corners(coenergy: _Coenergy):
    """``K(q, v, dv, t)`` of :class:`~.controlled.ControlledPart`: the corners of the
    core's ``B(H)`` at the MMF ``F = Σ N_k q̇_k`` — a :class:`PiecewiseLinearCore`'s
    rounded corner begins and ends where ``H − H_j = ∓d_j`` (its comparisons), and there
    ``B″`` jumps, so the windings' current has a kink in its slope that a step's error
    estimate reads only as an average. Located as a behavioural law's corners are
    (:mod:`diracvi.driver.law_corners`; the transformer deck of tests/test_magnetics.py:
    a try across the end of a corner's rounding read ``v(m1)`` 1.06e-3 of its peak off
    at its end node, 1.1e-4 one node on). None for a core without corners (a
    :class:`Reluctance`)."""
    core, turns = coenergy.core, coenergy.turns
    if corner_arguments(core.flux, (0.0,), (0.0,))[0].shape[0] == 0:
        return None

    def law_corners(q, v, dv, t):
        mmf = jnp.dot(turns, v)
        # a tolerance not set (inf on a coordinate the step control leaves out) moves
        # nothing: the corner is then known to its terms only
        dmmf = jnp.dot(jnp.abs(turns), jnp.where(jnp.isfinite(dv), dv, 0.0))
        return corner_rows(core.flux, (mmf,), (dmmf,))

    return law_corners
