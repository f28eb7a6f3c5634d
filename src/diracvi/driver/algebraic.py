r"""Coordinates whose momentum the midpoint step carries only as an undamped −1 mode.

A coordinate ``j`` on which the Lagrangian has no velocity dependence (``∂L/∂v_j ≡ 0``)
and which no constraint row touches (``(Aᵀμ)_j ≡ 0``) — a diode's flux linkage ``w``
without junction charge, whose velocity is the junction voltage — has the continuous
momentum ``p_j = ∂L/∂v_j = 0``: its Euler–Lagrange line is algebraic,
``E_j = ∂L/∂q_j + F_j = 0`` (the diode's law ``q̇ = i_D(ẇ)``). The (+) midpoint step
puts half of the step's ``h E_j`` on each end,

    p_{k,j} = −(h/2) E_j(q̄_k, v_k),      p_{k+1,j} = (h/2) E_j(q̄_k, v_k),

so ``p_{k+1,j} = −p_{k,j}``: the algebraic line holds only as the mean of two consecutive
steps, and its defect ``ε_k = h E_j`` alternates undamped, ``ε_k = −ε_{k−1}`` (the
midpoint's amplification −1 at infinite stiffness). In exact arithmetic from a start
with ``p_{0,j} = 0`` it is zero at every step; in floating point each step adds its
round-off (a breakdown junction's ``i_D(V)`` is evaluated to ~``|V|/nV_T`` ulps), the
defects add up as a random walk, and as a current ``ε/h`` the walk grows as the step
shrinks: at a floating node held by picosiemens (two nearly-off diodes, the zener deck
near its zero crossings) a stored ``ε ≈ 3·10⁻²¹ C`` alternated the node by 0.06 V at
10 ns steps, and the error control, seeing it, cut the steps further.

The variable-step driver therefore holds these momenta at their value ``0`` after every
step (:func:`algebraic_mask`): each step then satisfies its algebraic line itself,
``E_j(q̄_k, v_k) = 0``, as SPICE solves a junction's law at every time point. It removes
round-off only — with ``p_{0,j} = 0`` the exact (+) steps have ``p_{k,j} = 0`` — so the
constraints, the step's discrete power balance and everything exact are untouched.

Only lines free of their own coordinate (``∂E_j/∂q_j ≡ 0``: the diode's law reads ``ẇ``,
not ``w``) are held. A line that reads ``q_j`` itself fixes only the midpoint
``q̄_j = (q_{j,k} + q_{j,k+1})/2``, so ``q_j`` keeps a −1 mode of its own,
``q_{j,k+1} = 2q̄_j − q_{j,k}``, whatever its momentum (a behavioural source's ``ddt``
position ``y``, held by ``g = ȳ/τ``): holding its momentum would not damp it
(:mod:`.pinned` re-pins that one instead).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ..runtime.compile import run_once_jit

#: random points at which ∂L/∂v and Aᵀ are probed (a dependence that vanishes at all
#: of them by chance is not a concern: autodiff gives exact zeros only for no dependence)
_PROBES = 3


def _probe(system, q, v, t0):
    """``(∂L/∂v, diag ∂E/∂q, Aᵀ)`` at one point: one program for all three."""

    def line(q, v):  # E(q, v) = ∂L/∂q + F: the Euler–Lagrange line without ṗ
        e = jax.grad(lambda a: system.lagrangian(a, v, t0))(q)
        return e + system.force(q, v, t0) if system.has_force else e

    dldv = jax.grad(lambda b: system.lagrangian(q, b, t0))(v)
    own = jnp.diagonal(jax.jacfwd(line)(q, v))
    rows = jax.jacfwd(lambda mu: system.multiplier_force(q, mu, t0))(jnp.zeros(system.m))
    return dldv, own, rows


@run_once_jit
def _probes(system, qs, vs, t0):
    """:func:`_probe` at each of the points: one program per system's structure, kept
    (traced afresh at every run it cost ~0.13 CPU s a call on the bridge rectifier)."""
    return jax.vmap(lambda q, v: _probe(system, q, v, t0))(qs, vs)


def algebraic_mask(system, q0, p0, t0=0.0, seed=0) -> np.ndarray:
    """A boolean per coordinate: ``∂L/∂v_j``, the column ``j`` of ``Aᵀ`` and
    ``∂E_j/∂q_j`` (``E = ∂L/∂q + F``) vanish at every probe (exactly, as autodiff gives
    them), and ``p0_j = 0`` — the coordinates whose momentum the (+) steps keep at zero
    in exact arithmetic and whose line then holds on each step (module docstring)."""
    n, m = system.n, system.m
    q0 = np.asarray(q0, dtype=np.float64)
    rng = np.random.default_rng(seed)
    scale = np.maximum(np.abs(q0), 1.0)

    qs = q0 + 1e-3 * scale * rng.standard_normal((_PROBES, n))
    vs = rng.standard_normal((_PROBES, n))
    dldv, own, rows = (np.asarray(a) for a in _probes(system, qs, vs, np.float64(t0)))
    free = np.asarray(p0, dtype=np.float64) == 0.0
    free &= np.all(dldv == 0.0, axis=0) & np.all(own == 0.0, axis=0)
    if m:
        free &= np.all(rows == 0.0, axis=(0, 2))  # Aᵀ: (probes, n, m)
    return free


@run_once_jit
def _inertia(system, q, t0, which):
    """``∂²L/∂v_j²`` at ``(q, v = 0)`` for each ``j`` of ``which``: one Hessian-vector
    product per coordinate in a loop (memory O(n): the dense Hessian of a large circuit
    would be O(n²))."""
    zero = jnp.zeros(q.shape[0], q.dtype)

    def momentum(v):
        return jax.grad(lambda b: system.lagrangian(q, b, t0))(v)

    def entry(j):
        unit = zero.at[j].set(1.0)
        return jax.jvp(momentum, (zero,), (unit,))[1][j]

    return jax.lax.map(entry, which)


@run_once_jit
def _inertia_coloured(system, q, t0, seeds):
    """``(∂²L/∂v²) s`` at ``(q, v = 0)`` for each seed ``s`` (rows of ``seeds``): one
    Hessian-vector product a seed, in a loop."""
    zero = jnp.zeros(q.shape[0], q.dtype)

    def momentum(v):
        return jax.grad(lambda b: system.lagrangian(q, b, t0))(v)

    return jax.lax.map(lambda seed: jax.jvp(momentum, (zero,), (seed,))[1], seeds)


def block_colours(system) -> np.ndarray | None:
    """Per coordinate of an interconnection ``L = Σ_i L^i(q_i, v_i)``, its position in
    its part's block (the blocks are ``system._offsets``), or ``None`` for a system that
    is not one. ``∂²L/∂v²`` is block diagonal by part, so coordinates of one position
    in different parts meet in no entry: one product along the sum of their unit
    vectors reads each one's diagonal entry, ``(M s_c)_j = M_jj``."""
    offsets = getattr(system, "_offsets", None)
    if offsets is None or not getattr(system, "subsystems", None):
        return None
    offsets = np.asarray(offsets, dtype=np.int64)
    sizes = np.diff(offsets)
    return np.arange(system.n, dtype=np.int64) - np.repeat(offsets[:-1], sizes)


def inertia(system, q0, t0=0.0, which=None) -> np.ndarray:
    """Per coordinate, its inertia ``M_jj = ∂²L/∂v_j²`` at ``q0`` and rest (an inductor's
    inductance; 0 for a coordinate the Lagrangian reads no velocity of), probed for the
    coordinates ``which`` (indices; default all) and 0 for the others: the scale of a
    nodal momentum's error in the step control
    (:func:`~diracvi.driver.step_error.node_momentum_error`).

    An interconnection's are read by part position (:func:`block_colours`): as many
    products as its largest part has coordinates (one on a ladder of R, L and C),
    where one a coordinate made the probe O(n²) — 0.6 s at 9001 coordinates, 5.1 s at
    30 001 (``docs/performance.md``)."""
    n = system.n
    which = np.arange(n) if which is None else np.asarray(which, dtype=np.int32).reshape(-1)
    out = np.zeros(n)
    if which.size:
        # NumPy arguments, as the program takes them: jnp.asarray of NumPy data is an
        # eager program per shape, compiled in every process
        q = np.asarray(q0, dtype=np.float64).reshape(n)
        colour = block_colours(system)
        if colour is None:
            out[which] = np.asarray(_inertia(system, q, np.float64(t0), which))
            return out
        used = np.unique(colour[which])
        seeds = (colour[None, :] == used[:, None]).astype(np.float64)
        products = np.asarray(_inertia_coloured(system, q, np.float64(t0), seeds))
        out[which] = products[np.searchsorted(used, colour[which]), which]
    return out


__all__ = ["algebraic_mask", "block_colours", "inertia"]
