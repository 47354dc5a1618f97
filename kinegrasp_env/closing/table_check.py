"""Whether a description robot's links meet the support table an object stands on, for the
fast closing's start check.

The table (:class:`~kinegrasp_env.world.support.SupportTable`) is a box fixed in the object's
frame. A link meets it when its collision geometry (:class:`~kinegrasp_env.closing.
link_geometry.LinkGeometry`) touches or enters the box: a polytope when GJK
(:func:`~kinegrasp_env.closing.convex_distance.hull_distance_bounds`) finds it within 0 of
the box's hull, a rounded part (a ball swept along a core) when its core comes within its
radius. GJK's bound is certified and tight to :data:`~kinegrasp_env.closing.
convex_distance.GAP_REL` of the distance, so this is the reference's rule (pybullet's
closest points at 0 m between the link and the box) up to that tolerance. A link whose
bounding ball is clear of the box is not examined.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.convex_distance import (
    hull_distance_bounds,
    new_hints,
    new_simplex,
    stacked_points,
)
from kinegrasp_env.closing.link_geometry import LinkGeometry, robot_link_geometry
from kinegrasp_env.closing.rounded_links import core_layout
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics, rigid_inverse
from kinegrasp_env.world.objects import GraspObject

__all__ = ["RobotTableCheck", "TableCheck", "table_in_object"]

_CORNERS = np.array([[x, y, z] for x in (-1.0, 1.0) for y in (-1.0, 1.0) for z in (-1.0, 1.0)])


def table_in_object(obj: GraspObject) -> tuple[np.ndarray, np.ndarray]:
    """(the table box's centre pose in the object frame (4, 4), its half extents (3,),
    metres) of an object that stands on a table."""
    pose, half = obj.table.box(obj.pose)
    return obj.pose_inverse @ pose, half


class TableCheck:
    """The start check against an object's table for one robot's links.

    Args:
        geometry: link name -> its collision geometry (link frame).
        obj: the object (it must stand on a table).
    """

    def __init__(self, geometry: dict[str, LinkGeometry], obj: GraspObject) -> None:
        if obj.table is None:
            raise ValueError(f"object {obj.name!r} has no support table")
        box, self.half = table_in_object(obj)
        self._object_inverse = obj.pose_inverse
        self._to_box = rigid_inverse(box)
        self._box = stacked_points([_CORNERS * self.half])
        self._simplex = new_simplex()
        self._hulls = {link: g.hulls for link, g in geometry.items() if g.parts}
        self._cores = {link: [(core_layout(p), p.radius) for p in g.rounded]
                       for link, g in geometry.items() if g.rounded}
        self._balls = {link: g.sphere for link, g in geometry.items()}

    def robot_hits(self, kinematics: Kinematics, q: np.ndarray) -> np.ndarray:
        """(n,) bool: at configurations q (n, dof) some link (placed by ``kinematics``, the
        robot's, with the object where it stands) touches or enters the table."""
        links = list(self._balls)
        world = kinematics.forward(q, links)
        return self.any_hits(links, self._object_inverse @ np.stack([world[k] for k in links]))

    def any_hits(self, links: list[str], poses: np.ndarray) -> np.ndarray:
        """(n,) bool: some link of ``links`` (L) placed by object-frame poses (L, n, 4, 4)
        touches or enters the table."""
        hit = np.zeros(poses.shape[1], dtype=bool)
        for link, pose in zip(links, poses, strict=True):
            hit |= self.hits(link, pose)
        return hit

    def hits(self, link: str, poses: np.ndarray) -> np.ndarray:
        """(n,) bool: ``link`` placed by object-frame poses (n, 4, 4) touches or enters the
        table."""
        poses = self._to_box @ poses  # the box's frame: the box is [-half, half]
        centre, radius = self._balls[link]
        ball = poses[:, :3, :3] @ centre[0] + poses[:, :3, 3]
        outside = np.linalg.norm(np.maximum(np.abs(ball) - self.half, 0.0), axis=1)
        out = np.zeros(len(poses), dtype=bool)
        rows = np.flatnonzero(outside <= radius)
        if rows.size == 0:
            return out
        rot = np.ascontiguousarray(poses[rows, :3, :3])
        trans = np.ascontiguousarray(poses[rows, :3, 3])
        shapes = [(self._hulls[link], 0.0)] if link in self._hulls else []
        for hull, reach in shapes + self._cores.get(link, []):
            bound, travel = np.empty(rows.size), np.empty(rows.size)
            hull_distance_bounds(*hull, rot, trans, *self._box, np.zeros((rows.size, 3)), 0.0,
                                 new_hints(rows.size, hull, self._box), self._simplex, bound,
                                 travel, reach)  # only "within reach?" is asked
            out[rows[bound <= reach]] = True
        return out


class RobotTableCheck:
    """Which configurations of a robot start with a link in its object's support table: a
    simulation of the hand alone (the physics closing, the holding test) takes them as start
    collisions, as the kinematic engines do, without simulating them.

    Args:
        description: the robot.
        obj: the catalog object (without a table, no configuration is in it).
    """

    def __init__(self, description: RobotDescription, obj: GraspObject) -> None:
        self.check = (None if obj.table is None
                      else TableCheck(robot_link_geometry(description), obj))
        self.kinematics = Kinematics(description.model)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """(n,) bool: configuration i of q (n, dof) puts a link in the table."""
        q = np.atleast_2d(q)
        if self.check is None:
            return np.zeros(len(q), dtype=bool)
        return self.check.robot_hits(self.kinematics, q)
