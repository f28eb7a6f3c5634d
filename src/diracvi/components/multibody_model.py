r"""A built multibody system (:class:`MultibodyModel`): the system, its initial state, and
the motion by name — bodies' poses, joint coordinates, the circuit's branch charges, and
an ``xarray.Dataset`` with all of them (``diracvi run``'s NetCDF for a URDF robot).

The orientation is given two ways: the rotation ``R = [d₁ d₂ d₃]`` (body axes → world
axes), exact and free of singularities, and the Tait–Bryan angles (z-y′-x″, the
aerospace yaw, pitch, roll) ``R = R_z(ψ) R_y(θ) R_x(φ)``::

    φ = atan2(R₃₂, R₃₃),   θ = −asin(R₃₁),   ψ = atan2(R₂₁, R₁₁)

for reading (singular at pitch ±90°, where roll and yaw mix; unwrapped along time).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .joints import revolute_angle, slide


def tait_bryan(rot) -> np.ndarray:
    """``(roll φ, pitch θ, yaw ψ)`` of rotations (…, 3, 3), ``R = R_z(ψ) R_y(θ) R_x(φ)``."""
    rot = np.asarray(rot)
    roll = np.arctan2(rot[..., 2, 1], rot[..., 2, 2])
    pitch = -np.arcsin(np.clip(rot[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(rot[..., 1, 0], rot[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


@dataclass(frozen=True)
class MultibodyModel:
    """A built multibody system: the system, its initial state and where each body is.

    Attributes:
        system: the :class:`~diracvi.LagrangeDiracSystem` (monolithic) or
            :class:`~diracvi.InterconnectedSystem` (torn); built with a circuit, the
            :class:`~diracvi.InterconnectedSystem` of those bodies and the circuit.
        q0, p0: initial coordinates and momenta.
        bodies: body name → the slice of its 12 coordinates ``(x, d₁, d₂, d₃)`` in ``q``.
        parts: body name → its :class:`~diracvi.components.RigidBody`.
        joints: joint name → its kind and frames.
    """

    system: object
    q0: np.ndarray
    p0: np.ndarray
    bodies: dict = field(default_factory=dict)
    parts: dict = field(default_factory=dict)
    joints: dict = field(default_factory=dict)
    #: the circuit's :class:`~diracvi.components.network.Assembly` when built with one
    #: (its coordinates follow the bodies' in ``q``, prefixed ``circuit_name + "."``)
    circuit: object = None
    circuit_name: str = ""

    def current_coordinate(self, label: str) -> str:
        """The coordinate (a branch charge) whose velocity is the circuit's ``i(label)``:
        ``traj[model.current_coordinate("R1")]`` is its charge."""
        if self.circuit is None or label not in self.circuit.currents:
            known = [] if self.circuit is None else sorted(self.circuit.currents)
            raise ModelError(f"current_coordinate: no branch {label!r}; the branches are {known}.")
        return f"{self.circuit_name}.{self.circuit.currents[label]}"

    def body(self, q, name: str) -> np.ndarray:
        """The 12 coordinates of body ``name`` in ``q`` (…, n)."""
        return np.asarray(q)[..., self.bodies[name]]

    def rotation(self, q, name: str) -> np.ndarray:
        """The rotation ``R = [d₁ d₂ d₃]`` of body ``name`` at ``q`` (…, 3, 3)."""
        y = self.body(q, name)
        return np.swapaxes(y[..., 3:12].reshape(*y.shape[:-1], 3, 3), -1, -2)

    def point(self, q, frame: str) -> np.ndarray:
        """World position of the frame ``"body.frame"`` at ``q`` (…, 3)."""
        body, local = frame.split(".", 1)
        pt, _ = self.parts[body].frame(local)
        y = self.body(q, body)
        return y[..., 0:3] + np.einsum("...ij,j->...i", self.rotation(q, body), pt)

    def frame_pose(self, q, frame):
        """World ``(r, E)`` of a joint's frame at ``q`` (…, 3) and (…, 3, 3)."""
        if frame.body is None:
            shape = np.shape(q)[:-1]
            return (
                np.broadcast_to(frame.point, (*shape, 3)),
                np.broadcast_to(frame.axes, (*shape, 3, 3)),
            )
        rot = self.rotation(q, frame.body)
        r = self.body(q, frame.body)[..., 0:3] + np.einsum("...ij,j->...i", rot, frame.point)
        return r, rot @ frame.axes

    def joint_position(self, q, name: str) -> np.ndarray:
        """The joint coordinate of joint ``name`` recovered from the bodies' directors at
        ``q`` (…, n): a revolute joint's angle (unwrapped along the first axis of a time
        series, so a continuous joint's turns accumulate), a prismatic or cylindrical
        joint's slide along its axis."""
        if name not in self.joints:
            raise ModelError(
                f"joint_position: no joint {name!r}; the joints are {sorted(self.joints)}."
            )
        conn = self.joints[name]
        (ra, ea), (rb, eb) = self.frame_pose(q, conn.a), self.frame_pose(q, conn.b)
        if conn.kind == "revolute":
            angle = revolute_angle(ea, eb)
            return np.unwrap(angle, axis=0) if np.ndim(angle) else angle
        if conn.kind in ("prismatic", "cylindrical"):
            return slide(ra, ea, rb)
        raise ModelError(
            f"joint_position: joint {name!r} is {conn.kind}; only revolute, prismatic and "
            "cylindrical joints have one joint coordinate."
        )

    def coordinate_joints(self) -> tuple[str, ...]:
        """The joints with one joint coordinate (revolute, prismatic, cylindrical), in the
        order they were added."""
        kinds = ("revolute", "prismatic", "cylindrical")
        return tuple(n for n, c in self.joints.items() if c.kind in kinds)

    def dataset(self, traj):
        """The trajectory's ``xarray.Dataset`` with the motion by name: ``joint_position``
        (time, joint) — a revolute joint's angle in rad, a prismatic or cylindrical
        joint's slide in m, as :meth:`joint_position` recovers them —, ``body_position``
        (time, body, xyz) the body origin in world axes, and ``body_orientation`` (time,
        body, row, col) the rotation ``R = [d₁ d₂ d₃]`` taking body axes to world axes,
        ``body_angles`` (time, body, angle) its roll, pitch, yaw in rad (:func:`tait_bryan`,
        roll and yaw unwrapped along time); with a circuit, ``current`` (step, branch) the
        branch currents ``Δq/Δt`` between saved states (each step's, when every step is
        saved)."""
        if traj.q is None:
            raise ModelError(
                "dataset: the trajectory keeps no states (saved with keep_states=False); "
                "simulate with the states kept to name the motion."
            )
        ds = traj.to_xarray()
        names = list(self.bodies)
        joints = list(self.coordinate_joints())
        ds.coords["body"] = names
        ds.coords["xyz"] = ["x", "y", "z"]
        ds["body_position"] = (
            ("time", "body", "xyz"),
            np.stack([self.body(traj.q, b)[:, 0:3] for b in names], axis=1),
        )
        ds["body_orientation"] = (
            ("time", "body", "row", "col"),
            np.stack([self.rotation(traj.q, b) for b in names], axis=1),
        )
        ds["body_orientation"].attrs["description"] = "R = [d1 d2 d3]: body axes -> world axes"
        angles = tait_bryan(ds["body_orientation"].values)
        angles[..., 0::2] = np.unwrap(angles[..., 0::2], axis=0)  # roll, yaw: turns add up
        ds.coords["angle"] = ["roll", "pitch", "yaw"]
        ds["body_angles"] = (("time", "body", "angle"), angles)
        ds["body_angles"].attrs["description"] = (
            "Tait-Bryan z-y'-x'' angles: R = Rz(yaw) Ry(pitch) Rx(roll), rad"
        )
        if self.circuit is not None and ds.sizes.get("step") == len(traj.t) - 1:
            labels = sorted(self.circuit.currents)
            h = np.diff(np.asarray(traj.t))[:, None]
            charges = np.stack([traj[self.current_coordinate(b)] for b in labels], axis=1)
            ds.coords["branch"] = labels
            ds["current"] = (("step", "branch"), np.diff(charges, axis=0) / h)
        if joints:
            ds.coords["joint"] = joints
            ds["joint_position"] = (
                ("time", "joint"),
                np.stack([self.joint_position(traj.q, j) for j in joints], axis=1),
            )
            ds["joint_kind"] = (("joint",), [self.joints[j].kind for j in joints])
        return ds


__all__ = ["MultibodyModel", "tait_bryan"]
