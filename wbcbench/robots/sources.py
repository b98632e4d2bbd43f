"""Model file text as both libraries can read it: package paths, includes and mimic joints.

Pinocchio and MuJoCo each read robot files their own way, and neither resolves everything a
robot package ships:

- URDF mesh paths ``package://<package>/<path>`` (and ``package:///<absolute path>``) are
  resolved against the ``package_dirs`` a scenario gives and, when installed, the data folders of
  ``example-robot-data`` (its cmeel prefix) and of ``icub-models`` (the environment's
  ``share``); relative mesh paths become absolute.
- URDF ``<mimic>`` joints are written as fixed joints at their offset (the master joint's zero):
  a whole-body controller drives every joint with its own torque, and a mimic joint has none.
- MJCF ``<include file=…>`` elements are checked here (a missing or circular include is named
  with its element); MuJoCo reads the file itself and resolves them.
- URDF effort and velocity limits are read here: MuJoCo's URDF reader keeps neither.

Every failure is a :class:`~wbcbench.errors.ModelError` naming the file, the element and the fix.
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wbcbench.errors import ModelError

PACKAGE_PREFIX = "package://"


@dataclass(frozen=True)
class ModelSource:
    """A model file rewritten for both libraries.

    Attributes:
        path: the file as the user named it.
        text: the rewritten XML (absolute mesh paths, includes inlined, mimic joints fixed).
        is_urdf: URDF (True) or MJCF.
        mimic_joints: URDF joints that mimic another, fixed at their offset (name → master).
        urdf_limits: URDF joint name → (effort [N·m], velocity [rad/s]) from its ``<limit>``;
            ``inf`` where the file gives none or zero.
    """

    path: Path
    text: str
    is_urdf: bool
    mimic_joints: dict[str, str]
    urdf_limits: dict[str, tuple[float, float]]


def default_package_dirs() -> list[Path]:
    """Folders searched for ``package://`` paths after the scenario's own: the ``share`` folder
    of every cmeel prefix on ``sys.path`` (where ``example-robot-data`` installs its robots),
    then the environment's own ``share`` folder (where a wheel's data files go: ``icub-models``
    installs ``share/iCub``)."""
    dirs = []
    for entry in sys.path:
        share = Path(entry or ".") / "cmeel.prefix" / "share"
        if share.is_dir():
            dirs.append(share)
    share = Path(sys.prefix) / "share"
    if share.is_dir() and share not in dirs:
        dirs.append(share)
    return dirs


def read_source(path: Path, package_dirs: Sequence[Path] = ()) -> ModelSource:
    """The model file at ``path`` rewritten as described in the module docstring."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ModelError(f"{path}: not valid XML: {exc}") from None
    except OSError as exc:
        raise ModelError(f"{path}: cannot be read: {exc.strerror or exc}") from None
    is_urdf = root.tag == "robot"
    if not is_urdf and root.tag != "mujoco":
        raise ModelError(
            f"{path}: the root element is <{root.tag}>; a robot model is a URDF (<robot>) or an "
            "MJCF (<mujoco>) file"
        )
    mimic: dict[str, str] = {}
    if is_urdf:
        _resolve_meshes(path, root, [*package_dirs, *default_package_dirs()])
        mimic = _fix_mimic_joints(path, root)
    elif any(True for _ in root.iter("include")):
        _inline_includes(path, root, path.parent, [path.resolve()])
    limits = _urdf_limits(path, root) if is_urdf else {}
    return ModelSource(path, ET.tostring(root, encoding="unicode"), is_urdf, mimic, limits)


def _urdf_limits(path: Path, root: ET.Element) -> dict[str, tuple[float, float]]:
    out = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is None:
            continue
        name = joint.get("name", "")
        try:
            values = [abs(float(limit.get(key, "0"))) for key in ("effort", "velocity")]
        except ValueError as exc:
            raise ModelError(f"{path}: <joint name={name!r}> <limit>: {exc}") from None
        effort, velocity = (v if v > 0 else float("inf") for v in values)
        out[name] = (effort, velocity)
    return out


def resolve_package_path(uri: str, package_dirs: Sequence[Path], file: Path, element: str) -> Path:
    """The file a ``package://`` URI names.

    ``package:///abs/path`` is an absolute path; ``package://pkg/rest`` is ``dir/pkg/rest`` for
    the first ``dir`` of ``package_dirs`` that holds it (or ``dir/rest`` when ``dir`` is itself
    named ``pkg``).

    Raises:
        ModelError: naming ``file``, the ``element`` and the folders searched.
    """
    rest = uri[len(PACKAGE_PREFIX) :]
    if rest.startswith("/"):
        target = Path(rest)
        if target.is_file():
            return target
        raise ModelError(f"{file}: {element}: {uri!r}: no such file {target}")
    package, _, inner = rest.partition("/")
    for folder in map(Path, package_dirs):
        candidates = [folder / package / inner]
        if folder.name == package:
            candidates.append(folder / inner)
        for candidate in candidates:
            if candidate.is_file():
                return candidate
    searched = ", ".join(str(d) for d in package_dirs) or "(none)"
    raise ModelError(
        f"{file}: {element}: cannot resolve {uri!r}: package {package!r} is in none of the "
        f"package folders ({searched}); add the folder that holds {package}/ to the scenario's "
        "'package_dirs:'"
    )


def _resolve_meshes(path: Path, root: ET.Element, package_dirs: Sequence[Path]) -> None:
    for link in root.iter("link"):
        for kind in ("visual", "collision"):
            for item in link.iter(kind):
                for mesh in item.iter("mesh"):
                    name = mesh.get("filename", "")
                    element = f"<link name={link.get('name')!r}> <{kind}> <mesh>"
                    mesh.set("filename", str(_mesh_file(name, path, package_dirs, element)))


def _mesh_file(name: str, path: Path, package_dirs: Sequence[Path], element: str) -> Path:
    if name.startswith(PACKAGE_PREFIX):
        return resolve_package_path(name, package_dirs, path, element)
    if name.startswith("file://"):
        name = name[len("file://") :]
    target = Path(name)
    if not target.is_absolute():
        target = path.parent / target
    if not target.is_file():
        raise ModelError(f"{path}: {element}: no such mesh file {target}")
    return target.resolve()


def _fix_mimic_joints(path: Path, root: ET.Element) -> dict[str, str]:
    """Make every mimic joint fixed at ``offset`` (its value with the master at zero)."""
    mimic: dict[str, str] = {}
    for joint in root.iter("joint"):
        tag = joint.find("mimic")
        if tag is None:
            continue
        name = joint.get("name", "")
        master = tag.get("joint", "")
        try:
            offset = float(tag.get("offset", "0"))
            axis = np.array([float(x) for x in _child_attr(joint, "axis", "xyz", "1 0 0").split()])
            xyz = [float(x) for x in _child_attr(joint, "origin", "xyz", "0 0 0").split()]
            rpy = [float(x) for x in _child_attr(joint, "origin", "rpy", "0 0 0").split()]
        except ValueError as exc:
            raise ModelError(f"{path}: <joint name={name!r}>: {exc}") from None
        if offset != 0.0:
            xyz, rpy = _offset_origin(joint.get("type", ""), xyz, rpy, axis, offset)
        for child in list(joint):
            if child.tag not in ("parent", "child"):
                joint.remove(child)
        ET.SubElement(
            joint, "origin", xyz=" ".join(repr(v) for v in xyz), rpy=" ".join(repr(v) for v in rpy)
        )
        joint.set("type", "fixed")
        mimic[name] = master
    return mimic


def _child_attr(element: ET.Element, tag: str, attr: str, default: str) -> str:
    child = element.find(tag)
    return default if child is None else child.get(attr, default)


def _offset_origin(
    kind: str, xyz: list[float], rpy: list[float], axis: np.ndarray, offset: float
) -> tuple[list[float], list[float]]:
    """The joint origin composed with the joint's motion by ``offset`` (rad or m)."""
    import pinocchio as pin

    origin = pin.SE3(pin.rpy.rpyToMatrix(np.array(rpy)), np.array(xyz))
    unit = axis / np.linalg.norm(axis)
    if kind == "prismatic":
        motion = pin.SE3(np.eye(3), unit * offset)
    else:
        motion = pin.SE3(pin.exp3(unit * offset), np.zeros(3))
    placed = origin * motion
    return list(placed.translation), list(pin.rpy.matrixToRpy(placed.rotation))


def _inline_includes(path: Path, root: ET.Element, base: Path, stack: list[Path]) -> None:
    """Replace every ``<include file=…>`` under ``root`` by the children of that file's root."""
    for parent in list(root.iter()):
        for index, child in reversed(list(enumerate(parent))):
            if child.tag != "include":
                continue
            name = child.get("file")
            element = f"<include file={name!r}>"
            if not name:
                raise ModelError(f"{path}: <include> has no 'file' attribute")
            target = (base / name).resolve()
            if not target.is_file():
                raise ModelError(
                    f"{path}: {element}: no such file {target} (include paths are relative to "
                    f"the main file's folder, {base})"
                )
            if target in stack:
                raise ModelError(f"{path}: {element}: includes itself (through {stack[-1].name})")
            try:
                included = ET.parse(target).getroot()
            except ET.ParseError as exc:
                raise ModelError(f"{path}: {element}: {target} is not valid XML: {exc}") from None
            _inline_includes(target, included, base, [*stack, target])
            parent.remove(child)
            for offset, item in enumerate(list(included)):
                parent.insert(index + offset, item)
