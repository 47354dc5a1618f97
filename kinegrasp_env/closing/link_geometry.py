"""A robot link's collision geometry for the fast generic closing: its hull vertices,
surface samples and convex parts in the link's frame (read once from pybullet), the distance
grid's error bound, and where a point lies along an edge."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env import jit
from kinegrasp_env.closing.capsule_gap import grid_arrays, posed_min_one
from kinegrasp_env.closing.contact_patch import link_hull_vertices
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.polytope import ConvexPart, face_planes
from kinegrasp_env.world.sdf import DistanceGrid

#: Spacing of the finger links' surface samples (metres): they bound the gap far from the
#: object, so the spacing sets only how soon the exact distance takes over.
FINGER_SPACING = 3.0e-3
#: Spacing of the other links' surface samples (metres): they screen start collisions.
ARM_SPACING = 6.0e-3
#: Edge of the cubes that group a link's samples into clusters (metres).
CLUSTER = 0.02


def grid_error(grid: DistanceGrid) -> float:
    """Bound (metres) on |trilinear grid value - exact distance| for a 1-Lipschitz distance
    with exact node values: sum_i w_i |x_i - x| <= sqrt(sum_k f_k (1 - f_k)) h <= h sqrt(3)/2."""
    return 0.5 * np.sqrt(3.0) * float(grid.spacing)


@dataclass(frozen=True)
class LinkGeometry:
    """One link's collision geometry in its URDF frame.

    Attributes:
        vertices: (V, 3) hull vertices of every collision shape, metres.
        points: (P, 3) surface samples (the vertices first), metres.
        spacing: the lattice spacing of the samples, metres.
        parts: each collision shape's hull as a :class:`~kinegrasp_env.world.polytope.
            ConvexPart` (exact closest points on it).
        clusters: the samples grouped for :func:`clustered_bound` (:func:`cluster_samples`).
    """

    vertices: np.ndarray
    points: np.ndarray
    spacing: float
    parts: tuple[ConvexPart, ...]
    clusters: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]

    @property
    def sphere(self) -> tuple[np.ndarray, float]:
        """((1, 3) centre, radius): a ball (metres) holding every point."""
        centre = 0.5 * (self.points.min(axis=0) + self.points.max(axis=0))
        return centre[None], float(np.linalg.norm(self.points - centre, axis=1).max())


def hull_samples(vertices: np.ndarray, spacing: float) -> np.ndarray:
    """(P, 3) points on the convex hull of ``vertices`` (V, 3): the vertices, then on every
    hull triangle rows parallel to its longest edge, ceil(height / spacing) + 1 rows of
    ceil(length / spacing) + 1 evenly spaced points each (every surface point within
    ``spacing`` of a sample)."""
    from scipy.spatial import ConvexHull

    hull = ConvexHull(vertices)
    out = [vertices[hull.vertices]]
    for tri in hull.simplices:
        p = vertices[tri]
        lengths = [np.linalg.norm(p[(i + 1) % 3] - p[i]) for i in range(3)]
        i = int(np.argmax(lengths))
        a, b, c = p[i], p[(i + 1) % 3], p[(i + 2) % 3]
        base = b - a
        height = np.linalg.norm(np.cross(base, c - a)) / max(lengths[i], 1e-300)
        rows = int(np.ceil(height / spacing))
        for w in np.linspace(0.0, 1.0, rows + 1):
            start, end = a + w * (c - a), b + w * (c - b)
            count = int(np.ceil(np.linalg.norm(end - start) / spacing)) + 1
            s = np.linspace(0.0, 1.0, count)[:, None]
            out.append(start + s * (end - start))
    return np.unique(np.round(np.vstack(out), 12), axis=0)


def link_geometry(description: RobotDescription, finger_spacing: float = FINGER_SPACING,
                  arm_spacing: float = ARM_SPACING) -> dict[str, LinkGeometry]:
    """Every link with collision geometry -> its :class:`LinkGeometry` (read from pybullet
    once, the robot at its open configuration; each shape's hull sampled on its own)."""
    from kinegrasp_env.quiet import quiet_c_output
    from kinegrasp_env.world.sim import BulletWorld

    with BulletWorld() as sim:  # a DIRECT client of its own, its banner kept off stdout
        bullet = sim.bullet
        with quiet_c_output():  # mesh-loader notes
            robot = bullet.loadURDF(str(description.urdf), useFixedBase=True)
        names = {-1: description.model.base_link}
        for j in range(bullet.getNumJoints(robot)):
            names[j] = bullet.getJointInfo(robot, j)[12].decode()
        hand = set(description.finger_links)
        out = {}
        for index, name in names.items():
            world = link_hull_vertices(bullet, robot, index)
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
            spacing = finger_spacing if name in hand else arm_spacing
            pieces, parts, start = [], [], 0
            for count in counts:
                shape = local[start:start + count]
                pieces.append(hull_samples(shape, spacing))
                parts.append(ConvexPart(shape, face_planes(shape)))
                start += count
            points = np.vstack([local, *pieces])
            out[name] = LinkGeometry(local, points, spacing, tuple(parts),
                                     cluster_samples(points))
        return out


def _shape_vertex_count(bullet, body: int, link: int, shape) -> int:
    """Vertices :func:`link_hull_vertices` gives one collision shape (its rows, in order)."""
    from kinegrasp_env.closing.contact_patch import _mesh_hull

    return 8 if shape[2] == 3 else len(_mesh_hull(shape[4].decode()))


@jit.kernel(_nrt=False)
def segment_holding(segments, x, y, z, tol, direction):
    """Index of the one segment of ``segments`` (E, 2, 3) whose interior holds the point
    (x, y, z) (within ``tol`` metres, not within ``tol`` of its ends), its unit direction in
    ``direction`` (3,); -1 where none, several, or the point lies at an end of one."""
    found = -1
    for e in range(segments.shape[0]):
        ax, ay, az = segments[e, 0, 0], segments[e, 0, 1], segments[e, 0, 2]
        dx, dy, dz = segments[e, 1, 0] - ax, segments[e, 1, 1] - ay, segments[e, 1, 2] - az
        if (np.sqrt((x - ax) ** 2 + (y - ay) ** 2 + (z - az) ** 2) < tol
                or np.sqrt((x - ax - dx) ** 2 + (y - ay - dy) ** 2 + (z - az - dz) ** 2) < tol):
            return -1
        length2 = dx * dx + dy * dy + dz * dz
        s = ((x - ax) * dx + (y - ay) * dy + (z - az) * dz) / max(length2, 1e-300)
        s = min(max(s, 0.0), 1.0)
        gap = np.sqrt((ax + s * dx - x) ** 2 + (ay + s * dy - y) ** 2 + (az + s * dz - z) ** 2)
        length = np.sqrt(length2)
        if gap < tol and s * length > tol and (1.0 - s) * length > tol:
            if found >= 0:
                return -1
            found = e
            direction[0], direction[1], direction[2] = dx / length, dy / length, dz / length
    return found


def edge_along(segments: np.ndarray, point: np.ndarray, tol: float = 1e-7
               ) -> np.ndarray | None:
    """(3,) unit direction of the one segment of ``segments`` (E, 2, 3) whose interior holds
    ``point`` (3,) (within ``tol`` metres, not within ``tol`` of its ends), or None
    (:func:`segment_holding`)."""
    direction = np.empty(3)
    found = segment_holding(segments, float(point[0]), float(point[1]), float(point[2]),
                            float(tol), direction)
    return None if found < 0 else direction


def cluster_samples(points: np.ndarray, size: float = CLUSTER
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Samples (P, 3) grouped by the cube of edge ``size`` (metres) they fall in: (centres
    (C, 3): each group's bounding-box centre, radii (C,): its largest distance to a sample of
    the group, starts (C + 1,) int64, the samples (P, 3) reordered group by group: group c is
    rows starts[c] .. starts[c + 1] - 1)."""
    keys = np.floor(points / size).astype(np.int64)
    _, group = np.unique(keys, axis=0, return_inverse=True)
    group = group.reshape(-1)
    order = np.argsort(group, kind="stable")
    ordered, group = points[order], group[order]
    starts = np.searchsorted(group, np.arange(group.max() + 2)).astype(np.int64)
    centres = np.empty((len(starts) - 1, 3))
    radii = np.empty(len(starts) - 1)
    for c in range(len(starts) - 1):
        chunk = ordered[starts[c]:starts[c + 1]]
        centres[c] = 0.5 * (chunk.min(axis=0) + chunk.max(axis=0))
        radii[c] = np.linalg.norm(chunk - centres[c], axis=1).max()
    return centres, radii, starts, np.ascontiguousarray(ordered)


@jit.kernel(_nrt=False)
def clustered_min(values, shape, origin, spacing, rot, trans, centres, radii, starts, points,
                  below, keys, out):
    """Per draw i (rot (n, 3, 3), trans (n, 3)): the smallest grid value over a link's
    samples, found cluster by cluster: a cluster's key is the grid value at its centre less
    its radius (below every value of its samples' true distances plus the grid's error);
    clusters are opened in increasing key order while their key is below both the best
    sample value so far and ``below``. out[i]: min(best sample value, smallest key left)."""
    count = centres.shape[0]
    for i in range(rot.shape[0]):
        for c in range(count):
            keys[c] = posed_min_one(values, shape, origin, spacing, rot[i], trans[i], centres,
                                    c, c + 1) - radii[c]
        best = np.inf
        while True:
            low, pick = np.inf, -1
            for c in range(count):
                if keys[c] < low:
                    low, pick = keys[c], c
            if pick < 0 or not (low < best and low < below):
                break
            value = posed_min_one(values, shape, origin, spacing, rot[i], trans[i], points,
                                  starts[pick], starts[pick + 1])
            best = min(best, value)
            keys[pick] = np.inf
        out[i] = min(best, low)


def clustered_bound(grid: DistanceGrid, poses: np.ndarray, geometry: LinkGeometry,
                    below: float = np.inf) -> np.ndarray:
    """(n,) lower bound (metres) of the exact distance of a link's hull to the object at
    object-frame poses (n, 4, 4): the least grid value over its samples less the grid's error
    (:func:`grid_error`) and the samples' spacing, clusters of samples whose centre bounds
    them all (:func:`clustered_min`) standing in for their samples where that bound is not
    below ``below`` (so the bound is the samples' own wherever it is below ``below``)."""
    slack = grid_error(grid) + geometry.spacing
    centres, radii, starts, points = geometry.clusters
    poses = np.asarray(poses, dtype=float)
    out = np.empty(poses.shape[0])
    clustered_min(*grid_arrays(grid), np.ascontiguousarray(poses[:, :3, :3]),
                  np.ascontiguousarray(poses[:, :3, 3]), centres, radii,
                  starts, points, float(below) + slack, np.empty(len(radii)), out)
    return out - slack
