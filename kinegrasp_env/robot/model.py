"""Robot models read from URDF: joints, limits, links, mimic couplings.

Nothing here is a hand-typed copy of the robot's numbers: :func:`load_urdf` parses the
shipped ``kuka_sdh.urdf`` (or any serial/tree URDF with revolute, prismatic and fixed joints)
into a :class:`RobotModel` (the default robot's names and model:
:mod:`kinegrasp_env.robot.default_robot`).

Configuration vectors: an *actuated* vector ``q`` (``RobotModel.dof`` entries, in
``RobotModel.actuated`` order) holds one value per independent joint; mimic joints (the SDH
coupled spread) follow from it through :meth:`RobotModel.expand`.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw to a (3, 3) rotation: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True)
class Joint:
    """One URDF joint.

    Attributes:
        name, kind: joint name and type (``revolute``, ``continuous``, ``prismatic``, ``fixed``).
        parent, child: link names.
        origin: (4, 4) transform parent link frame -> joint frame at zero joint value.
        axis: (3,) unit axis in the joint frame.
        lower, upper: limits (radians or metres); infinite for continuous/fixed joints.
        mimic: ``(driving joint name, multiplier, offset)`` or None.
    """

    name: str
    kind: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    mimic: tuple[str, float, float] | None = None

    @property
    def movable(self) -> bool:
        return self.kind != "fixed"


@dataclass(frozen=True)
class RobotModel:
    """A kinematic tree read from URDF.

    Attributes:
        name: robot name.
        base_link: the root link (its frame is the world frame).
        joints: all joints in topological order (parents before children).
        actuated: names of the independent movable joints, in configuration-vector order.
        urdf_path: where the model was read from.
    """

    name: str
    base_link: str
    joints: tuple[Joint, ...]
    actuated: tuple[str, ...]
    urdf_path: Path

    @property
    def dof(self) -> int:
        return len(self.actuated)

    @property
    def links(self) -> tuple[str, ...]:
        return (self.base_link, *(j.child for j in self.joints))

    def joint(self, name: str) -> Joint:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(f"unknown joint {name!r} in robot {self.name!r}")

    @cached_property
    def _limits(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(lower, upper) limits of the actuated joints, looked up once."""
        joints = [self.joint(n) for n in self.actuated]
        return tuple(j.lower for j in joints), tuple(j.upper for j in joints)

    @property
    def lower(self) -> np.ndarray:
        """(dof,) lower limits of the actuated joints (a new array each call)."""
        return np.array(self._limits[0])

    @property
    def upper(self) -> np.ndarray:
        """(dof,) upper limits of the actuated joints (a new array each call)."""
        return np.array(self._limits[1])

    def index(self, names: tuple[str, ...] | list[str]) -> np.ndarray:
        """Positions of ``names`` in the actuated vector."""
        return np.array([self.actuated.index(n) for n in names], dtype=int)

    def drivers(self) -> dict[str, tuple[int, float, float]]:
        """For every movable joint: (actuated index, multiplier, offset) that sets its value."""
        out: dict[str, tuple[int, float, float]] = {}
        for j in self.joints:
            if not j.movable:
                continue
            if j.mimic is not None:
                src, mult, off = j.mimic
                out[j.name] = (self.actuated.index(src), mult, off)
            elif j.name in self.actuated:
                out[j.name] = (self.actuated.index(j.name), 1.0, 0.0)
        return out

    def expand(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Values of every movable joint for actuated configurations ``q`` (..., dof)."""
        q = np.asarray(q, dtype=float)
        return {name: mult * q[..., i] + off for name, (i, mult, off) in self.drivers().items()}

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Boolean (...,) : every actuated joint of ``q`` (..., dof) within its limits."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.lower - tol) & (q <= self.upper + tol), axis=-1)


def _floats(text: str | None, default: tuple[float, ...]) -> tuple[float, ...]:
    return default if text is None else tuple(float(v) for v in text.split())


def origin_matrix(element: ET.Element | None) -> np.ndarray:
    """(4, 4) the transform of a URDF ``<origin xyz=".." rpy=".."/>`` element (identity
    where it, or either attribute, is absent; metres, radians)."""
    xyz = _floats(element.get("xyz") if element is not None else None, (0.0, 0.0, 0.0))
    rpy = _floats(element.get("rpy") if element is not None else None, (0.0, 0.0, 0.0))
    origin = np.eye(4)
    origin[:3, :3] = rpy_to_matrix(*rpy)
    origin[:3, 3] = xyz
    return origin


def load_urdf(path: str | Path, actuated: tuple[str, ...] | None = None) -> RobotModel:
    """Parse a URDF file into a :class:`RobotModel`.

    Args:
        path: URDF file.
        actuated: order of the configuration vector; defaults to every movable, non-mimic
            joint in file order.

    Raises:
        ValueError: for an unsupported joint type, a non-tree structure or unknown names.
    """
    path = Path(path)
    root = ET.parse(path).getroot()
    joints: list[Joint] = []
    for element in root.findall("joint"):
        kind = element.get("type", "")
        if kind not in ("revolute", "continuous", "prismatic", "fixed"):
            raise ValueError(f"{path.name}: joint {element.get('name')!r} has unsupported "
                             f"type {kind!r}")
        origin = origin_matrix(element.find("origin"))
        axis_el = element.find("axis")
        axis = np.array(_floats(axis_el.get("xyz") if axis_el is not None else None,
                                (1.0, 0.0, 0.0)))
        length = np.linalg.norm(axis)
        if length == 0.0 and kind != "fixed":
            raise ValueError(f"joint {element.get('name')!r}: axis {axis.tolist()} has no "
                             "direction")
        axis = axis / length if length > 0.0 else np.array([1.0, 0.0, 0.0])
        limit_el = element.find("limit")
        lower, upper = -math.inf, math.inf
        if kind in ("revolute", "prismatic") and limit_el is not None:
            lower = float(limit_el.get("lower", "-inf"))
            upper = float(limit_el.get("upper", "inf"))
        mimic_el = element.find("mimic")
        mimic = None
        if mimic_el is not None:
            mimic = (mimic_el.get("joint"), float(mimic_el.get("multiplier", "1")),
                     float(mimic_el.get("offset", "0")))
        joints.append(Joint(element.get("name"), kind, element.find("parent").get("link"),
                            element.find("child").get("link"), origin, axis, lower, upper,
                            mimic))

    children = {j.child for j in joints}
    link_names = [link.get("name") for link in root.findall("link")]
    for j in joints:  # a joint naming a link the file does not have: name both
        for end, name in (("parent", j.parent), ("child", j.child)):
            if name not in link_names:
                raise ValueError(f"{path.name}: joint {j.name!r} has {end} link {name!r}, "
                                 "which is not a link of the file")
    joint_names = {j.name for j in joints}
    for j in joints:
        if j.mimic is not None and j.mimic[0] not in joint_names:
            raise ValueError(f"{path.name}: joint {j.name!r} mimics {j.mimic[0]!r}, which is "
                             "not a joint of the file")
    roots = [name for name in link_names if name not in children]
    if len(roots) != 1:
        raise ValueError(f"{path.name}: expected one root link, found {roots}")
    # topological order: breadth-first from the root
    ordered: list[Joint] = []
    frontier = [roots[0]]
    while frontier:
        link = frontier.pop(0)
        for j in joints:
            if j.parent == link:
                ordered.append(j)
                frontier.append(j.child)
    if len(ordered) != len(joints):
        raise ValueError(f"{path.name}: joints not connected to the root {roots[0]!r}")
    if actuated is None:
        actuated = tuple(j.name for j in joints if j.movable and j.mimic is None)
    known = {j.name for j in joints if j.movable}
    missing = [n for n in actuated if n not in known]
    if missing:
        raise ValueError(f"{path.name}: actuated joints not found: {missing}")
    return RobotModel(root.get("name", path.stem), roots[0], tuple(ordered), tuple(actuated),
                      path)
