"""Where an object stands: its placement in the robot's base frame and an optional support
table under it, and the test of whether the robot is in that table.

A placement is a position (metres, robot base frame) and a rotation: a yaw about the
vertical (radians; the object upright, its frame's +z along the world's +z:
:func:`placement_pose`) or a full orientation (a tilted object: :func:`is_upright` False,
and then no table under it).

The table (:class:`SupportTable`) is a box whose top face is the object frame's z = 0 plane
(the plane of the object's base), centred under the object's origin, its sides along the
object frame's x and y axes; by default it reaches down to the robot's base plane (z = 0 in
the world), as a table the robot is mounted beside. The object rests on it; the hand and the
arm collide with it: :class:`~kinegrasp_env.closing.table_check.TableCheck` answers, for a
batch of configurations, whether any arm link or hand link intersects the box
(``tests/table_probe_reference.py`` answers the same from pybullet's own closest points,
the tests' reference; the box as a pybullet body: :mod:`kinegrasp_env.world.table_body`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Default table top, metres (along the object frame's x and y).
TABLE_SIZE: tuple[float, float] = (0.6, 0.8)
#: The thinnest table, metres (used when the object stands less than this above the robot's
#: base plane and no thickness is given).
MIN_THICKNESS = 0.02


def placement_pose(position, yaw: float = 0.0) -> np.ndarray:
    """(4, 4) object frame in the world frame: at ``position`` (3,) metres, rotated by
    ``yaw`` radians about the vertical.

    Raises:
        ValueError: a position that is not 3 finite numbers, or a non-finite yaw.
    """
    position = np.asarray(position, dtype=float)
    if position.shape != (3,) or not np.all(np.isfinite(position)):
        raise ValueError(f"a position is 3 finite numbers (metres), got {position.tolist()}")
    if not math.isfinite(yaw):
        raise ValueError(f"yaw must be finite (radians), got {yaw}")
    pose = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    pose[:2, :2] = [[c, -s], [s, c]]
    pose[:3, 3] = position
    return pose


def is_upright(pose: np.ndarray, tol: float = 1e-9) -> bool:
    """The pose (4, 4) turns its object about the vertical only (its z axis is the world's)."""
    return bool(abs(pose[2, 2] - 1.0) <= tol)


def pose_yaw(pose: np.ndarray) -> float:
    """The yaw (radians) of an upright placement ``pose`` (4, 4)."""
    return math.atan2(pose[1, 0], pose[0, 0])


@dataclass(frozen=True)
class SupportTable:
    """A box under the object (metres).

    Attributes:
        size: (x, y) extents of the top face, along the object frame's axes.
        thickness: the box's height below the top face; None: down to the robot's base plane
            (at least :data:`MIN_THICKNESS`).
    """

    size: tuple[float, float] = TABLE_SIZE
    thickness: float | None = None

    def __post_init__(self) -> None:
        values = [*self.size] + ([] if self.thickness is None else [self.thickness])
        if len(self.size) != 2 or not all(math.isfinite(v) and v > 0 for v in values):
            raise ValueError(f"a table's size (x, y) and thickness are positive metres, got "
                             f"size {list(self.size)}, thickness {self.thickness}")

    def box(self, object_pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(world pose (4, 4) of the box's centre, half extents (3,)) for an object standing
        at ``object_pose`` (4, 4)."""
        thickness = self.thickness
        if thickness is None:
            thickness = max(float(object_pose[2, 3]), MIN_THICKNESS)
        pose = np.array(object_pose, dtype=float)
        pose[:3, 3] = object_pose[:3, :3] @ [0.0, 0.0, -0.5 * thickness] + object_pose[:3, 3]
        return pose, np.array([0.5 * self.size[0], 0.5 * self.size[1], 0.5 * thickness])

    def to_dict(self) -> dict:
        """The catalog form: ``{"size": [x, y], "thickness": t or null}``."""
        return {"size": [float(v) for v in self.size], "thickness": self.thickness}

    @classmethod
    def from_dict(cls, data: dict) -> SupportTable:
        """The table of a catalog entry's ``table`` field (ValueError when malformed)."""
        try:
            size = tuple(float(v) for v in data["size"])
            thickness = data.get("thickness")
            return cls(size, None if thickness is None else float(thickness))
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"a table is {{'size': [x, y], 'thickness': t or null}}, got "
                             f"{data!r} ({exc})") from None
