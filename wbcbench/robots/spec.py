"""Plain-data description of a generated humanoid, from which the MJCF text is written.

A humanoid is a floating base body plus serial chains of links. Every link is one body carrying
at most one hinge (one hinge per body keeps MuJoCo and Pinocchio joint-for-joint identical), an
explicit mass and an inertia computed from a simple solid (box or rod), one capsule used as
visual and self-collision proxy, and optional sites and contact boxes.

All body frames are parallel to the world frame in the zero configuration, so a joint axis, an
offset or a box size is written once, in that common orientation. Lengths are in metres, masses in
kilograms, angles in radians, torques in N·m, velocities in rad/s.

A chain is an ordered list of links that hang one inside the other; arms of different lengths are
just different lists, which is how a DoF-scaled family is built from one torso.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal, NamedTuple

import numpy as np

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]  # (w, x, y, z), MuJoCo order

IDENTITY: Quat = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class JointSpec:
    """A hinge at the origin of its link's body.

    Attributes:
        name: joint name, also the name of its motor, e.g. ``"L_Knee"``.
        axis: unit rotation axis in the body frame (= world frame at zero configuration).
        range: (lower, upper) position limits [rad].
        torque: symmetric torque limit [N·m].
        velocity: symmetric velocity limit [rad/s] (metadata only: MJCF has no such field).
        armature: reflected rotor inertia about the axis [kg·m²].
        damping: viscous joint damping [N·m·s/rad].
        frictionloss: dry (Coulomb) joint friction [N·m].
    """

    name: str
    axis: Vec3
    range: tuple[float, float]
    torque: float
    velocity: float
    armature: float = 0.0
    damping: float = 0.0
    frictionloss: float = 0.0


@dataclass(frozen=True)
class Box:
    """Solid axis-aligned box used for a link's inertia.

    Attributes:
        center: box centre (= the link's centre of mass) in the body frame [m].
        size: full edge lengths along x, y, z [m], all > 0.
    """

    center: Vec3
    size: Vec3


@dataclass(frozen=True)
class Rod:
    """Solid cylinder from ``start`` to ``end`` (body frame) of radius ``radius`` [m].

    As an inertia shape its centre of mass is the midpoint; as a capsule it is the capsule's axis.
    """

    start: Vec3
    end: Vec3
    radius: float


@dataclass(frozen=True)
class SiteSpec:
    """A named frame rigidly attached to a body (becomes a Pinocchio ``OP_FRAME``)."""

    name: str
    pos: Vec3
    quat: Quat = IDENTITY


ContactKind = Literal["foot", "palm"]


@dataclass(frozen=True)
class ContactBoxSpec:
    """A collision box: ``"foot"`` boxes touch the floor, ``"palm"`` boxes touch the wall.

    Attributes:
        name: geom name.
        center: box centre in the body frame [m].
        half: half edge lengths [m] (MuJoCo ``size``).
        kind: which environment geoms it collides with.
        quat: box orientation in the body frame (w, x, y, z).
    """

    name: str
    center: Vec3
    half: Vec3
    kind: ContactKind
    quat: Quat = IDENTITY


@dataclass(frozen=True)
class LinkSpec:
    """One body: where it sits on its parent, its joint, its mass properties and attachments.

    Attributes:
        body: body name.
        pos: body origin in the parent body frame [m]; also the joint's origin.
        joint: the hinge, or ``None`` for a body welded to its parent.
        mass: link mass [kg].
        shape: solid whose uniform-density inertia stands for the link's.
        capsule: visual / self-collision capsule; ``None`` uses ``shape`` when it is a ``Rod``.
        sites: frames attached to the body.
        boxes: collision boxes attached to the body.
    """

    body: str
    pos: Vec3
    joint: JointSpec | None
    mass: float
    shape: Box | Rod
    capsule: Rod | None = None
    sites: tuple[SiteSpec, ...] = ()
    boxes: tuple[ContactBoxSpec, ...] = ()

    @property
    def capsule_rod(self) -> Rod:
        """The capsule actually written: explicit, or the inertia rod."""
        if self.capsule is not None:
            return self.capsule
        if isinstance(self.shape, Rod):
            return self.shape
        raise ValueError(f"link {self.body!r} has a box inertia shape and no capsule")


@dataclass(frozen=True)
class ChainSpec:
    """Serial links attached to body ``parent``: each link is the child of the previous one."""

    parent: str
    links: tuple[LinkSpec, ...]


@dataclass(frozen=True)
class KeyframeSpec:
    """A named posture.

    The base sits at the origin facing +x, at the height that puts the ``stand_on`` sites on the
    floor (z = 0); the generator computes that height from the model's forward kinematics.

    Attributes:
        name: keyframe name.
        joints: (joint name, angle [rad]) pairs; unnamed joints are at 0.
        stand_on: sites that must lie on the floor plane, flat.
    """

    name: str
    joints: tuple[tuple[str, float], ...]
    stand_on: tuple[str, ...] = ("l_sole", "r_sole")


@dataclass(frozen=True)
class WallSpec:
    """A static wall at +y whose inner face touches ``site`` in keyframe ``keyframe``.

    Attributes:
        keyframe: keyframe in which the site touches the wall.
        site: site lying on the wall (its z axis must be −y, the normal into the robot).
        thickness: wall thickness [m].
        half_x, half_z: half extents of the wall along x and z [m].
    """

    keyframe: str
    site: str
    thickness: float = 0.1
    half_x: float = 1.0
    half_z: float = 1.2


class ContactRect(NamedTuple):
    """Flat contact rectangle in its contact frame (sole or palm): x_min, x_max, y_min, y_max [m].

    The contact frame's z axis is the contact normal pointing into the robot.
    """

    x_min: float
    x_max: float
    y_min: float
    y_max: float


@dataclass(frozen=True)
class RobotInfo:
    """Machine-readable facts about a robot that the MJCF does not carry.

    For external models every field is empty or ``None`` unless the user supplies it.

    Attributes:
        contact_frames: default contact frames (sole sites for the generated robots).
        contact_rects: contact rectangle per contact-capable frame (soles, palm), in that frame.
        hand_frames: (left, right) hand tool frames.
        base_body: floating base body.
        torso_body: upper-body body used for orientation tasks.
        head_frame: gaze frame (x forward).
        default_keyframe: keyframe to start scenarios from.
        velocity_limits: joint name → velocity limit [rad/s].
        extra: other named frames (e.g. the palm contact frame).
    """

    contact_frames: tuple[str, ...] = ()
    contact_rects: dict[str, ContactRect] = field(default_factory=dict)
    hand_frames: tuple[str, ...] = ()
    base_body: str | None = None
    torso_body: str | None = None
    head_frame: str | None = None
    default_keyframe: str | None = None
    velocity_limits: dict[str, float] = field(default_factory=dict)
    extra: dict[str, str] = field(default_factory=dict)

    def sole_box(self, frame: str) -> ContactRect | None:
        """Contact rectangle of ``frame`` (sole or palm site), ``None`` when unknown."""
        return self.contact_rects.get(frame)


@dataclass(frozen=True)
class HumanoidSpec:
    """A whole generated humanoid.

    Bodies are written depth first; a body's children are the next link of its own chain first,
    then the chains attached to it in the order of ``chains``. That order is the joint order of
    both MuJoCo and Pinocchio.

    Attributes:
        name: model name and file stem.
        base: the floating base body (its ``joint`` must be ``None``; the free joint is ``root``).
        chains: serial chains, each attached to an already defined body.
        keyframes: named postures; the first one is the default.
        wall: optional static wall.
        info: metadata exposed as ``Robot.info``.
        floor_friction: sliding, torsional, rolling friction of the floor.
    """

    name: str
    base: LinkSpec
    chains: tuple[ChainSpec, ...]
    keyframes: tuple[KeyframeSpec, ...]
    info: RobotInfo
    wall: WallSpec | None = None
    floor_friction: Vec3 = (1.0, 0.005, 0.0001)

    @property
    def links(self) -> tuple[LinkSpec, ...]:
        """Every link, base first, in chain order (not necessarily depth-first)."""
        return (self.base, *(link for chain in self.chains for link in chain.links))

    @property
    def joints(self) -> tuple[JointSpec, ...]:
        """Every hinge, in chain order."""
        return tuple(link.joint for link in self.links if link.joint is not None)

    @property
    def total_mass(self) -> float:
        """Sum of link masses [kg]."""
        return float(sum(link.mass for link in self.links))


# ---------------------------------------------------------------------------------------------
# Mass properties


def inertia_of(shape: Box | Rod, mass: float) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass (3,) [m] and inertia about it (3, 3) [kg·m²] of a uniform solid."""
    if isinstance(shape, Box):
        sx, sy, sz = shape.size
        inertia = (mass / 12.0) * np.diag([sy**2 + sz**2, sx**2 + sz**2, sx**2 + sy**2])
        return np.asarray(shape.center, dtype=float), inertia
    start, end = np.asarray(shape.start, dtype=float), np.asarray(shape.end, dtype=float)
    axis = end - start
    length = float(np.linalg.norm(axis))
    if length < 1e-12:
        raise ValueError("a rod used as inertia shape needs a nonzero length")
    u = axis / length
    r2 = shape.radius**2
    i_axial = 0.5 * mass * r2
    i_perp = mass * (3.0 * r2 + length**2) / 12.0
    # I = i_perp (1 − u uᵀ) + i_axial u uᵀ: the cylinder's tensor in any orientation.
    inertia = i_perp * (np.eye(3) - np.outer(u, u)) + i_axial * np.outer(u, u)
    return 0.5 * (start + end), inertia


# ---------------------------------------------------------------------------------------------
# Left/right mirroring (reflection through the sagittal x–z plane)


def _flip(v: Vec3) -> Vec3:
    return (v[0], -v[1], v[2])


def _flip_quat(q: Quat) -> Quat:
    # Reflecting y maps the rotation (w, x, y, z) to (w, −x, y, −z).
    return (q[0], -q[1], q[2], -q[3])


def _flip_name(name: str, left: str, right: str) -> str:
    return right + name[len(left) :] if name.startswith(left) else name


def mirror_joint(joint: JointSpec, prefix: tuple[str, str] = ("L_", "R_")) -> JointSpec:
    """The right-side twin of a left joint: same axis, range negated for x and z axes.

    A reflection through the x–z plane turns a rotation about x or z into the opposite
    rotation and keeps a rotation about y, so keeping the axis means mirroring the range.
    """
    lo, hi = joint.range
    mirrored_sign = abs(joint.axis[1]) < 0.5
    new_range = (-hi, -lo) if mirrored_sign else (lo, hi)
    return replace(joint, name=_flip_name(joint.name, *prefix), range=new_range)


def _mirror_rod(rod: Rod) -> Rod:
    return Rod(_flip(rod.start), _flip(rod.end), rod.radius)


def mirror_link(
    link: LinkSpec,
    prefix: tuple[str, str] = ("L_", "R_"),
    site_prefix: tuple[str, str] = ("l_", "r_"),
) -> LinkSpec:
    """Right-side twin of a left link (names, positions, shapes, sites, boxes, joint)."""
    shape: Box | Rod
    shape = (
        Box(_flip(link.shape.center), link.shape.size)
        if isinstance(link.shape, Box)
        else _mirror_rod(link.shape)
    )
    return LinkSpec(
        body=_flip_name(link.body, *prefix),
        pos=_flip(link.pos),
        joint=None if link.joint is None else mirror_joint(link.joint, prefix),
        mass=link.mass,
        shape=shape,
        capsule=None if link.capsule is None else _mirror_rod(link.capsule),
        sites=tuple(
            SiteSpec(_flip_name(s.name, *site_prefix), _flip(s.pos), _flip_quat(s.quat))
            for s in link.sites
        ),
        boxes=tuple(
            replace(
                b,
                name=_flip_name(b.name, *site_prefix),
                center=_flip(b.center),
                quat=_flip_quat(b.quat),
            )
            for b in link.boxes
        ),
    )


def mirror_chain(chain: ChainSpec) -> ChainSpec:
    """Right-side twin of a left chain attached to the same parent."""
    return ChainSpec(chain.parent, tuple(mirror_link(link) for link in chain.links))


@dataclass(frozen=True)
class RobotFile:
    """A robot model file and the facts the file does not carry: what a robot plugin (entry
    point group ``wbcbench.robots``) or :func:`wbcbench.register_robot` provides.

    Attributes:
        path: the MJCF (with a free joint) or URDF file.
        info: contact frames and sole sizes, hand, base and torso frames, the keyframe.
        summary: one line for ``wbcbench list``.
        package_dirs: folders holding the packages of the file's ``package://`` paths.
    """

    path: Path
    info: RobotInfo
    summary: str = ""
    package_dirs: tuple[Path, ...] = ()
