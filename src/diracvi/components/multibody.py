r"""Rigid bodies joined at frames: one monolithic system, or one subsystem per body.

:class:`Multibody` collects :class:`~diracvi.components.RigidBody` parts with their
initial poses, joints between frames (:mod:`~diracvi.components.joints`) and
spring–dampers between points, and builds

- ``torn=False``: one :class:`~diracvi.LagrangeDiracSystem` on all bodies' coordinates,
  ``L = Σ Lᵇ + Σ Lˢ``, holonomic rows = every body's orthonormality, then every joint's
  rows;
- ``torn=True``: an :class:`~diracvi.InterconnectedSystem` with one subsystem per body
  (its own orthonormality rows) and one per joint or spring, whose coordinates are
  massless copies of the bodies' it touches, joined by :func:`~diracvi.connect`. The
  connections are constant one-forms ``dq_body − dq_copy``, which a step keeps exactly
  at position level, so a joint's rows still hold at every step end.

Both describe the same motion (the interconnection theorem), which the tests check to
round-off. A spring–damper between points ``r_a``, ``r_b`` (``ℓ = |r_b − r_a|``,
``u = (r_b − r_a)/ℓ``) adds ``Lˢ = −½ k (ℓ − ℓ₀)²`` and the force ``c u·(ṙ_b − ṙ_a)``
pulling the points together along ``u``. A motor across a revolute joint
(:meth:`Multibody.motor`, :mod:`~diracvi.components.spatial_motor`) is a part of a
:class:`~diracvi.components.Circuit`; ``build(circuit=…)`` joins the two systems.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from ..errors import ModelError
from ..model.interaction import connect
from ..model.interconnect import interconnect
from ..model.system import LagrangeDiracSystem
from ._gram import gram_rows
from ._part import finite
from .joints import joint_rows
from .multibody_model import MultibodyModel
from .rigid_body import (
    COORDS,
    ORTHONORMALITY,
    RigidBody,
    directors,
    rotation,
    vector,
)
from .rolling import check_contact, contact_rows, rolling_forms
from .spatial_motor import MotorLink, join_circuit, motor_part

WORLD = "world"
#: a joint's rows must vanish at the initial poses to this (absolute) tolerance
TOLERANCE = 1e-9


@dataclass(frozen=True)
class _Frame:
    body: str | None  # None for a world frame
    point: np.ndarray
    axes: np.ndarray


@dataclass(frozen=True)
class _Connector:
    """A joint or a spring–damper between frames a and b (b may be a world frame)."""

    name: str
    a: _Frame
    b: _Frame
    kind: str  # a joint kind, or "spring"
    params: tuple = ()

    @property
    def bodies(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(f.body for f in (self.a, self.b) if f.body is not None))


def _pose(frame: _Frame, q):
    """World ``(r, E)`` of ``frame`` on a body with coordinates ``q`` (or constant)."""
    if frame.body is None:
        return jnp.asarray(frame.point), jnp.asarray(frame.axes)
    r = directors(q)
    return q[0:3] + r @ jnp.asarray(frame.point), r @ jnp.asarray(frame.axes)


def _rates(frame: _Frame, q, v):
    """World velocity of the frame's point (``ẋ + Ṙ X``)."""
    if frame.body is None:
        return jnp.zeros(3)
    return v[0:3] + directors(v) @ jnp.asarray(frame.point)


class _Ends:
    """The coordinates a connector sees: ``{body: (q_body, v_body)}`` from a vector."""

    def __init__(self, layout: dict):
        self.layout = layout  # body -> start index

    def __call__(self, conn: _Connector, x):
        return {b: x[self.layout[b] : self.layout[b] + 12] for b in conn.bodies}


def _holonomic(conn: _Connector):
    """``(rows(r_a, E_a, r_b, E_b), names)`` of a joint or of a rolling contact."""
    if conn.kind == "rolling":
        shape, radius, upright = conn.params
        return contact_rows(shape, radius, upright)
    return joint_rows(conn.kind)


def _forms(conn: _Connector, q):
    """A rolling contact's two one-forms on its body's 12 coordinates ``q``."""
    shape, radius, _ = conn.params
    return rolling_forms(shape, radius, conn.a.point, conn.a.axes, q, jnp.asarray(conn.b.axes))


def _rows(conn: _Connector, qs: dict):
    fn, _ = _holonomic(conn)
    ra, ea = _pose(conn.a, qs.get(conn.a.body))
    rb, eb = _pose(conn.b, qs.get(conn.b.body))
    return fn(ra, ea, rb, eb)


def _spring_energy(conn: _Connector, qs: dict):
    k, rest, _ = conn.params
    ra, _ = _pose(conn.a, qs.get(conn.a.body))
    rb, _ = _pose(conn.b, qs.get(conn.b.body))
    length = jnp.sqrt(jnp.sum((rb - ra) ** 2))
    return -0.5 * k * (length - rest) ** 2


def _damper_forces(conn: _Connector, qs: dict, vs: dict) -> dict:
    r"""``{body: covector}`` of the damper force ``−c u (u·(ṙ_b − ṙ_a))`` on b (and its
    opposite on a), each mapped through its point ``(f, X₁ f, X₂ f, X₃ f)``."""
    _, _, c = conn.params
    ra, _ = _pose(conn.a, qs.get(conn.a.body))
    rb, _ = _pose(conn.b, qs.get(conn.b.body))
    u = (rb - ra) / jnp.sqrt(jnp.sum((rb - ra) ** 2))
    rel = _rates(conn.b, qs.get(conn.b.body), vs.get(conn.b.body)) - _rates(
        conn.a, qs.get(conn.a.body), vs.get(conn.a.body)
    )
    f = -c * (u @ rel) * u  # on b
    out = {}
    for frame, sign in ((conn.a, -1.0), (conn.b, 1.0)):
        if frame.body is not None:
            cov = jnp.concatenate([f, (jnp.asarray(frame.point)[:, None] * f[None, :]).reshape(9)])
            out[frame.body] = out.get(frame.body, 0.0) + sign * cov
    return out


class Multibody:
    """Rigid bodies, the joints between their frames and spring–dampers.

    ``mb.add(body, position=…, orientation=…, velocity=…, omega=…)`` places a body;
    ``mb.joint("revolute", "arm.tip", "link.base")`` joins two frames (``"world"`` or a
    world frame of :meth:`world_frame` for the ground); :meth:`spring` adds a
    spring–damper; :meth:`build` gives a :class:`MultibodyModel`.
    """

    def __init__(self, name: str = "multibody"):
        self.name = str(name)
        self._bodies: dict[str, RigidBody] = {}
        self._states: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._world = {WORLD: _Frame(None, np.zeros(3), np.eye(3))}
        self._connectors: list[_Connector] = []
        self._motors: dict[str, MotorLink] = {}

    def add(
        self, body: RigidBody, position=(0.0, 0.0, 0.0), orientation=None, velocity=None, omega=None
    ) -> RigidBody:
        """Place ``body`` at ``position``, turned by ``orientation`` (a rotation matrix),
        moving with reference-point ``velocity`` and world angular velocity ``omega``."""
        if not isinstance(body, RigidBody):
            raise ModelError(f"Multibody.add: {body!r} is not a RigidBody.")
        if body.name in self._bodies or body.name == WORLD:
            raise ModelError(
                f"Multibody.add: the name {body.name!r} is taken; give each body its own name."
            )
        self._bodies[body.name] = body
        self._states[body.name] = body.state(position, orientation, velocity, omega)
        return body

    def world_frame(self, name: str, point=(0.0, 0.0, 0.0), axes=None) -> str:
        """A frame fixed in the world, ``"world.<name>"`` (``axes`` a rotation, default I)."""
        where = f"Multibody.world_frame({name!r})"
        rot = np.eye(3) if axes is None else rotation(where, "axes", axes)
        key = f"{WORLD}.{name}"
        self._world[key] = _Frame(None, vector(where, "point", point), rot)
        return key

    def _frame(self, ref: str, where: str) -> _Frame:
        if ref in self._world:
            return self._world[ref]
        body, _, local = str(ref).partition(".")
        if body not in self._bodies:
            raise ModelError(
                f"{where}: {ref!r} names no body or world frame; bodies are "
                f"{sorted(self._bodies)}, world frames {sorted(self._world)} "
                "(name a body frame as 'body.frame')."
            )
        pt, axes = self._bodies[body].frame(local or "origin")
        return _Frame(body, pt, axes)

    def joint(self, kind: str, a: str, b: str, name: str | None = None) -> str:
        """Join frame ``a`` to frame ``b`` by a joint ``kind`` (see
        :mod:`~diracvi.components.joints`); returns the joint's name."""
        name = name or f"{kind}{len(self._connectors)}"
        where = f"Multibody.joint({kind!r}, {a!r}, {b!r})"
        joint_rows(kind)
        fa, fb = self._frame(a, where), self._frame(b, where)
        if fa.body is None and fb.body is None:
            raise ModelError(f"{where}: both frames are fixed in the world; join a body.")
        if fa.body == fb.body:
            raise ModelError(f"{where}: both frames are on body {fa.body!r}.")
        self._connectors.append(_Connector(name, fa, fb, kind))
        return name

    def motor(self, constant, joint: str, name: str | None = None, inertia=0.0):
        r"""A DC motor's coupling across the revolute joint ``joint`` (its frame a the
        stator, b the rotor): back-emf ``K e₃·(ω_b − ω_a)`` between pins ``p`` and ``n``,
        torque ``K i e₃`` on b and ``−K i e₃`` on a (:mod:`~.spatial_motor`); ``inertia``
        is the rotor's moment ``J_m`` about the shaft (kg m², default 0), added to the
        joint's. Returns the part: add it to a :class:`~diracvi.components.Circuit` and
        pass that circuit to :meth:`build`."""
        name = name or f"motor{len(self._motors)}"
        conn = next((c for c in self._connectors if c.name == joint), None)
        if conn is None or conn.kind != "revolute":
            revolute = [c.name for c in self._connectors if c.kind == "revolute"]
            raise ModelError(
                f"Multibody.motor({name!r}): joint={joint!r} is not a revolute joint of "
                f"{self.name!r}; its revolute joints are {revolute}."
            )
        if name in self._motors:
            raise ModelError(f"Multibody.motor: a motor named {name!r} exists already.")
        link = MotorLink(joint, conn.a, conn.b)
        part = motor_part(constant, link, self._states, name, inertia)
        self._motors[name] = link
        return part

    def rolling(
        self,
        frame: str,
        radius,
        shape: str = "disk",
        plane: str = WORLD,
        upright: bool = False,
        name: str | None = None,
    ) -> str:
        """Rolling without slipping of a disk (axis: the frame's third axis) or a ball
        centred at body frame ``frame`` on the plane through world frame ``plane`` with
        normal its third axis (``"world"``: z = 0, normal +z). ``upright=True`` also keeps
        the disk's axis in the plane (the vertical rolling disk). See
        :mod:`~diracvi.components.rolling`."""
        name = name or f"rolling{len(self._connectors)}"
        where = f"Multibody.rolling({frame!r}, plane={plane!r})"
        rho = check_contact(where, shape, radius, upright)
        fa = self._frame(frame, where)
        if fa.body is None:
            raise ModelError(f"{where}: {frame!r} is a world frame; name a body frame.")
        if plane not in self._world:
            raise ModelError(
                f"{where}: plane={plane!r} is not a world frame; the world frames are "
                f"{sorted(self._world)} (add one with mb.world_frame)."
            )
        self._connectors.append(
            _Connector(name, fa, self._world[plane], "rolling", (shape, rho, bool(upright)))
        )
        return name

    def spring(
        self, a: str, b: str, stiffness, rest_length=0.0, damping=0.0, name: str | None = None
    ) -> str:
        """A spring–damper ``−½ k (ℓ − ℓ₀)²``, damping ``c`` along the line between the
        points of frames ``a`` and ``b`` (``ℓ > 0`` is required: the line has no
        direction when the points meet)."""
        name = name or f"spring{len(self._connectors)}"
        where = f"Multibody.spring({a!r}, {b!r})"
        k = finite(where, "stiffness", stiffness)
        rest = finite(where, "rest_length", rest_length)
        c = finite(where, "damping", damping)
        if k < 0 or c < 0 or rest < 0:
            raise ModelError(f"{where}: stiffness, rest_length and damping must be ≥ 0.")
        fa, fb = self._frame(a, where), self._frame(b, where)
        self._connectors.append(_Connector(name, fa, fb, "spring", (k, rest, c)))
        return name

    # -- building -------------------------------------------------------------------
    def _initial(self):
        names = list(self._bodies)
        if not names:
            raise ModelError(f"Multibody {self.name!r} has no bodies; add one with mb.add(body).")
        q0 = {b: self._states[b][0] for b in names}
        v0 = {b: self._states[b][1] for b in names}
        bad = []
        for conn in self._connectors:
            if conn.kind == "spring":
                ra = np.asarray(_pose(conn.a, q0.get(conn.a.body))[0])
                rb = np.asarray(_pose(conn.b, q0.get(conn.b.body))[0])
                if np.linalg.norm(rb - ra) == 0.0:
                    bad.append(f"spring {conn.name!r}: its two points coincide (ℓ = 0)")
                continue
            rows = np.asarray(_rows(conn, q0))
            _, labels = _holonomic(conn)
            off = {lab: float(x) for lab, x in zip(labels, rows, strict=True) if abs(x) > TOLERANCE}
            if off:
                bad.append(f"joint {conn.name!r} ({conn.kind}): rows {off} are not 0")
            vel = np.asarray(_joint_rate(conn, q0, v0))
            if conn.kind == "rolling":  # and the contact point's velocity in the plane
                body = conn.a.body
                vel = np.concatenate([vel, np.asarray(_forms(conn, q0[body]) @ v0[body])])
            if np.max(np.abs(vel)) > TOLERANCE * max(
                1.0, np.max(np.abs(np.concatenate(list(v0.values()))))
            ):
                bad.append(
                    f"joint {conn.name!r} ({conn.kind}): the initial velocities violate it "
                    f"(rates {np.round(vel, 12).tolist()})"
                )
        if bad:
            raise ModelError(
                f"Multibody {self.name!r}: the initial state does not satisfy the joints: "
                + "; ".join(bad)
                + ". Fix: place the bodies (mb.add(…, position=, orientation=)) so that "
                "joined frames coincide, and give velocities the joints allow."
            )
        return names, q0, v0

    def build(self, torn: bool = False, circuit=None) -> MultibodyModel:
        """The system and its consistent initial state (see the module docstring);
        with ``circuit`` (a :class:`~diracvi.components.Circuit` holding this
        multibody's motors) the two joined at the motors' copies of the bodies."""
        names, q0, v0 = self._initial()
        model = self._torn(names, q0, v0) if torn else self._monolithic(names, q0, v0)
        if circuit is None:
            if self._motors:
                raise ModelError(
                    f"Multibody {self.name!r} has motors {sorted(self._motors)}: add them to a "
                    "Circuit and build with mb.build(circuit=that_circuit)."
                )
            return model
        return join_circuit(model, self.name, circuit, self._motors)

    def _monolithic(self, names, q0, v0) -> MultibodyModel:
        bodies = self._bodies
        layout = {b: 12 * i for i, b in enumerate(names)}
        ends = _Ends(layout)
        conns = tuple(self._connectors)
        springs = tuple(c for c in conns if c.kind == "spring")
        joints = tuple(c for c in conns if c.kind != "spring")
        loaded = tuple(b for b in names if bodies[b].loads is not None)
        damped = tuple(c for c in springs if c.params[2] > 0.0)

        def lagrangian(q, v):
            total = sum(
                bodies[b].inertial(q[layout[b] : layout[b] + 12], v[layout[b] : layout[b] + 12])
                for b in names
            )
            for conn in springs:
                total = total + _spring_energy(conn, ends(conn, q))
            return total

        def holonomic(q):
            d = q.reshape(len(names), 4, 3)[:, 1:, :]  # every body's directors at once
            rows = [gram_rows(d).reshape(-1)]
            rows += [_rows(conn, ends(conn, q)) for conn in joints]
            return jnp.concatenate(rows)

        def force(q, v, t):
            out = jnp.zeros_like(q)
            for b in loaded:
                s = slice(layout[b], layout[b] + 12)
                out = out.at[s].add(bodies[b].loads(q[s], v[s], t))
            for conn in damped:
                for b, cov in _damper_forces(conn, ends(conn, q), ends(conn, v)).items():
                    out = out.at[layout[b] : layout[b] + 12].add(cov)
            return out

        hol_names = [f"{b}.{r}" for b in names for r in ORTHONORMALITY]
        hol_names += [f"{c.name}.{r}" for c in joints for r in _holonomic(c)[1]]
        rolls = tuple(c for c in joints if c.kind == "rolling")
        n = 12 * len(names)

        def constraints(q):
            rows = jnp.zeros((2 * len(rolls), n))
            for i, conn in enumerate(rolls):
                s = layout[conn.a.body]
                rows = rows.at[2 * i : 2 * i + 2, s : s + 12].set(_forms(conn, q[s : s + 12]))
            return rows

        system = LagrangeDiracSystem(
            tuple(f"{b}.{c}" for b in names for c in COORDS),
            lagrangian,
            force=force if (loaded or damped) else None,
            holonomic=holonomic,
            holonomic_names=tuple(hol_names),
            constraints=constraints if rolls else None,
            constraint_names=tuple(f"{c.name}.roll{i}" for c in rolls for i in (1, 2)) or None,
            name=self.name,
        )
        q = np.concatenate([q0[b] for b in names])
        p = np.concatenate([bodies[b].momenta(v0[b]) for b in names])
        return MultibodyModel(
            system,
            q,
            p,
            {b: slice(layout[b], layout[b] + 12) for b in names},
            dict(bodies),
            self._joints(),
        )

    def _torn(self, names, q0, v0) -> MultibodyModel:
        subsystems = [self._bodies[b] for b in names]
        links, q_parts, p_parts = (
            [],
            [q0[b] for b in names],
            [self._bodies[b].momenta(v0[b]) for b in names],
        )
        for conn in self._connectors:
            sub = _connector_system(conn)
            subsystems.append(sub)
            for b in conn.bodies:
                links += [connect(f"{b}.{c}", f"{conn.name}.{b}_{c}") for c in COORDS]
                q_parts.append(q0[b])
                p_parts.append(np.zeros(12))  # massless copies: ∂L/∂v = 0
        system = interconnect(subsystems, links, name=self.name)
        layout = {b: 12 * i for i, b in enumerate(names)}
        return MultibodyModel(
            system,
            np.concatenate(q_parts),
            np.concatenate(p_parts),
            {b: slice(layout[b], layout[b] + 12) for b in names},
            dict(self._bodies),
            self._joints(),
        )

    def _joints(self) -> dict:
        return {c.name: c for c in self._connectors if c.kind != "spring"}


def _joint_rate(conn: _Connector, q0: dict, v0: dict):
    """``d/dt rows`` at the initial state (a forward-mode derivative)."""
    import jax

    bodies = conn.bodies
    qs = tuple(jnp.asarray(q0[b]) for b in bodies)
    vs = tuple(jnp.asarray(v0[b]) for b in bodies)
    _, rate = jax.jvp(lambda *x: _rows(conn, dict(zip(bodies, x, strict=True))), qs, vs)
    return rate


def _connector_system(conn: _Connector) -> LagrangeDiracSystem:
    """A joint or spring as a subsystem on massless copies of its bodies' coordinates."""
    bodies = conn.bodies
    coords = tuple(f"{b}_{c}" for b in bodies for c in COORDS)

    def split(x):
        return {b: x[12 * i : 12 * i + 12] for i, b in enumerate(bodies)}

    if conn.kind == "spring":
        damped = conn.params[2] > 0.0

        def force(q, v):
            covs = _damper_forces(conn, split(q), split(v))
            return jnp.concatenate([covs.get(b, jnp.zeros(12)) for b in bodies])

        return LagrangeDiracSystem(
            coords,
            lambda q, v: _spring_energy(conn, split(q)) + 0.0 * jnp.sum(v),
            force=force if damped else None,
            name=conn.name,
        )
    rolling = conn.kind == "rolling"
    return LagrangeDiracSystem(
        coords,
        lambda q, v: 0.0 * jnp.sum(v) + 0.0 * jnp.sum(q),
        holonomic=lambda q: _rows(conn, split(q)),
        holonomic_names=_holonomic(conn)[1],
        constraints=(lambda q: _forms(conn, q)) if rolling else None,
        constraint_names=("roll1", "roll2") if rolling else None,
        name=conn.name,
    )


__all__ = ["WORLD", "Multibody", "MultibodyModel"]
