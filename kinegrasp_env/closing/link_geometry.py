"""A robot link's collision geometry for the fast generic closing: its hull vertices and
convex parts in the link's frame (read once from pybullet), and the distance grid's error
bound."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.contact_patch import link_hull_vertices
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.polytope import ConvexPart, face_planes
from kinegrasp_env.world.sdf import DistanceGrid


def grid_error(grid: DistanceGrid) -> float:
    """Bound (metres) on |trilinear grid value - exact distance| for a 1-Lipschitz distance
    with exact node values: sum_i w_i |x_i - x| <= sqrt(sum_k f_k (1 - f_k)) h <= h sqrt(3)/2."""
    return 0.5 * np.sqrt(3.0) * float(grid.spacing)


@dataclass(frozen=True)
class LinkGeometry:
    """One link's collision geometry in its URDF frame.

    Attributes:
        vertices: (V, 3) hull vertices of every collision shape, metres.
        parts: each collision shape's hull as a :class:`~kinegrasp_env.world.polytope.
            ConvexPart` (exact closest points on it).
    """

    vertices: np.ndarray
    parts: tuple[ConvexPart, ...]

    @property
    def sphere(self) -> tuple[np.ndarray, float]:
        """((1, 3) centre, radius): a ball (metres) holding every hull."""
        centre = 0.5 * (self.vertices.min(axis=0) + self.vertices.max(axis=0))
        return centre[None], float(np.linalg.norm(self.vertices - centre, axis=1).max())


def link_geometry(description: RobotDescription, links: tuple[str, ...] | None = None, *,
                  skip_meshed: bool = False) -> dict[str, LinkGeometry]:
    """Every link with collision geometry (or those of ``links`` that have it) -> its
    :class:`LinkGeometry` (read from pybullet once, the robot at its open configuration);
    ``skip_meshed``: leave out a link with a shape pybullet meshed itself (a cylinder, whose
    vertices it does not give) instead of failing on it.

    Raises:
        ValueError: a collision mesh of a link read cannot be loaded."""
    from kinegrasp_env.quiet import quiet_c_output
    from kinegrasp_env.world.sim import BulletWorld

    with BulletWorld() as sim:  # a DIRECT client of its own, its banner kept off stdout
        bullet = sim.bullet
        with quiet_c_output():  # mesh-loader notes
            robot = bullet.loadURDF(str(description.urdf), useFixedBase=True)
        names = {-1: description.model.base_link}
        for j in range(bullet.getNumJoints(robot)):
            names[j] = bullet.getJointInfo(robot, j)[12].decode()
        out = {}
        for index, name in names.items():
            if links is not None and name not in links:
                continue
            world = link_hull_vertices(bullet, robot, index, skip_meshed=skip_meshed)
            if world is None:
                continue
            if index < 0:  # the base's URDF frame: the world origin (its fixed base)
                position, quaternion = (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)
            else:
                state = bullet.getLinkState(robot, index, computeForwardKinematics=True)
                position, quaternion = state[4], state[5]
            rot = np.reshape(bullet.getMatrixFromQuaternion(quaternion), (3, 3))
            local = (world - np.asarray(position)) @ rot
            counts = [_shape_vertex_count(bullet, robot, index, s)
                      for s in bullet.getCollisionShapeData(robot, index)]
            parts, start = [], 0
            for count in counts:
                shape = local[start:start + count]
                parts.append(ConvexPart(shape, face_planes(shape)))
                start += count
            out[name] = LinkGeometry(local, tuple(parts))
        return out


def _shape_vertex_count(bullet, body: int, link: int, shape) -> int:
    """Vertices :func:`link_hull_vertices` gives one collision shape (its rows, in order)."""
    from kinegrasp_env.closing.contact_patch import _mesh_hull

    return 8 if shape[2] == 3 else len(_mesh_hull(shape[4].decode()))
