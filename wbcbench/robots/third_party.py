"""Real robots from other packages, loaded by name like the generated ones.

Each entry names a model file inside an installed distribution (a ``package://`` path, resolved
as :mod:`wbcbench.robots.sources` resolves mesh paths) and the facts a scenario needs that the
file does not carry: contact frames and sole sizes, hand, base and torso frames. The files are
read as published, with no edits; what the loader changes (floor, mimic joints) ``validate``
prints. ``pip install 'wbcbench[robots]'`` installs TALOS and G1, ``pip install 'wbcbench[icub]'``
iCub.
"""

from __future__ import annotations

from dataclasses import dataclass

from wbcbench.robots.spec import ContactRect, RobotInfo


@dataclass(frozen=True)
class ThirdPartyRobot:
    """A robot model shipped by another distribution.

    Attributes:
        distribution: the distribution and version that ships it (``pip install`` it).
        uri: ``package://<package>/<path>`` of the model file.
        info: contact frames, sole rectangles [m] and named frames.
        summary: one line for ``wbcbench list``.
        extra: the wbcbench extra that installs the distribution (``wbcbench[<extra>]``).
    """

    distribution: str
    uri: str
    info: RobotInfo
    summary: str
    extra: str = "robots"


_ERD = "example-robot-data==6.0.0"
_ERD_ROBOTS = "package://example-robot-data/robots"

# TALOS' box foot: 0.21 × 0.13 m, centred under the ankle; the sole frame is 3 mm above its
# bottom face, which the initial placement accounts for.
_TALOS_SOLE = ContactRect(-0.1, 0.1, -0.06, 0.06)
# G1's foot touches through four 5 mm spheres at x ∈ {−0.05, 0.12}, y = ±0.025 / ±0.03 of the
# ankle roll link, 35 mm below its origin: the support rectangle spans those points.
_G1_SOLE = ContactRect(-0.05, 0.12, -0.025, 0.025)

#: TALOS's frames, the same in its box-foot and mesh-foot files
_TALOS = RobotInfo(
    contact_frames=("left_sole_link", "right_sole_link"),
    contact_rects={"left_sole_link": _TALOS_SOLE, "right_sole_link": _TALOS_SOLE},
    hand_frames=("arm_left_7_link", "arm_right_7_link"),
    base_body="base_link",
    torso_body="torso_2_link",
)

_ICUB = "icub-models==3.2.0"
# iCub's foot collides through one box, 160 × 72 × 1 mm, at (30, ±5, 14) mm of the foot link,
# whose z axis points down; the sole frame sits at (3.5, 0, 4) mm of it, turned half a turn
# about x (z up). In the sole frame the box spans x −53.5…106.5 mm and y −31…41 mm (left foot;
# mirrored for the right), and its bottom face lies 10.5 mm below the sole plane.
_ICUB_LEFT_SOLE = ContactRect(-0.0535, 0.1065, -0.031, 0.041)
_ICUB_RIGHT_SOLE = ContactRect(-0.0535, 0.1065, -0.041, 0.031)

THIRD_PARTY: dict[str, ThirdPartyRobot] = {
    "talos": ThirdPartyRobot(
        distribution=_ERD,
        uri=f"{_ERD_ROBOTS}/talos_data/robots/talos_reduced_box.urdf",
        info=_TALOS,
        summary="PAL Robotics TALOS, reduced model with box feet (example-robot-data)",
    ),
    "talos_mesh": ThirdPartyRobot(
        distribution=_ERD,
        uri=f"{_ERD_ROBOTS}/talos_data/robots/talos_reduced.urdf",
        info=_TALOS,
        summary="PAL Robotics TALOS, reduced model with its mesh feet (example-robot-data)",
    ),
    "g1": ThirdPartyRobot(
        distribution=_ERD,
        uri=f"{_ERD_ROBOTS}/g1_description/urdf/g1_29dof_rev_1_0.urdf",
        info=RobotInfo(
            contact_frames=("left_ankle_roll_link", "right_ankle_roll_link"),
            contact_rects={"left_ankle_roll_link": _G1_SOLE, "right_ankle_roll_link": _G1_SOLE},
            hand_frames=("left_rubber_hand", "right_rubber_hand"),
            base_body="pelvis",
            torso_body="torso_link",
        ),
        summary="Unitree G1, 29 DoF, point-contact feet (example-robot-data)",
    ),
    "icub": ThirdPartyRobot(
        distribution=_ICUB,
        uri="package://iCub/robots/iCubGazeboV2_5/model.urdf",
        info=RobotInfo(
            contact_frames=("l_sole", "r_sole"),
            contact_rects={"l_sole": _ICUB_LEFT_SOLE, "r_sole": _ICUB_RIGHT_SOLE},
            hand_frames=("l_hand", "r_hand"),
            base_body="root_link",
            torso_body="chest",
        ),
        summary="IIT iCub v2.5, 32 DoF, the simulation model iCubGazeboV2_5 (icub-models)",
        extra="icub",
    ),
}
