"""A robot link's collision geometry for the fast generic closing, read once from pybullet
(the URDF loaded with its cylinders implicit, as written), in the link's URDF frame:

* **polytopes** (:class:`~kinegrasp_env.world.polytope.ConvexPart`): a mesh's convex hull
  (scaled, as pybullet collides it), a box's corners, and a cylinder as the prism of
  :data:`CYLINDER_SIDES` sides inscribed in it (within r (1 - cos(pi / sides)) of it: 1.4e-5
  m for a 48 mm radius);
* **rounded parts** (:class:`RoundedPart`): a capsule (its axis segment and radius) or a
  sphere (a segment of one point): a ball swept along a segment, whose distance to the
  object is the segment's less the radius (exact). Their dimensions and placement are read
  from the URDF's own XML, in double precision (:func:`urdf_rounded_parts`), where pybullet's
  reports are single precision (1.3e-8 m off).

And the distance grid's error bound."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from kinegrasp_env.closing.contact_patch import mesh_hull
from kinegrasp_env.closing.convex_distance import stacked_faces, stacked_vertices
from kinegrasp_env.closing.packed_geometry import pack_each
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.polytope import ConvexPart, face_planes
from kinegrasp_env.world.sdf import DistanceGrid

#: Sides of the prism a cylinder is read as.
CYLINDER_SIDES = 128
#: pybullet's collision shape kinds (``getCollisionShapeData``'s third entry).
GEOM_SPHERE, GEOM_BOX, GEOM_CYLINDER, GEOM_MESH, GEOM_CAPSULE = 2, 3, 4, 5, 7


def grid_error(grid: DistanceGrid) -> float:
    """Bound (metres) on |trilinear grid value - exact distance| for a 1-Lipschitz distance
    with exact node values: sum_i w_i |x_i - x| <= sqrt(sum_k f_k (1 - f_k)) h <= h sqrt(3)/2."""
    return 0.5 * np.sqrt(3.0) * float(grid.spacing)


@dataclass(frozen=True)
class RoundedPart:
    """A ball of ``radius`` (metres) swept along the segment [a, b] ((3,) each, link frame):
    a capsule, or a sphere where a == b."""

    a: np.ndarray
    b: np.ndarray
    radius: float

    def box_corners(self) -> np.ndarray:
        """(8, 3) corners of an axis-aligned box holding the part (link frame)."""
        lo = np.minimum(self.a, self.b) - self.radius
        hi = np.maximum(self.a, self.b) + self.radius
        return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                         for z in (lo[2], hi[2])])


@dataclass(frozen=True)
class LinkGeometry:
    """One link's collision geometry in its URDF frame.

    Attributes:
        vertices: (V, 3) hull vertices of every polytope shape, metres (V = 0 for a link
            of rounded parts alone).
        parts: each polytope shape's hull as a :class:`~kinegrasp_env.world.polytope.
            ConvexPart` (exact closest points on it).
        rounded: the capsules and spheres (:class:`RoundedPart`).
        curved: some shape is a cylinder, capsule or sphere (its contacts are points: no
            flat pad to place a patch on).
        hulls: the polytopes' vertices as GJK reads them (:func:`~kinegrasp_env.closing.
            convex_distance.stacked_vertices`), None without polytopes.
        faces: their face planes and edges as the exact distances read them
            (:func:`~kinegrasp_env.closing.convex_distance.stacked_faces`), None without.
    """

    vertices: np.ndarray
    parts: tuple[ConvexPart, ...]
    rounded: tuple[RoundedPart, ...] = ()
    curved: bool = False
    hulls: tuple | None = field(init=False, default=None, repr=False)
    faces: tuple | None = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        if self.parts:
            object.__setattr__(self, "hulls", stacked_vertices(self.parts))
            object.__setattr__(self, "faces", stacked_faces(self.parts))

    @cached_property
    def packed(self) -> tuple[tuple, ...]:
        """Each polytope packed as one part for the exact segment search (its
        :func:`~kinegrasp_env.closing.packed_geometry.parts_tuple`), built on first use and
        kept (the geometry is read once per robot and process)."""
        return pack_each(self.parts)

    def placed_vertices(self, poses: np.ndarray) -> np.ndarray:
        """(..., V, 3) :attr:`vertices` placed by the link's poses (..., 4, 4) (in the frame
        the poses are given in, metres)."""
        return (self.vertices @ np.swapaxes(poses[..., :3, :3], -1, -2)
                + poses[..., None, :3, 3])

    @property
    def extent_points(self) -> np.ndarray:
        """(K, 3) points whose convex hull holds the whole link (the polytopes' vertices and
        a box around each rounded part): what bounds its reach and its bounding ball."""
        return np.vstack([self.vertices, *(r.box_corners() for r in self.rounded)])

    @property
    def sphere(self) -> tuple[np.ndarray, float]:
        """((1, 3) centre, radius): a ball (metres) holding every shape."""
        points = self.extent_points
        centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
        return centre[None], float(np.linalg.norm(points - centre, axis=1).max())


def cylinder_prism(length: float, radius: float, sides: int = CYLINDER_SIDES) -> np.ndarray:
    """(2 sides, 3) vertices of the prism inscribed in a cylinder about z (its frame)."""
    theta = 2.0 * np.pi * np.arange(sides) / sides
    ring = np.stack([radius * np.cos(theta), radius * np.sin(theta)], axis=1)
    return np.vstack([np.column_stack([ring, np.full(sides, z)])
                      for z in (-0.5 * length, 0.5 * length)])


def _shapes(bullet, robot: int, index: int
            ) -> tuple[list[np.ndarray], list[RoundedPart], bool]:
    """(polytope vertices (V_k, 3) per shape, rounded parts, some shape is curved) of link
    ``index``, in its URDF frame; ValueError for a mesh that cannot be loaded."""
    def matrix(position, quaternion) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3] = np.reshape(bullet.getMatrixFromQuaternion(quaternion), (3, 3))
        out[:3, 3] = position
        return out

    if index < 0:  # the base: its inertial frame and its URDF frame are the world's here
        inertial = link = np.eye(4)
    else:
        state = bullet.getLinkState(robot, index, computeForwardKinematics=True)
        inertial, link = matrix(state[0], state[1]), matrix(state[4], state[5])
    to_link = np.linalg.inv(link) @ inertial  # in double precision, as the kinematics
    polytopes, rounded, curved = [], [], False
    for shape in bullet.getCollisionShapeData(robot, index):
        kind, dims, filename = shape[2], np.asarray(shape[3], dtype=float), shape[4].decode()
        frame = to_link @ matrix(shape[5], shape[6])
        rot, origin = frame[:3, :3], frame[:3, 3]
        if kind in (GEOM_CAPSULE, GEOM_SPHERE):
            half = 0.5 * dims[0] * rot[:, 2] if kind == GEOM_CAPSULE else np.zeros(3)
            radius = dims[1] if kind == GEOM_CAPSULE else dims[0]
            rounded.append(RoundedPart(origin - half, origin + half, float(radius)))
            continue
        if kind == GEOM_MESH:
            try:
                local = mesh_hull(filename) * dims
            except (OSError, ValueError) as exc:
                raise ValueError(f"collision mesh {filename!r} cannot be loaded: {exc}") from None
        elif kind == GEOM_BOX:  # full extents
            local = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1)
                              for z in (-1, 1)]) * (0.5 * dims)
        elif kind == GEOM_CYLINDER:
            local, curved = cylinder_prism(dims[0], dims[1]), True
        else:
            raise ValueError(f"collision shape kind {kind} is not read (boxes, meshes, "
                             "cylinders, capsules and spheres are)")
        polytopes.append(local @ rot.T + origin)
    return polytopes, rounded, curved or bool(rounded)


def urdf_rounded_parts(urdf: str) -> dict[str, list[RoundedPart]]:
    """Link name -> its capsules and spheres, in the order of its ``<collision>`` elements,
    read from the URDF file ``urdf`` (link frame, metres; a capsule's ``length`` is the
    distance between its spheres' centres, along the z axis of its ``<origin>``)."""
    import xml.etree.ElementTree as ET

    from kinegrasp_env.robot.model import rpy_to_matrix

    out: dict[str, list[RoundedPart]] = {}
    for link in ET.parse(urdf).getroot().iter("link"):
        parts = []
        for collision in link.findall("collision"):
            geometry = collision.find("geometry")
            shape = geometry[0] if geometry is not None and len(geometry) else None
            if shape is None or shape.tag not in ("capsule", "sphere"):
                continue
            origin = collision.find("origin")
            xyz = np.array([float(v) for v in (origin.get("xyz", "0 0 0") if origin is not None
                                               else "0 0 0").split()])
            rpy = [float(v) for v in (origin.get("rpy", "0 0 0") if origin is not None
                                      else "0 0 0").split()]
            radius = float(shape.get("radius"))
            half = (0.5 * float(shape.get("length")) * rpy_to_matrix(*rpy)[:, 2]
                    if shape.tag == "capsule" else np.zeros(3))
            parts.append(RoundedPart(xyz - half, xyz + half, radius))
        if parts:
            out[link.get("name")] = parts
    return out


_ROBOT_GEOMETRY: dict[tuple[str, str], dict[str, LinkGeometry]] = {}


def robot_link_geometry(description: RobotDescription) -> dict[str, LinkGeometry]:
    """:func:`link_geometry` of every link of the robot, read once per URDF file and
    process (the closings of every object share it)."""
    key = (description.name, str(description.urdf))
    if key not in _ROBOT_GEOMETRY:
        _ROBOT_GEOMETRY[key] = link_geometry(description)
    return _ROBOT_GEOMETRY[key]


def link_geometry(description: RobotDescription, links: tuple[str, ...] | None = None
                  ) -> dict[str, LinkGeometry]:
    """Every link with collision geometry (or those of ``links`` that have it) -> its
    :class:`LinkGeometry` (read from pybullet once, the robot at its open configuration).

    Raises:
        ValueError: a collision mesh of a link read cannot be loaded."""
    import pybullet

    from kinegrasp_env.quiet import quiet_c_output
    from kinegrasp_env.world.sim import BulletWorld

    with BulletWorld() as sim:  # a DIRECT client of its own, its banner kept off stdout
        bullet = sim.bullet
        with quiet_c_output():  # mesh-loader notes
            robot = bullet.loadURDF(str(description.urdf), useFixedBase=True,
                                    flags=pybullet.URDF_USE_IMPLICIT_CYLINDER)
        names = {-1: description.model.base_link}
        for j in range(bullet.getNumJoints(robot)):
            names[j] = bullet.getJointInfo(robot, j)[12].decode()
        exact = urdf_rounded_parts(str(description.urdf))
        out = {}
        for index, name in names.items():
            if links is not None and name not in links:
                continue
            polytopes, rounded, curved = _shapes(bullet, robot, index)
            if len(exact.get(name, ())) == len(rounded):  # the XML's, in double precision
                rounded = exact.get(name, [])
            if not polytopes and not rounded:
                continue
            parts = tuple(ConvexPart(v, face_planes(v)) for v in polytopes)
            vertices = np.vstack(polytopes) if polytopes else np.empty((0, 3))
            out[name] = LinkGeometry(vertices, parts, tuple(rounded), curved)
        return out
