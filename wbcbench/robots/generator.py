"""Write a :class:`~wbcbench.robots.spec.HumanoidSpec` as one self-contained MJCF file.

The file follows the rules that make MuJoCo and Pinocchio read the same multibody: no
``<include>`` or ``<frame>``, an explicit ``<inertial>`` on every body, one hinge per body, rotor
inertia as ``armature``, torque limits as ``actuatorfrcrange``.

Generation has two passes: the model is first compiled without keyframes or wall, its forward
kinematics give the base height that puts the soles on the floor and the wall position that puts
the palm on the wall, then the final text is written. Numbers are printed with 12 significant
digits so the text is reproducible byte for byte and computed positions stay exact to ~1e-12 m.

``python -m wbcbench.robots.generator`` rewrites every file in ``wbcbench/robots/models``.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from wbcbench.errors import ModelError
from wbcbench.robots.spec import (
    IDENTITY,
    ContactBoxSpec,
    HumanoidSpec,
    LinkSpec,
    Rod,
    inertia_of,
)

MODELS_DIR = Path(__file__).resolve().parent / "models"

# Collision bit masks: a pair collides when (contype_a & conaffinity_b) or (contype_b &
# conaffinity_a). Feet meet only the floor and the palm only the wall; feet never meet each other.
_MASKS = {
    "floor": (2, 1),
    "wall": (0, 4),
    "foot": (1, 2),
    "palm": (4, 0),
}
# margin = gap reports touching pairs (distance in [0, margin)) as inactive contacts, so a sole
# resting exactly on the floor shows up in mjData.contact while forces still start at distance 0.
_CONTACT_MARGIN = 0.001
_FLAT_TOL = 1e-9


def fmt(x: float) -> str:
    """Deterministic short float text: 12 significant digits, rounded to 1e-12, no "-0"."""
    text = f"{round(float(x), 12):.12g}"
    return "0" if text in ("-0", "0") else text


def fmt_vec(values: Iterable[float]) -> str:
    """Space-separated :func:`fmt` of each value."""
    return " ".join(fmt(v) for v in values)


@dataclass(frozen=True)
class _Placement:
    """Computed placement data filled in by the first pass."""

    base_height: float  # base z putting the soles on the floor at zero joint angles [m]
    keyframes: tuple[tuple[str, np.ndarray], ...]  # (name, qpos (nq,)) in MuJoCo order
    wall_center: np.ndarray | None  # (3,) [m]


# ---------------------------------------------------------------------------------------------
# Text rendering


def _inertial_xml(link: LinkSpec) -> str:
    com, inertia = inertia_of(link.shape, link.mass)
    off = (inertia[0, 1], inertia[0, 2], inertia[1, 2])
    if all(abs(v) < 1e-15 for v in off):
        tensor = f'diaginertia="{fmt_vec(np.diag(inertia))}"'
    else:
        full = (inertia[0, 0], inertia[1, 1], inertia[2, 2], *off)
        tensor = f'fullinertia="{fmt_vec(full)}"'
    return f'<inertial pos="{fmt_vec(com)}" mass="{fmt(link.mass)}" {tensor}/>'


def _capsule_xml(body: str, rod: Rod) -> str:
    if np.linalg.norm(np.subtract(rod.end, rod.start)) < 1e-6:
        raise ModelError(f"capsule of body {body!r} has zero length; give the link a capsule")
    return (
        f'<geom name="{body}_capsule" type="capsule" '
        f'fromto="{fmt_vec((*rod.start, *rod.end))}" size="{fmt(rod.radius)}" '
        'contype="0" conaffinity="0" group="1" rgba="0.7 0.7 0.75 1"/>'
    )


def _box_xml(box: ContactBoxSpec) -> str:
    contype, conaffinity = _MASKS[box.kind]
    friction = "1 0.005 0.0001" if box.kind == "foot" else "0.05 0.005 0.0001"
    quat = "" if box.quat == IDENTITY else f' quat="{fmt_vec(box.quat)}"'
    return (
        f'<geom name="{box.name}" type="box" pos="{fmt_vec(box.center)}"{quat} '
        f'size="{fmt_vec(box.half)}" contype="{contype}" conaffinity="{conaffinity}" '
        f'condim="3" friction="{friction}" margin="{fmt(_CONTACT_MARGIN)}" '
        f'gap="{fmt(_CONTACT_MARGIN)}" rgba="0.3 0.3 0.35 1"/>'
    )


def _joint_xml(link: LinkSpec) -> str:
    j = link.joint
    assert j is not None
    return (
        f'<joint name="{j.name}" type="hinge" axis="{fmt_vec(j.axis)}" limited="true" '
        f'range="{fmt_vec(j.range)}" armature="{fmt(j.armature)}" damping="{fmt(j.damping)}" '
        f'frictionloss="{fmt(j.frictionloss)}" actuatorfrclimited="true" '
        f'actuatorfrcrange="{fmt(-j.torque)} {fmt(j.torque)}"/>'
    )


def _children_of(spec: HumanoidSpec) -> dict[str, list[LinkSpec]]:
    """Body name → child links in write order (own chain's next link first, then chains)."""
    children: dict[str, list[LinkSpec]] = {link.body: [] for link in spec.links}
    if len(children) != len(spec.links):
        raise ModelError(f"{spec.name}: body names are not unique")
    for chain in spec.chains:
        parents = (chain.parent, *(lk.body for lk in chain.links[:-1]))
        for parent, link in zip(parents, chain.links, strict=True):
            if parent not in children:
                raise ModelError(f"{spec.name}: chain parent {parent!r} is not a body")
            children[parent].append(link)
    # Chains attached to a body were appended in listing order; the body's own chain
    # continuation goes in front of them so a chain's joints stay contiguous.
    continuation = {
        prev.body: nxt.body
        for chain in spec.chains
        for prev, nxt in zip(chain.links[:-1], chain.links[1:], strict=True)
    }
    for body, kids in children.items():
        nxt = continuation.get(body)
        first = [lk for lk in kids if lk.body == nxt]
        kids[:] = first + [lk for lk in kids if lk.body != nxt]
    return children


def _body_lines(
    link: LinkSpec, children: dict[str, list[LinkSpec]], depth: int, pos: Sequence[float]
) -> list[str]:
    """Lines of ``link``'s body and its subtree; the top call (depth 2) is the free base."""
    pad = "  " * depth
    inner = "  " * (depth + 1)
    lines = [f'{pad}<body name="{link.body}" pos="{fmt_vec(pos)}">']
    if link.joint is None and depth == 2:
        lines.append(f'{inner}<freejoint name="root"/>')
    elif link.joint is not None:
        lines.append(inner + _joint_xml(link))
    lines.append(inner + _inertial_xml(link))
    lines.append(inner + _capsule_xml(link.body, link.capsule_rod))
    lines.extend(inner + _box_xml(b) for b in link.boxes)
    for site in link.sites:
        quat = "" if site.quat == IDENTITY else f' quat="{fmt_vec(site.quat)}"'
        lines.append(
            f'{inner}<site name="{site.name}" pos="{fmt_vec(site.pos)}"{quat} size="0.01"/>'
        )
    for child in children[link.body]:
        lines.extend(_body_lines(child, children, depth + 1, child.pos))
    lines.append(f"{pad}</body>")
    return lines


def render(spec: HumanoidSpec, placement: _Placement | None = None) -> str:
    """MJCF text of ``spec``; without ``placement`` the base is at z = 0 and there are no
    keyframes and no wall (the first pass)."""
    if spec.base.joint is not None:
        raise ModelError(f"{spec.name}: the base body carries the free joint, not a hinge")
    children = _children_of(spec)
    base_z = 0.0 if placement is None else placement.base_height
    out = [
        f'<mujoco model="{spec.name}">',
        "  <!-- Generated by wbcbench.robots.generator from wbcbench/robots/library.py;"
        " do not edit. -->",
        '  <compiler angle="radian" inertiafromgeom="false"/>',
        '  <option timestep="0.001" integrator="implicitfast"/>',
        "  <visual>",
        '    <headlight ambient="0.4 0.4 0.4" diffuse="0.6 0.6 0.6" specular="0 0 0"/>',
        "  </visual>",
        "  <worldbody>",
        '    <light name="sun" pos="0 0 4" dir="0 0 -1" directional="true"/>',
        f'    <geom name="floor" type="plane" size="10 10 0.05" contype="{_MASKS["floor"][0]}"'
        f' conaffinity="{_MASKS["floor"][1]}" condim="3"'
        f' friction="{fmt_vec(spec.floor_friction)}" rgba="0.8 0.8 0.8 1"/>',
    ]
    if placement is not None and placement.wall_center is not None and spec.wall is not None:
        w = spec.wall
        out.append(
            f'    <geom name="wall" type="box" pos="{fmt_vec(placement.wall_center)}"'
            f' size="{fmt_vec((w.half_x, w.thickness / 2, w.half_z))}"'
            f' contype="{_MASKS["wall"][0]}" conaffinity="{_MASKS["wall"][1]}" condim="3"'
            ' friction="0.05 0.005 0.0001" rgba="0.85 0.8 0.7 0.5"/>'
        )
    out.extend(_body_lines(spec.base, children, 2, (0.0, 0.0, base_z)))
    out.append("  </worldbody>")
    out.append("  <actuator>")
    for joint in _depth_first_joints(spec, children):
        out.append(
            f'    <motor name="{joint}" joint="{joint}" gear="1" ctrllimited="true"'
            f' ctrlrange="{fmt(-_torque(spec, joint))} {fmt(_torque(spec, joint))}"/>'
        )
    out.append("  </actuator>")
    if placement is not None and placement.keyframes:
        out.append("  <keyframe>")
        for name, qpos in placement.keyframes:
            out.append(f'    <key name="{name}" qpos="{fmt_vec(qpos)}"/>')
        out.append("  </keyframe>")
    out.append("</mujoco>")
    return "\n".join(out) + "\n"


def _torque(spec: HumanoidSpec, joint: str) -> float:
    return next(j.torque for j in spec.joints if j.name == joint)


def _depth_first_joints(spec: HumanoidSpec, children: dict[str, list[LinkSpec]]) -> list[str]:
    order: list[str] = []

    def visit(link: LinkSpec) -> None:
        if link.joint is not None:
            order.append(link.joint.name)
        for child in children[link.body]:
            visit(child)

    visit(spec.base)
    return order


# ---------------------------------------------------------------------------------------------
# First pass: forward kinematics for keyframes and the wall


def _site(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> tuple[np.ndarray, np.ndarray]:
    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if sid < 0:
        raise ModelError(f"site {name!r} does not exist in the generated model")
    return data.site_xpos[sid].copy(), data.site_xmat[sid].reshape(3, 3).copy()


def _placement(spec: HumanoidSpec) -> _Placement:
    model = mujoco.MjModel.from_xml_string(render(spec))
    data = mujoco.MjData(model)

    def qpos_of(joints: Iterable[tuple[str, float]]) -> np.ndarray:
        qpos = model.qpos0.copy()
        qpos[0:7] = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
        for name, angle in joints:
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if jid < 0:
                raise ModelError(f"{spec.name}: keyframe names unknown joint {name!r}")
            lo, hi = model.jnt_range[jid]
            if not lo <= angle <= hi:
                raise ModelError(f"{spec.name}: keyframe angle of {name} outside its range")
            qpos[model.jnt_qposadr[jid]] = angle
        # Kinematics must see the angles exactly as the file will store them.
        return np.array([float(fmt(v)) for v in qpos])

    def floor_height(qpos: np.ndarray, sites: Sequence[str]) -> float:
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        heights = []
        for name in sites:
            pos, rot = _site(model, data, name)
            if np.abs(rot[:, 2] - (0.0, 0.0, 1.0)).max() > _FLAT_TOL:
                raise ModelError(f"{spec.name}: site {name} is not flat in this posture")
            heights.append(pos[2])
        if max(heights) - min(heights) > 1e-12:
            raise ModelError(f"{spec.name}: sites {list(sites)} are at different heights")
        return -float(np.mean(heights))

    base_height = floor_height(qpos_of(()), spec.keyframes[0].stand_on)
    keyframes = []
    for key in spec.keyframes:
        qpos = qpos_of(key.joints)
        qpos[2] = float(fmt(floor_height(qpos, key.stand_on)))
        keyframes.append((key.name, qpos))

    wall_center = None
    if spec.wall is not None:
        w = spec.wall
        qpos = dict(keyframes)[w.keyframe]
        data.qpos[:] = qpos
        mujoco.mj_kinematics(model, data)
        pos, rot = _site(model, data, w.site)
        if np.abs(rot[:, 2] - (0.0, -1.0, 0.0)).max() > _FLAT_TOL:
            raise ModelError(f"{spec.name}: site {w.site} is not flat against a +y wall")
        # The wall stands on the floor; only its inner face (y) has to be exact.
        wall_center = np.array([pos[0], pos[1] + w.thickness / 2, w.half_z])
    return _Placement(base_height, tuple(keyframes), wall_center)


def generate(spec: HumanoidSpec) -> str:
    """Final MJCF text of ``spec`` (keyframes and wall included)."""
    return render(spec, _placement(spec))


def write_all(out_dir: Path = MODELS_DIR) -> list[Path]:
    """Write every library robot to ``out_dir/<name>.xml``; returns the written paths."""
    from wbcbench.robots.library import SPECS

    out_dir.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, make in SPECS.items():
        path = out_dir / f"{name}.xml"
        path.write_text(generate(make()), encoding="utf-8")
        paths.append(path)
    return paths


def main() -> int:
    """Entry point of ``python -m wbcbench.robots.generator``."""
    for path in write_all():
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
