r"""The paper's chain of spring masses attached to a wall (§5.1), monolithic form.

``L = Σ ½ m_i (v^i)² − ½ k_1 (q^1)² − Σ_{i≥2} ½ k_i (q^i − q^{i−1})²`` — no constraints,
so the (+) equations reduce to the discrete Euler–Lagrange equations. Paper data:
``m_i = k_i = 1``, ``q_0 = (0, 1, 2)``, ``p_0 = (0, 0, 3)``, ``h = 0.01``, 1000 steps.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from functools import cache

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..model.interaction import connect
from ..model.interconnect import interconnect
from ..model.system import LagrangeDiracSystem
from ._problem import Problem, linear_flow, mass_spring_generator


def chain_stiffness(springs) -> np.ndarray:
    """``K`` of a wall-anchored chain: ``V = ½ qᵀ K q``."""
    k = np.asarray(springs, dtype=np.float64)
    n = k.size
    stiff = np.zeros((n, n))
    stiff[0, 0] += k[0]
    for i in range(1, n):
        stiff[i, i] += k[i]
        stiff[i - 1, i - 1] += k[i]
        stiff[i, i - 1] -= k[i]
        stiff[i - 1, i] -= k[i]
    return stiff


def chain_lagrangian(masses, springs):
    m = jnp.asarray(masses, dtype=jnp.float64)
    k = jnp.asarray(springs, dtype=jnp.float64)

    def lagrangian(q, v):
        stretch = jnp.concatenate([q[:1], q[1:] - q[:-1]])
        return 0.5 * jnp.sum(m * v**2) - 0.5 * jnp.sum(k * stretch**2)

    return lagrangian


def spring_chain(
    masses=(1.0, 1.0, 1.0),
    springs=(1.0, 1.0, 1.0),
    q0=(0.0, 1.0, 2.0),
    p0=(0.0, 0.0, 3.0),
    dt: float = 0.01,
    steps: int = 1000,
) -> Problem:
    """The paper's monolithic three-mass chain (or any N-mass chain)."""
    masses = np.asarray(masses, dtype=np.float64)
    n = masses.size
    coords = tuple(f"q{i + 1}" for i in range(n))
    system = LagrangeDiracSystem(coords, chain_lagrangian(masses, springs), name="chain")
    q0, p0 = np.asarray(q0, dtype=np.float64), np.asarray(p0, dtype=np.float64)
    state0 = np.concatenate([q0, p0 / masses])

    @cache  # dense n×n: built only when the exact solution is asked for (large chains)
    def generator():
        return mass_spring_generator(np.diag(masses), chain_stiffness(springs))

    def exact(t):
        return linear_flow(generator(), state0, t)[:, :n]

    return Problem(
        name="spring-chain",
        description="Paper §5.1: three masses on springs from a wall, monolithic (DEL equations)",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        exact=exact,
        reference="Parks & Leok §5.1, eqs. (mono_springs)",
        parameters={"masses": masses.tolist(), "springs": list(springs)},
    )


class SegmentLagrangian(eqx.Module):
    r"""``L = ½ Σ m_i (v^i)² − ½ Σ k_i (stretch_i)²`` of one piece of a torn chain.

    With ``port=True`` the coordinates are ``(q̄, q_0, q_1, …)`` and the first spring hangs
    from the massless port ``q̄`` (the paper's q̄²); without, it is anchored to the wall.
    Masses and stiffnesses are array leaves, so pieces of equal length have one PyTree
    structure and the partitioned solver steps them together with ``jax.vmap``.
    """

    masses: jax.Array
    springs: jax.Array
    port: bool = eqx.field(static=True)

    def __call__(self, q, v):
        if self.port:
            stretch = q[1:] - q[:-1]  # the first spring hangs from the port
            kinetic = 0.5 * jnp.sum(self.masses * v[1:] ** 2)
        else:
            stretch = jnp.concatenate([q[:1], q[1:] - q[:-1]])  # the first spring: the wall
            kinetic = 0.5 * jnp.sum(self.masses * v**2)
        return kinetic - 0.5 * jnp.sum(self.springs * stretch**2)


def _segment(name, masses, springs, with_port):
    """One piece of a torn chain: its masses, and (unless it is the wall end) a massless
    port coordinate ``qbar`` marking where its first spring attaches (the paper's q̄²)."""
    # NumPy leaves: a JAX array per piece costs a device transfer each, which is most of
    # the time of building 10⁴ pieces (they become arguments of the compiled step anyway)
    m = np.asarray(masses, dtype=np.float64)
    k = np.asarray(springs, dtype=np.float64)
    coords = tuple(f"q{i}" for i in range(len(masses)))
    if with_port:
        coords = ("qbar", *coords)
    return LagrangeDiracSystem(coords, SegmentLagrangian(m, k, with_port), name=name)


def spring_chain_torn(dt: float = 0.01, steps: int = 1000) -> Problem:
    r"""The paper's chain torn in two (§5.1): ``(q^1, q^2)`` and ``(q̄^2, q^3)``, with
    ``Σ° = span{dq^2 − dq̄^2}``. ``L^2`` has no velocity for ``q̄^2`` (degenerate), so the
    second piece alone cannot be stepped; joined, it can."""
    k = (1.0, 1.0, 1.0)

    def l1(q, v):
        return (
            0.5 * (v[0] ** 2 + v[1] ** 2) - 0.5 * k[0] * q[0] ** 2 - 0.5 * k[1] * (q[1] - q[0]) ** 2
        )

    def l2(q, v):
        return 0.5 * v[1] ** 2 - 0.5 * k[2] * (q[1] - q[0]) ** 2

    left = LagrangeDiracSystem(("q1", "q2"), l1, name="left")
    right = LagrangeDiracSystem(("q2bar", "q3"), l2, name="right")
    system = interconnect([left, right], [connect("left.q2", "right.q2bar")], name="chain")
    return Problem(
        name="spring-chain-torn",
        description="Paper §5.1: the three-mass chain as two interconnected subsystems",
        system=system,
        q0=np.array([0.0, 1.0, 1.0, 2.0]),
        p0=np.array([0.0, 0.0, 0.0, 3.0]),
        dt=dt,
        steps=steps,
        reference="Parks & Leok §5.1, eqs. (int_springs)",
        reduced=spring_chain(dt=dt, steps=steps),
        shared={"left.q1": "q1", "left.q2": "q2", "right.q3": "q3"},
        ports=(("left.q2", "right.q2bar"),),
    )


class _SharedNames(Mapping):
    """``"s{j}.q{i}" → "q{lo_j + i + 1}"``: a torn chain's coordinate → the reduced
    chain's, for pieces ``[lo_j, hi_j)``. A read-only mapping computed on lookup: as a
    dict it is 10⁶ pairs of formatted names, a quarter of building a 10⁶-mass chain."""

    def __init__(self, bounds: np.ndarray):
        self._bounds = bounds

    def __getitem__(self, key):
        piece, dot, local = key.partition(".") if isinstance(key, str) else ("", "", "")
        try:
            j, i = int(piece[1:]), int(local[1:])
        except ValueError:
            raise KeyError(key) from None
        if not (dot and piece == f"s{j}" and local == f"q{i}"):
            raise KeyError(key)
        if not (0 <= j < self._bounds.size - 1 and 0 <= i < self._bounds[j + 1] - self._bounds[j]):
            raise KeyError(key)
        return f"q{self._bounds[j] + i + 1}"

    def __iter__(self) -> Iterator[str]:
        for j in range(self._bounds.size - 1):
            for i in range(self._bounds[j + 1] - self._bounds[j]):
                yield f"s{j}.q{i}"

    def __len__(self) -> int:
        return int(self._bounds[-1] - self._bounds[0])


def chain_torn(masses: int = 12, pieces: int = 3, dt: float = 0.01, steps: int = 1000) -> Problem:
    r"""An N-mass chain torn into M pieces (any ``N ≥ M ≥ 2``), each joined to the next
    by ``dq_last − dq̄`` as in the paper. Masses and stiffnesses vary along the chain so
    that no symmetry hides an indexing mistake."""
    n, m = int(masses), int(pieces)
    if not 2 <= m <= n:
        raise ValueError(f"pieces={m} must satisfy 2 ≤ pieces ≤ masses={n}.")
    mass = 1.0 + 0.5 * np.sin(np.arange(n)) ** 2
    stiff = 1.0 + 0.3 * np.cos(np.arange(n)) ** 2
    bounds = np.linspace(0, n, m + 1).round().astype(int)
    segments, interactions, q0_parts, ports = [], [], [], []
    q0_full = np.arange(n, dtype=np.float64)
    p0_full = np.zeros(n)
    p0_full[-1] = 3.0
    p0_parts = []
    for j in range(m):
        lo, hi = bounds[j], bounds[j + 1]
        name = f"s{j}"
        segments.append(_segment(name, mass[lo:hi], stiff[lo:hi], with_port=j > 0))
        if j > 0:
            prev = f"s{j - 1}.q{bounds[j] - bounds[j - 1] - 1}"
            interactions.append(connect(prev, f"{name}.qbar"))
            ports.append((prev, f"{name}.qbar"))
            q0_parts.append([q0_full[lo - 1]])
            p0_parts.append([0.0])  # the massless port carries no momentum
        q0_parts.append(q0_full[lo:hi])
        p0_parts.append(p0_full[lo:hi])
    system = interconnect(segments, interactions, name="chain")
    q0 = np.concatenate(q0_parts)
    p0 = np.concatenate(p0_parts)  # in the system's coordinate order, as q0
    return Problem(
        name="chain-torn",
        description="An N-mass spring chain torn into M interconnected pieces",
        system=system,
        q0=q0,
        p0=p0,
        dt=dt,
        steps=steps,
        reference="generalizes Parks & Leok §5.1",
        reduced=spring_chain(mass, stiff, q0_full, p0_full, dt=dt, steps=steps),
        shared=_SharedNames(bounds),
        ports=tuple(ports),
        parameters={"N": n, "M": m},
    )
