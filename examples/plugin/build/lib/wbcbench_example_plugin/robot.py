"""A robot from outside wbcbench: a model file shipped in this distribution and the facts the
file does not carry (contact frames and sole sizes, hands, base and torso, the keyframe)."""

from __future__ import annotations

from pathlib import Path

from wbcbench.robots.spec import ContactRect, RobotFile, RobotInfo

_SOLE = ContactRect(-0.15, 0.15, -0.065, 0.065)  # [m], in the sole frame

EXAMPLE_BIPED = RobotFile(
    path=Path(__file__).parent / "models" / "example_biped.xml",
    info=RobotInfo(
        contact_frames=("l_sole", "r_sole"),
        contact_rects={"l_sole": _SOLE, "r_sole": _SOLE},
        hand_frames=("l_hand", "r_hand"),
        base_body="pelvis",
        torso_body="torso",
        head_frame="head",
        default_keyframe="stand",
    ),
    summary="example plugin: a 20-DoF humanoid (legs, waist, one-joint arms, neck)",
)
