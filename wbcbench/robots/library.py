"""The named humanoids: ``tocabi_like`` (33 DoF) and ``comanplus_like`` (28 DoF).

Figures follow the public descriptions of TOCABI and COMAN+ collected in the project's
``robot_specs.md``; where those are silent (link offsets the papers don't give, COMAN+ arm
limits, rotor inertia and friction of COMAN+) the values are plausible choices, marked below.

Every chain is built by a small function returning its links, so a variant with a longer or
shorter arm is another list of links attached to the same torso.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import replace

from wbcbench.robots.spec import (
    Box,
    ChainSpec,
    ContactBoxSpec,
    ContactRect,
    HumanoidSpec,
    JointSpec,
    KeyframeSpec,
    LinkSpec,
    RobotInfo,
    Rod,
    SiteSpec,
    WallSpec,
    mirror_chain,
)

X: tuple[float, float, float] = (1.0, 0.0, 0.0)
Y: tuple[float, float, float] = (0.0, 1.0, 0.0)
Z: tuple[float, float, float] = (0.0, 0.0, 1.0)
ORIGIN: tuple[float, float, float] = (0.0, 0.0, 0.0)

# Site frame whose z axis is the body's +y: the palm normal pointing into the hand.
_Z_ALONG_Y = (math.sqrt(0.5), -math.sqrt(0.5), 0.0, 0.0)


def _rod(end: tuple[float, float, float], radius: float) -> Rod:
    """Rod from the body origin to ``end`` (typically the next joint)."""
    return Rod(ORIGIN, end, radius)


def _link(
    body: str,
    pos: tuple[float, float, float],
    joint: JointSpec | None,
    mass: float,
    shape: Box | Rod,
    capsule: Rod | None = None,
    sites: Sequence[SiteSpec] = (),
    boxes: Sequence[ContactBoxSpec] = (),
) -> LinkSpec:
    return LinkSpec(body, pos, joint, mass, shape, capsule, tuple(sites), tuple(boxes))


def _velocity_limits(chains: Sequence[ChainSpec]) -> dict[str, float]:
    """Velocity limit [rad/s] per joint name."""
    return {
        lk.joint.name: lk.joint.velocity
        for chain in chains
        for lk in chain.links
        if lk.joint is not None
    }


def _bent_legs(pitch_joints: tuple[str, str, str], a: float) -> tuple[tuple[str, float], ...]:
    """Hip pitch, knee, ankle pitch at −a, 2a, −a on both legs: the sole stays parallel to the
    pelvis, so with zero roll and yaw it is flat on the floor."""
    hip, knee, ankle = pitch_joints
    return tuple(
        (f"{side}_{joint}", angle)
        for side in "LR"
        for joint, angle in ((hip, -a), (knee, 2 * a), (ankle, -a))
    )


# =============================================================================================
# TOCABI-like


def _tocabi_leg() -> ChainSpec:
    """Left leg: HipYaw z, HipRoll x, HipPitch y, Knee y, AnklePitch y, AnkleRoll x."""

    def j(name: str, axis: tuple[float, float, float], rng: tuple[float, float], tau: float,
          arm: float, fric: float) -> JointSpec:  # fmt: skip
        return JointSpec(f"L_{name}", axis, rng, tau, 20.0, arm, 0.04, fric)

    sole_z = -0.1585  # sole plane below the ankle axis
    sole_x = 0.03  # sole centre: toe +0.18, heel −0.12 from the ankle axis
    links = (
        _link("L_HipYaw_link", (0.0, 0.1025, 0.0), j("HipYaw", Z, (-0.7, 0.7), 333, 0.614, 8),
              2.68, _rod((0, 0, -0.08), 0.05)),
        _link("L_HipRoll_link", (0.0, 0.0, -0.08), j("HipRoll", X, (-0.4, 0.8), 232, 0.862, 22),
              2.67, Box(ORIGIN, (0.1, 0.08, 0.08)), Rod((-0.05, 0, 0), (0.05, 0, 0), 0.05)),
        _link("L_HipPitch_link", ORIGIN, j("HipPitch", Y, (-1.8, 0.6), 263, 1.0, 22),
              5.37, _rod((0, 0, -0.35), 0.06)),
        _link("L_Knee_link", (0.0, 0.0, -0.35), j("Knee", Y, (0.0, 2.6), 289, 1.0, 22),
              3.88, _rod((0, 0, -0.35), 0.05)),
        _link("L_AnklePitch_link", (0.0, 0.0, -0.35), j("AnklePitch", Y, (-1.2, 0.9), 222, 1.0, 12),
              2.51, Box(ORIGIN, (0.08, 0.08, 0.08)), Rod((0, -0.04, 0), (0, 0.04, 0), 0.045)),
        # Ankle-roll link (1.26 kg) and foot (2.33 kg) are one rigid body here.
        _link("L_AnkleRoll_link", ORIGIN, j("AnkleRoll", X, (-0.6, 0.6), 166, 0.36, 5),
              3.59, Box((sole_x, 0.0, -0.1), (0.3, 0.13, 0.1)),
              Rod((-0.08, 0, -0.115), (0.14, 0, -0.115), 0.04),
              sites=[SiteSpec("l_sole", (sole_x, 0.0, sole_z))],
              boxes=[ContactBoxSpec("l_foot", (sole_x, 0.0, sole_z + 0.01), (0.15, 0.065, 0.01),
                                    "foot")]),
    )  # fmt: skip
    return ChainSpec("pelvis", links)


def _tocabi_waist() -> ChainSpec:
    """Waist1 z (0.198 m above the pelvis), Waist2 y, Upperbody x → ``torso``."""
    vel = {"Waist1": 10.0, "Waist2": 10.0, "Upperbody": 2.0}

    def j(name: str, axis: tuple[float, float, float], rng: tuple[float, float]) -> JointSpec:
        return JointSpec(name, axis, rng, 303, vel[name], 0.078, 0.03, 8)

    links = (
        _link("Waist1_link", (0.0, 0.0, 0.198), j("Waist1", Z, (-0.8, 0.8)),
              0.90, _rod((0, 0, 0.04), 0.06)),
        _link("Waist2_link", (0.0, 0.0, 0.04), j("Waist2", Y, (-0.5, 0.5)),
              3.75, Box(ORIGIN, (0.12, 0.2, 0.08)), Rod((0, -0.08, 0), (0, 0.08, 0), 0.06)),
        _link("torso", ORIGIN, j("Upperbody", X, (-0.35, 0.35)),
              18.13, Box((0.0, 0.0, 0.2), (0.22, 0.32, 0.4)),
              Rod((0, 0, 0.04), (0, 0, 0.34), 0.14)),
    )  # fmt: skip
    return ChainSpec("pelvis", links)


ArmRow = tuple[
    str, tuple[float, float, float], tuple[float, float], float, float, float, float, float, float
]

# Left TOCABI arm in its zero posture: a T-pose along +y (axial joints have a y axis).
# Each entry: name, axis, range [rad], torque [N·m], armature [kg·m²], friction [N·m],
# mass [kg], offset of the NEXT joint along +y [m], capsule radius [m].
TOCABI_ARM: tuple[tuple[str, tuple[float, float, float], tuple[float, float], float, float, float,
                        float, float, float], ...] = (
    ("Shoulder1", Z, (-0.6, 0.6), 64, 0.18, 5, 1.68, 0.10, 0.05),
    ("Shoulder2", Y, (-1.6, 1.6), 64, 0.18, 5, 0.40, 0.04, 0.045),
    ("Shoulder3", X, (-1.9, 1.9), 64, 0.18, 5, 2.90, 0.12, 0.05),
    ("Armlink", Y, (-2.5, 2.5), 64, 0.18, 5, 0.59, 0.13, 0.04),
    ("Elbow", X, (-2.8, 0.3), 23, 0.032, 2, 2.07, 0.10, 0.045),
    ("Forearm", Y, (-2.5, 2.5), 23, 0.032, 2, 0.35, 0.13, 0.035),
    ("Wrist1", X, (-1.5, 1.5), 10, 0.0032, 1.5, 0.71, 0.04, 0.035),
    # Wrist2 link 0.10 kg plus a 0.6 kg hand; its rod is the hand.
    ("Wrist2", Y, (-1.5, 1.5), 10, 0.0032, 1.5, 0.70, 0.12, 0.035),
)  # fmt: skip


def arm_chain(
    rows: Sequence[tuple[str, tuple[float, float, float], tuple[float, float], float, float, float,
                         float, float, float]],
    parent: str,
    shoulder: tuple[float, float, float],
    hand_site: str = "l_hand",
    damping: float = 0.01,
    velocity: float = 5.0,
) -> ChainSpec:  # fmt: skip
    """Left arm along +y from a table of joints (see ``TOCABI_ARM``); any length works.

    The first joint sits at ``shoulder`` on ``parent``; each row's offset places the next joint,
    and the last row's offset is the tool point, where ``hand_site`` goes.
    """
    links = []
    pos = shoulder
    for name, axis, rng, tau, arm, fric, mass, length, radius in rows:
        joint = JointSpec(f"L_{name}", axis, rng, tau, velocity, arm, damping, fric)
        links.append(_link(f"L_{name}_link", pos, joint, mass, _rod((0, length, 0), radius)))
        pos = (0.0, length, 0.0)
    links[-1] = replace(links[-1], sites=(SiteSpec(hand_site, (0.0, pos[1] - 0.02, 0.0)),))
    return ChainSpec(parent, tuple(links))


def _tocabi_neck() -> ChainSpec:
    """Neck z, Head y → ``head`` with the gaze site ``head``."""

    def j(name: str, axis: tuple[float, float, float], rng: tuple[float, float]) -> JointSpec:
        return JointSpec(name, axis, rng, 10, 5.0, 0.0032, 0.003, 1.5)

    links = (
        _link("neck", (0.0, 0.0, 0.37), j("Neck", Z, (-1.2, 1.2)),
              0.25, _rod((0, 0, 0.08), 0.04)),
        _link("head", (0.0, 0.0, 0.08), j("Head", Y, (-0.6, 0.6)),
              1.42, Box((0.02, 0.0, 0.08), (0.2, 0.18, 0.2)), Rod((0, 0, 0.06), (0, 0, 0.09), 0.09),
              sites=[SiteSpec("head", (0.09, 0.0, 0.08))]),
    )  # fmt: skip
    return ChainSpec("torso", links)


def tocabi_like() -> HumanoidSpec:
    """TOCABI-like humanoid, 33 actuated joints (legs 6+6, waist 3, left arm 8, neck 2, right
    arm 8)."""
    return _tocabi("tocabi_like", TOCABI_ARM, TOCABI_ARM)


def _tocabi(name: str, left_arm: Sequence[ArmRow], right_arm: Sequence[ArmRow]) -> HumanoidSpec:
    """TOCABI-like body with the given left and right arm tables (see ``TOCABI_ARM``)."""
    pelvis = _link(
        "pelvis", ORIGIN, None, 12.2, Box((0.0, 0.0, 0.02), (0.18, 0.28, 0.16)),
        Rod((0, -0.09, 0.02), (0, 0.09, 0.02), 0.09),
    )  # fmt: skip
    leg = _tocabi_leg()
    arm = arm_chain(left_arm, "torso", (0.0, 0.154, 0.33))
    right = mirror_chain(arm_chain(right_arm, "torso", (0.0, 0.154, 0.33)))
    chains = (leg, mirror_chain(leg), _tocabi_waist(), arm, _tocabi_neck(), right)
    a = 0.16  # knee half-bend of the standing posture [rad]
    legs = _bent_legs(("HipPitch", "Knee", "AnklePitch"), a)
    # Arms down from the T-pose, 0.2 rad away from the body.
    arms = (("L_Shoulder3", -(math.pi / 2 - 0.2)), ("R_Shoulder3", math.pi / 2 - 0.2))
    # The same stance with the elbows bent 0.4 rad and the arms 0.35 rad from the body (for arms
    # that have an elbow). With straight arms a hand cannot move along its arm: the CoM, pelvis
    # and both hand-pose tasks stacked are nearly singular (smallest singular value ~7e-4 in the
    # contacts' null space; ~2e-2 with the elbows bent).
    arms_bent = (
        ("L_Shoulder3", -(math.pi / 2 - 0.35)), ("R_Shoulder3", math.pi / 2 - 0.35),
        ("L_Elbow", -0.4), ("R_Elbow", 0.4),
    )  # fmt: skip
    # Single support on the left foot: both hip/ankle rolls of -0.172 rad put the CoM over the
    # left sole (within 1 mm laterally); the right leg rolls 0.05 rad outwards and folds by
    # 0.25 rad at hip, knee and ankle, lifting its sole 4 cm, still parallel to the floor.
    s, r, lift = -0.172, -0.05, 0.25
    one_leg = (
        *((j, v) for j, v in legs if not j.startswith("R_")),
        ("L_HipRoll", s), ("L_AnkleRoll", -s), ("R_HipRoll", r), ("R_AnkleRoll", -r),
        ("R_HipPitch", -a - lift), ("R_Knee", 2 * (a + lift)), ("R_AnklePitch", -a - lift),
    )  # fmt: skip
    info = RobotInfo(
        contact_frames=("l_sole", "r_sole"),
        contact_rects={
            "l_sole": ContactRect(-0.15, 0.15, -0.065, 0.065),
            "r_sole": ContactRect(-0.15, 0.15, -0.065, 0.065),
        },
        hand_frames=("l_hand", "r_hand"),
        base_body="pelvis",
        torso_body="torso",
        head_frame="head",
        default_keyframe="stand",
        velocity_limits=_velocity_limits(chains),
    )
    keyframes = [
        KeyframeSpec("stand", legs + arms),
        KeyframeSpec("stand_left", one_leg + arms, stand_on=("l_sole",)),
    ]
    if all(any(row[0] == "Elbow" for row in arm) for arm in (left_arm, right_arm)):
        keyframes.append(KeyframeSpec("stand_arms_bent", legs + arms_bent))
    return HumanoidSpec(
        name=name,
        base=pelvis,
        chains=chains,
        keyframes=tuple(keyframes),
        info=info,
    )


# ---------------------------------------------------------------------------------------------
# DoF-scaled TOCABI-like family (RC-LQP paper §5.3, Fig. 5): only the arms change.

#: rows of ``TOCABI_ARM`` a shorter arm keeps (Shoulder3, which lowers the arm, is in all)
_ARM_SUBSETS: dict[int, tuple[int, ...]] = {
    1: (2,), 2: (2, 4), 3: (0, 2, 4), 4: (0, 1, 2, 4), 5: (0, 1, 2, 4, 6), 6: (0, 1, 2, 3, 4, 6),
    7: (0, 1, 2, 3, 4, 5, 6), 8: tuple(range(8)),
}  # fmt: skip
#: rows of ``TOCABI_ARM`` a longer arm splits in two, in this order
_ARM_SPLITS = (2, 4, 3, 5, 0, 6, 1)
#: total actuated DoF of the family members (33 is ``tocabi_like`` itself)
TOCABI_DOF_FAMILY = (20, 25, 29, 33, 39, 45)


def tocabi_arm(dof: int) -> tuple[ArmRow, ...]:
    """An arm table of ``dof`` joints (1…15) with the TOCABI arm's mass and reach.

    Shorter arms keep a subset of the TOCABI rows (``_ARM_SUBSETS``); each kept row takes the
    mass and length of the dropped rows after it (and the first one those before it). Longer
    arms split rows in two (``_ARM_SPLITS``): halves of the mass and length, the added joint
    ``<name>b`` about an axis different from both neighbours.
    """
    if not 1 <= dof <= len(TOCABI_ARM) + len(_ARM_SPLITS):
        raise ValueError(f"arm DoF must be 1…{len(TOCABI_ARM) + len(_ARM_SPLITS)}, got {dof}")
    if dof <= len(TOCABI_ARM):
        keep = _ARM_SUBSETS[dof]
        rows = []
        for i, k in enumerate(keep):
            first = 0 if i == 0 else k
            last = keep[i + 1] if i + 1 < len(keep) else len(TOCABI_ARM)
            group = TOCABI_ARM[first:last]
            mass = sum(r[6] for r in group)
            length = sum(r[7] for r in group)
            rows.append((*TOCABI_ARM[k][:6], mass, length, TOCABI_ARM[k][8]))
        return tuple(rows)
    split = set(_ARM_SPLITS[: dof - len(TOCABI_ARM)])
    out: list[ArmRow] = []
    for i, row in enumerate(TOCABI_ARM):
        if i not in split:
            out.append(row)
            continue
        name, axis, rng, tau, arm, fric, mass, length, radius = row
        after = TOCABI_ARM[i + 1][1] if i + 1 < len(TOCABI_ARM) else axis
        extra = next(a for a in (X, Y, Z) if a not in (axis, after))
        out.append((name, axis, rng, tau, arm, fric, mass / 2, length / 2, radius))
        out.append((f"{name}b", extra, rng, tau, arm, fric, mass / 2, length / 2, radius))
    return tuple(out)


def tocabi_dof(total: int) -> HumanoidSpec:
    """TOCABI-like humanoid with ``total`` actuated DoF (legs, waist and neck unchanged: 17 DoF;
    the arms share the rest, the left one taking the odd joint)."""
    arms = total - 17
    return _tocabi(f"tocabi_dof{total}", tocabi_arm((arms + 1) // 2), tocabi_arm(arms // 2))


# =============================================================================================
# COMAN+-like


def _comanplus_leg() -> ChainSpec:
    """Left leg: HipLat x, HipSag y, HipYaw z (mid-thigh), Knee y, AnklePitch y, AnkleRoll x.

    Rotor inertia and friction are not published: plausible values for geared series-elastic
    drives are used.
    """
    d = math.radians

    def j(name: str, axis: tuple[float, float, float], rng: tuple[float, float], tau: float,
          arm: float) -> JointSpec:  # fmt: skip
        return JointSpec(f"L_{name}", axis, rng, tau, 10.0, arm, 0.02, 1.0)

    sole_z = -0.069  # sole plane below the ankle-roll axis
    sole_x = 0.02
    links = (
        _link("L_HipLat_link", (0.0, 0.08, -0.06), j("HipLat", X, (d(-30), d(95)), 200, 0.3),
              2.1, Box(ORIGIN, (0.1, 0.08, 0.08)), Rod((-0.05, 0, 0), (0.05, 0, 0), 0.05)),
        _link("L_HipSag_link", ORIGIN, j("HipSag", Y, (d(-110), d(89)), 200, 0.3),
              1.6, _rod((0, 0, -0.2), 0.055)),
        _link("L_HipYaw_link", (0.0, 0.0, -0.2), j("HipYaw", Z, (d(-32), d(90)), 120, 0.15),
              1.7, _rod((0, 0, -0.2), 0.055)),
        _link("L_Knee_link", (0.0, 0.0, -0.2), j("Knee", Y, (0.0, d(140)), 200, 0.3),
              3.7, _rod((0, 0, -0.4), 0.05)),
        _link("L_AnklePitch_link", (0.0, 0.0, -0.4), j("AnklePitch", Y, (d(-50), d(40)), 200, 0.3),
              0.18, Box(ORIGIN, (0.05, 0.05, 0.05)), Rod((0, -0.03, 0), (0, 0.03, 0), 0.03)),
        _link("L_AnkleRoll_link", ORIGIN, j("AnkleRoll", X, (d(-15), d(15)), 60, 0.1),
              2.07, Box((sole_x, 0.0, -0.045), (0.21, 0.11, 0.05)),
              Rod((-0.06, 0, -0.04), (0.09, 0, -0.04), 0.03),
              sites=[SiteSpec("l_sole", (sole_x, 0.0, sole_z))],
              boxes=[ContactBoxSpec("l_foot", (sole_x, 0.0, sole_z + 0.01), (0.105, 0.055, 0.01),
                                    "foot")]),
    )  # fmt: skip
    return ChainSpec("pelvis", links)


def _comanplus_waist() -> ChainSpec:
    """WaistLat x, WaistYaw z → ``torso``. The WaistLat link mass (2.5 kg) is not published."""
    d = math.radians
    links = (
        _link("WaistLat_link", (0.0, 0.0, 0.07),
              JointSpec("WaistLat", X, (d(-30), d(30)), 200, 8.0, 0.2, 0.02, 1.0),
              2.5, _rod((0, 0, 0.05), 0.06)),
        _link("torso", (0.0, 0.0, 0.05),
              JointSpec("WaistYaw", Z, (d(-100), d(100)), 120, 8.0, 0.2, 0.02, 1.0),
              12.5, Box((0.0, 0.0, 0.2), (0.2, 0.3, 0.34)), Rod((0, 0, 0.04), (0, 0, 0.3), 0.12)),
    )  # fmt: skip
    return ChainSpec("pelvis", links)


def _comanplus_arm() -> ChainSpec:
    """Left arm hanging along −z: ShSag y, ShLat x, ShYaw z, Elbow y, ForearmPlate z, Wrist1 y,
    Wrist2 z. Arm joint limits, rotor inertia and friction are not published."""

    def j(name: str, axis: tuple[float, float, float], rng: tuple[float, float], tau: float,
          arm: float) -> JointSpec:  # fmt: skip
        return JointSpec(f"L_{name}", axis, rng, tau, 8.0, arm, 0.01, 0.5)

    links = (
        _link("L_ShSag_link", (0.0, 0.17, 0.30), j("ShSag", Y, (-3.0, 1.6), 140, 0.1),
              1.96, _rod((0, 0.05, 0), 0.05)),
        _link("L_ShLat_link", (0.0, 0.05, 0.0), j("ShLat", X, (-0.3, 2.8), 140, 0.1),
              1.86, _rod((0, 0, -0.10), 0.05)),
        _link("L_ShYaw_link", (0.0, 0.0, -0.10), j("ShYaw", Z, (-1.6, 1.6), 120, 0.1),
              1.67, _rod((0, 0, -0.17), 0.045)),
        _link("L_Elbow_link", (0.0, 0.0, -0.17), j("Elbow", Y, (-2.4, 0.1), 120, 0.1),
              1.32, _rod((0, 0, -0.10), 0.04)),
        _link("L_ForearmPlate_link", (0.0, 0.0, -0.10), j("ForearmPlate", Z, (-2.6, 2.6), 35, 0.02),
              1.49, _rod((0, 0, -0.15), 0.04)),
        _link("L_Wrist1_link", (0.0, 0.0, -0.15), j("Wrist1", Y, (-1.5, 1.5), 35, 0.02),
              1.13, _rod((0, 0, -0.05), 0.035)),
        # Wrist2 link 0.28 kg plus a 1.3 kg hand; the palm is the hand's −y face.
        _link("L_Wrist2_link", (0.0, 0.0, -0.05), j("Wrist2", Z, (-2.6, 2.6), 20, 0.02),
              1.58, Box((0.0, 0.0, -0.08), (0.08, 0.04, 0.12)), Rod(ORIGIN, (0, 0, -0.14), 0.035),
              sites=[SiteSpec("l_hand", (0.0, 0.0, -0.12))]),
    )  # fmt: skip
    return ChainSpec("torso", links)


def _with_palm(arm: ChainSpec) -> ChainSpec:
    """Add the wall-contact palm (box and ``l_palm`` site, z into the hand) to a left arm."""
    hand = arm.links[-1]
    palm = replace(
        hand,
        sites=(*hand.sites, SiteSpec("l_palm", (0.0, -0.02, -0.09), _Z_ALONG_Y)),
        boxes=(ContactBoxSpec("l_palm_box", (0.0, -0.015, -0.09), (0.04, 0.005, 0.05), "palm"),),
    )
    return ChainSpec(arm.parent, (*arm.links[:-1], palm))


def comanplus_like() -> HumanoidSpec:
    """COMAN+-like humanoid, 28 actuated joints (legs 6+6, waist 2, arms 7+7)."""
    pelvis = _link(
        "pelvis", ORIGIN, None, 3.46, Box(ORIGIN, (0.14, 0.24, 0.12)),
        Rod((0, -0.08, 0), (0, 0.08, 0), 0.07),
    )  # fmt: skip
    head = _link(
        "head", (0.0, 0.0, 0.36), None, 1.8, Box((0.02, 0.0, 0.1), (0.18, 0.16, 0.2)),
        Rod((0, 0, 0.03), (0, 0, 0.13), 0.085), sites=[SiteSpec("head", (0.08, 0.0, 0.1))],
    )  # fmt: skip
    leg, arm = _comanplus_leg(), _comanplus_arm()
    chains = (
        leg,
        mirror_chain(leg),
        _comanplus_waist(),
        _with_palm(arm),
        mirror_chain(arm),
        ChainSpec("torso", (head,)),
    )
    a = 0.15
    legs = _bent_legs(("HipSag", "Knee", "AnklePitch"), a)
    arms = (("L_ShLat", 0.15), ("R_ShLat", -0.15), ("L_Elbow", -0.4), ("R_Elbow", -0.4))
    # Left arm raised sideways by t; forearm, wrist1, wrist2 = π/2, t, π/2 undo that tilt and
    # turn the hand half a turn, so the palm (the hand's −y face) ends flat on a +y wall.
    t = 0.5
    wall_arm = (
        ("L_ShLat", t), ("L_ForearmPlate", math.pi / 2), ("L_Wrist1", t),
        ("L_Wrist2", math.pi / 2), ("R_ShLat", -0.15), ("R_Elbow", -0.4),
    )  # fmt: skip
    info = RobotInfo(
        contact_frames=("l_sole", "r_sole"),
        contact_rects={
            "l_sole": ContactRect(-0.105, 0.105, -0.055, 0.055),
            "r_sole": ContactRect(-0.105, 0.105, -0.055, 0.055),
            "l_palm": ContactRect(-0.04, 0.04, -0.05, 0.05),
        },
        hand_frames=("l_hand", "r_hand"),
        base_body="pelvis",
        torso_body="torso",
        head_frame="head",
        default_keyframe="stand",
        velocity_limits=_velocity_limits(chains),
        extra={"palm": "l_palm", "wall": "wall"},
    )
    return HumanoidSpec(
        name="comanplus_like",
        base=pelvis,
        chains=chains,
        keyframes=(KeyframeSpec("stand", legs + arms), KeyframeSpec("stand_wall", legs + wall_arm)),
        info=info,
        wall=WallSpec(keyframe="stand_wall", site="l_palm"),
    )


SPECS: dict[str, Callable[[], HumanoidSpec]] = {
    "tocabi_like": tocabi_like,
    "comanplus_like": comanplus_like,
    **{
        f"tocabi_dof{dof}": functools.partial(tocabi_dof, dof)
        for dof in TOCABI_DOF_FAMILY
        if dof != 33
    },
}
"""Registry of generated robots: name → spec factory (file ``models/<name>.xml``)."""


def robot_info(name: str) -> RobotInfo:
    """Metadata of a library robot (``SPECS`` key)."""
    return SPECS[name]().info
