r"""URDF input: a robot's links and joints as rigid bodies and joints of a :class:`Multibody`.

A URDF link is a body frame; its ``<inertial>`` gives the mass ``m``, the centre of mass
``c`` (the inertial origin's ``xyz``) and the inertia about ``c`` in the inertial frame,
turned by the origin's ``rpy`` into the link frame: ``J_link = R J Rᵀ`` with
``R = R_z(yaw) R_y(pitch) R_x(roll)``. A joint places its child link's frame at
``T_parent · origin · motion(θ)``, ``motion`` a turn by ``θ`` about (or a slide by ``θ``
along) the unit ``axis`` given in the child frame. So each joint becomes two frames with
a common third axis ``â``,

    on the parent (its body):   point  origin.xyz,  axes  R_origin · A
    on the child:               point  0,           axes  A,        A = [b₁ b₂ â] ∈ SO(3)

joined by a ``"revolute"`` (``revolute``, ``continuous``), ``"prismatic"`` or ``"fixed"``
joint of :mod:`~diracvi.components.joints`; their relative turn about ``â`` is the URDF
joint angle (:func:`~diracvi.components.joints.revolute_angle`). A ``floating`` joint
constrains nothing. Links that cannot move on their own are not bodies: the root link
(fixed base: it *is* the world, as in MuJoCo), and any link hung by a ``fixed`` joint that
is massless or fixed to the world becomes a named frame of the body (or world) carrying
it. Limits, ``<dynamics>``, ``<mimic>``, ``<calibration>`` and ``<safety_controller>``
are ignored, each with a note; geometry (visual, collision) is not read.

The parser is the standard library's :mod:`xml.etree.ElementTree` (see the README's
dependency list for why no PyPI parser); its expat rejects entity expansion attacks.
"""

from __future__ import annotations

import os
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from .multibody import WORLD, Multibody
from .rigid_body import RigidBody

#: URDF joint type → the joint kind of :mod:`~diracvi.components.joints` (None: no rows)
KINDS = {
    "revolute": "revolute",
    "continuous": "revolute",
    "prismatic": "prismatic",
    "fixed": "fixed",
    "floating": None,
}
#: MuJoCo's default gravity (its ``<option gravity>``)
GRAVITY = (0.0, 0.0, -9.81)
#: elements of a joint that diracvi reads no physics from, each reported once as a note
IGNORED = ("limit", "dynamics", "mimic", "calibration", "safety_controller")


@dataclass(frozen=True)
class Link:
    """A URDF link: mass, centre of mass and inertia about it in the link frame (None:
    no ``<inertial>`` or zero mass)."""

    name: str
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray | None = None


@dataclass(frozen=True)
class Joint:
    """A URDF joint: ``T_parent→child(θ) = origin · motion(θ)`` about/along ``axis``."""

    name: str
    type: str
    parent: str
    child: str
    xyz: np.ndarray
    rotation: np.ndarray  # the origin's rpy as a matrix
    axis: np.ndarray  # unit, in the child frame


@dataclass(frozen=True)
class Urdf:
    """A parsed URDF: links, joints in tree order from the root, and notes on what was
    ignored."""

    name: str
    root: str
    links: dict
    joints: tuple
    notes: tuple


def rpy_matrix(rpy) -> np.ndarray:
    """URDF's fixed-axis roll–pitch–yaw: ``R = R_z(y) R_y(p) R_x(r)``."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def axis_frame(axis) -> np.ndarray:
    """A rotation ``A = [b₁ b₂ â]`` whose third column is the unit ``axis``."""
    a = np.asarray(axis, dtype=np.float64)
    helper = np.eye(3)[int(np.argmin(np.abs(a)))]  # the basis vector least along â
    b1 = helper - (helper @ a) * a
    b1 /= np.linalg.norm(b1)
    return np.column_stack([b1, np.cross(a, b1), a])


def _turn(axis, angle) -> np.ndarray:
    """Rodrigues: the turn by ``angle`` about the unit ``axis``."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * k @ k


# -- parsing ------------------------------------------------------------------------------
def _numbers(where: str, element, attr: str, default: str, count: int) -> np.ndarray:
    text = default if element is None else element.get(attr, default)
    try:
        out = np.array([float(x) for x in text.split()])
    except ValueError:
        out = np.array([])
    if out.shape != (count,) or not np.all(np.isfinite(out)):
        raise ModelError(
            f"URDF {where}: {attr}={text!r} is not {count} finite numbers; write e.g. "
            f'{attr}="{default}".'
        )
    return out


def _origin(where: str, element):
    origin = None if element is None else element.find("origin")
    xyz = _numbers(f"{where} <origin>", origin, "xyz", "0 0 0", 3)
    rpy = _numbers(f"{where} <origin>", origin, "rpy", "0 0 0", 3)
    return xyz, rpy_matrix(rpy)


def _link(element) -> Link:
    name = element.get("name")
    where = f"link {name!r}"
    inertial = element.find("inertial")
    if inertial is None:
        return Link(name)
    mass_el = inertial.find("mass")
    if mass_el is None:
        raise ModelError(f'URDF {where}: <inertial> has no <mass value="…"/>; add one.')
    mass = float(_numbers(f"{where} <mass>", mass_el, "value", "1", 1)[0])
    if mass < 0.0:
        raise ModelError(f"URDF {where}: mass {mass} is negative; give a mass ≥ 0.")
    inertia_el = inertial.find("inertia")
    if inertia_el is None:
        raise ModelError(
            f'URDF {where}: <inertial> has no <inertia ixx="…" … izz="…"/>; add its six entries.'
        )
    entries = {
        k: float(_numbers(f"{where} <inertia>", inertia_el, k, "0", 1)[0])
        for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    }
    j = np.array(
        [
            [entries["ixx"], entries["ixy"], entries["ixz"]],
            [entries["ixy"], entries["iyy"], entries["iyz"]],
            [entries["ixz"], entries["iyz"], entries["izz"]],
        ]
    )
    xyz, rot = _origin(where + " <inertial>", inertial)
    return Link(name, mass, xyz, rot @ j @ rot.T)


def _joint(element, links: dict, notes: list) -> Joint:
    name, kind = element.get("name"), element.get("type")
    where = f"joint {name!r}"
    if kind not in KINDS:
        raise ModelError(
            f"URDF {where}: type={kind!r} is not supported; diracvi reads "
            f"{sorted(KINDS)} (a planar joint can be written as two prismatic joints and a "
            "revolute one through massive intermediate links)."
        )
    ends = []
    for tag in ("parent", "child"):
        el = element.find(tag)
        ref = None if el is None else el.get("link")
        if ref not in links:
            raise ModelError(
                f'URDF {where}: <{tag} link="{ref}"/> names no link; the links are {sorted(links)}.'
            )
        ends.append(ref)
    xyz, rot = _origin(where, element)
    axis = _numbers(f"{where} <axis>", element.find("axis"), "xyz", "1 0 0", 3)
    norm = np.linalg.norm(axis)
    if norm == 0.0 and KINDS[kind] in ("revolute", "prismatic"):
        raise ModelError(f"URDF {where}: <axis xyz> is the zero vector; give its direction.")
    for tag in IGNORED:
        if element.find(tag) is not None:
            notes.append(f"joint {name!r}: <{tag}> ignored")
    return Joint(name, kind, ends[0], ends[1], xyz, rot, axis / (norm if norm else 1.0))


def parse_urdf(source) -> Urdf:
    """A URDF file (a path) or its text into :class:`Urdf`, or a :class:`ModelError` that
    names the link or joint at fault and the fix."""
    text = str(source)
    try:
        if text.lstrip().startswith("<"):
            root_el = ET.fromstring(text)
        else:
            root_el = ET.parse(os.fspath(source)).getroot()
    except ET.ParseError as err:
        raise ModelError(f"URDF {text[:60]!r}: not well-formed XML ({err}).") from None
    except OSError as err:
        raise ModelError(f"URDF file {text!r} cannot be read ({err.strerror}).") from None
    if root_el.tag != "robot":
        raise ModelError(f"URDF: the top element is <{root_el.tag}>; a URDF's is <robot>.")
    links = {}
    for el in root_el.findall("link"):
        name = el.get("name")
        if not name or "." in name or name == WORLD:
            raise ModelError(
                f"URDF link name {name!r}: give every link a name without '.' other than "
                f"{WORLD!r} (diracvi names frames 'link.frame')."
            )
        if name in links:
            raise ModelError(f"URDF link {name!r} is defined twice; rename one.")
        links[name] = _link(el)
    if not links:
        raise ModelError("URDF: the robot has no <link>.")
    notes: list[str] = []
    joints = [_joint(el, links, notes) for el in root_el.findall("joint")]
    names = [j.name for j in joints]
    for name in names:
        if not name or "." in name or names.count(name) > 1:
            raise ModelError(f"URDF joint name {name!r}: give each joint its own name, no '.'.")
    parent_of = {}
    for j in joints:
        if j.child in parent_of:
            raise ModelError(
                f"URDF link {j.child!r} is the child of joints {parent_of[j.child]!r} and "
                f"{j.name!r}; a URDF is a tree (close loops with Multibody.joint after reading)."
            )
        parent_of[j.child] = j.name
    roots = [name for name in links if name not in parent_of]
    if len(roots) != 1:
        raise ModelError(
            f"URDF: links {roots} have no parent joint; a URDF has exactly one root link "
            "(join the others to the tree, or there is a cycle)."
        )
    ordered, frontier = [], [roots[0]]
    while frontier:  # breadth first from the root: parents before children
        parent = frontier.pop(0)
        for j in joints:
            if j.parent == parent:
                ordered.append(j)
                frontier.append(j.child)
    if len(ordered) != len(joints):
        loose = sorted({j.name for j in joints} - {j.name for j in ordered})
        raise ModelError(f"URDF joints {loose} are not reached from the root: a cycle.")
    return Urdf(root_el.get("name", "robot"), roots[0], links, tuple(ordered), tuple(notes))


# -- building ------------------------------------------------------------------------------
def _joint_values(where: str, arg: str, values, joints) -> dict:
    values = dict(values or {})
    movable = {j.name for j in joints if KINDS[j.type] in ("revolute", "prismatic")}
    for key, value in values.items():
        if key not in movable:
            raise ModelError(
                f"{where}: {arg}[{key!r}] names no revolute, continuous or prismatic joint; "
                f"those are {sorted(movable)}."
            )
        if not np.isfinite(float(value)):
            raise ModelError(f"{where}: {arg}[{key!r}]={value!r} is not finite.")
    return {k: float(v) for k, v in values.items()}


def read_urdf(
    source,
    positions=None,
    rates=None,
    *,
    gravity=GRAVITY,
    fixed_base: bool = True,
    quiet: bool = False,
) -> Multibody:
    """A URDF robot as a :class:`Multibody` (bodies named by link, joints by joint).

    Args:
        source: a URDF file path, or the XML text.
        positions: ``{joint: angle or displacement}`` of the initial pose (default 0).
        rates: ``{joint: its rate}`` of the initial velocity (default 0).
        gravity: the gravitational acceleration (world axes), MuJoCo's default.
        fixed_base: the root link is the world (True, as MuJoCo reads a URDF) or a free body.
        quiet: no warning listing the ignored elements (limits, dynamics, …).

    Returns:
        The :class:`Multibody` placed at the pose; ``.build()`` gives the model, whose
        :meth:`~diracvi.components.multibody.MultibodyModel.joint_position` recovers the
        joint angles from the bodies' directors. ``mb.urdf`` keeps the parsed file.
    """
    robot = parse_urdf(source)
    where = f"read_urdf({robot.name!r})"
    pos = _joint_values(where, "positions", positions, robot.joints)
    vel = _joint_values(where, "rates", rates, robot.joints)
    links = robot.links
    # carrier[link] = (body or WORLD, rotation and point of the link frame in that body)
    carrier = {robot.root: (WORLD, np.eye(3), np.zeros(3))} if fixed_base else {}
    pose = {robot.root: (np.eye(3), np.zeros(3), np.zeros(3), np.zeros(3))}  # R, x, ω, ẋ
    bodies = {} if fixed_base else {robot.root: []}
    frames: dict[str, dict] = {robot.root: {}} if not fixed_base else {}
    connectors = []
    for j in robot.joints:
        body, r_in, x_in = carrier.get(j.parent, (j.parent, np.eye(3), np.zeros(3)))
        kind, link = KINDS[j.type], links[j.child]
        r_p, x_p, w_p, v_p = pose[j.parent]
        r_joint, x_joint = r_p @ j.rotation, x_p + r_p @ j.xyz  # the joint frame, world
        theta, rate = pos.get(j.name, 0.0), vel.get(j.name, 0.0)
        axis_w = r_joint @ j.axis
        r_c, x_c = r_joint, x_joint
        w_c, v_c = w_p, v_p + np.cross(w_p, x_joint - x_p)
        if kind == "revolute":
            r_c, w_c = r_joint @ _turn(j.axis, theta), w_p + rate * axis_w
        elif kind == "prismatic":
            x_c = x_joint + theta * axis_w
            v_c = v_p + np.cross(w_p, x_c - x_p) + rate * axis_w
        pose[j.child] = (r_c, x_c, w_c, v_c)
        if kind == "fixed" and (link.mass == 0.0 or body == WORLD):
            # rigidly carried: a frame of the carrying body (or of the world), not a body
            carrier[j.child] = (body, r_in @ j.rotation, x_in + r_in @ j.xyz)
            frames.setdefault(body, {})[j.child] = carrier[j.child][1:]
            continue
        if link.mass == 0.0:
            raise ModelError(
                f"URDF link {j.child!r} has no mass but joint {j.name!r} ({j.type}) moves "
                "it; give the link an <inertial> with mass and inertia, or attach it by a "
                "fixed joint."
            )
        bodies[j.child] = []
        if kind is None:  # floating: no rows
            continue
        a = axis_frame(j.axis)
        if j.name in links:
            raise ModelError(
                f"URDF joint {j.name!r} has the name of a link; rename one (both become "
                "frames named 'body.name')."
            )
        frames.setdefault(body, {})[j.name] = (r_in @ j.rotation @ a, x_in + r_in @ j.xyz)
        frames.setdefault(j.child, {})[j.name] = (a, np.zeros(3))
        connectors.append((kind, body, j.child, j.name))
    mb = Multibody(robot.name)
    for name in bodies:
        link = links[name]
        if link.mass == 0.0:
            raise ModelError(
                f"URDF link {name!r} (the root of a floating base) has no mass; give it an "
                "<inertial>, or read the robot with fixed_base=True."
            )
        local = {k: (np.asarray(v[1]), np.asarray(v[0])) for k, v in frames.get(name, {}).items()}
        try:
            body = RigidBody(
                link.mass, link.inertia, name=name, com=link.com, frames=local, gravity=gravity
            )
        except ModelError as err:
            raise ModelError(
                f"URDF link {name!r}: {err} Fix the link's <inertial> (a point mass needs "
                "small positive moments of inertia)."
            ) from None
        r, x, w, v = pose[name]
        mb.add(body, position=x, orientation=r, velocity=v, omega=w)
    for name, (rot, point) in frames.get(WORLD, {}).items():
        mb.world_frame(name, point, rot)
    for kind, parent, child, name in connectors:
        a = f"{WORLD}.{name}" if parent == WORLD else f"{parent}.{name}"
        mb.joint(kind, a, f"{child}.{name}", name=name)
    mb.urdf = robot
    if robot.notes and not quiet:
        warnings.warn(
            f"{where}: " + "; ".join(robot.notes) + " (diracvi models no joint limits, "
            "friction or coupling; pass quiet=True to silence this note).",
            stacklevel=2,
        )
    return mb


__all__ = ["GRAVITY", "KINDS", "Joint", "Link", "Urdf", "axis_frame", "parse_urdf", "read_urdf"]
