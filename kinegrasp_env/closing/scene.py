"""A description robot and one object in a pybullet world: the robot's joint state, its
links' poses, and their distances to the object.

The whole robot (its URDF, fixed base at the world origin: the robot base frame) and the
object stand in one pybullet world, the object fixed (and its support table, where it has
one). A configuration q (the description's actuated vector) is set joint by joint, every
mimic joint from its driver (:meth:`~kinegrasp_env.robot.model.RobotModel.expand`).

A link's distance to the object is pybullet's closest-point distance, plus the collision
margins pybullet subtracts (:func:`hull_margin`; a link of boxes and meshes measured on
margin-free hulls of its parts: :meth:`RobotScene.box_hulls`); for a link made of capsules
and spheres alone, within :data:`~kinegrasp_env.closing.close_rules.EXACT_BAND` of the
object, the exact distance of its parts' core segments less their radii
(:meth:`RobotScene.rounded_pair`, as the fast closing computes it:
:mod:`~kinegrasp_env.closing.rounded_links`), so that where a rounded fingertip touches does
not depend on pybullet's convex-hull tolerance. A closing stages joint values
(:meth:`RobotScene.stage_joint_values`) that pybullet takes before its next query, and each
link's distance is measured once per state: a rounded link near contact is measured exactly
with no pybullet call at all where its exact distance settles the rule
(:meth:`RobotScene.surely_in_band`).

The closing that moves the fingers in this world: :mod:`~kinegrasp_env.closing.
generic_reference`.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_rules import EXACT_BAND, QUERY_DISTANCE
from kinegrasp_env.closing.finger_paths import joint_tree
from kinegrasp_env.closing.hand_errors import flange_link, hand_links
from kinegrasp_env.closing.link_geometry import robot_link_geometry
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.closing.table_check import table_in_object
from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import rigid_inverse
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sim import ObjectWorld, body_indices, matrix_to_pose, pybullet
from kinegrasp_env.world.table_body import table_body

GEOM_MESH = pybullet.GEOM_MESH

__all__ = ["BULLET_TOLERANCE", "RobotScene", "hull_margin"]

#: How far (metres) pybullet's distance of a rounded link to the object may be trusted to
#: lie from the exact one: its GJK tolerance was measured 8.3e-6 m off on capsules and convex
#: hulls; 2e-4 m leaves a margin of 24x.
BULLET_TOLERANCE = 2e-4
#: Where the margin-free hulls of box links wait between queries (:meth:`RobotScene.box_hulls`).
PARKED = (0.0, 0.0, -100.0)


def hull_margin(bullet, body: int, link: int) -> float:
    """The collision margin (metres) pybullet's distances subtract from a link's geometry:
    its reported margin when every collision shape of the link is a mesh (a convex hull,
    which Bullet inflates by the margin; the children of a link's compound shape keep the URDF
    importer's 1 mm whatever changeDynamics sets), else 0 (cylinders are shrunk by their
    margin and rounded by it at a rim, a sphere's or capsule's margin is its radius: their
    distances are exact, a cylinder's but near its rims; a link of boxes and meshes is
    measured on margin-free hulls of its parts instead: :meth:`RobotScene.box_hulls`)."""
    shapes = bullet.getCollisionShapeData(body, link)
    if shapes and all(shape[2] == GEOM_MESH for shape in shapes):
        return float(bullet.getDynamicsInfo(body, link)[11])
    return 0.0


class RobotScene(ObjectWorld):
    """A description robot (the whole URDF, fixed at the world origin) and one object.

    Attributes:
        description: the robot.
        obj: the catalog object (fixed at ``obj.pose``).
        joint_index: movable joint name -> pybullet joint index.
        link_index: link name -> pybullet link index (-1: the base link).
    """

    def __init__(self, description: RobotDescription, obj: GraspObject,
                 gui: bool = False) -> None:
        super().__init__(obj, gui)
        self.description = description
        self.model = description.model
        bullet = self.bullet
        # cylinders as written (pybullet otherwise meshes them coarsely); its mesh loader's
        # notes (a texture a material file names and the folder lacks) kept off stdout
        with quiet_c_output():
            robot = bullet.loadURDF(str(description.urdf), useFixedBase=True,
                                    flags=pybullet.URDF_USE_IMPLICIT_CYLINDER)
        self.bodies["robot"] = robot
        self.joint_index, self.link_index = body_indices(bullet, robot, self.model.base_link)
        for link in self.link_index.values():
            bullet.changeDynamics(robot, link, collisionMargin=0.0)
        self._table = None  # the support table: (body, its pose in the object frame)
        if obj.table is not None:
            self._table = (table_body(bullet, obj), table_in_object(obj)[0])
            self.bodies["table"] = self._table[0]
        self.margins = {(body, link): hull_margin(bullet, body, link)
                        for body, count in ((robot, bullet.getNumJoints(robot)),
                                            (self.bodies["object"],
                                             bullet.getNumJoints(self.bodies["object"])))
                        for link in range(-1, count)}
        if self._table is not None:
            self.margins[(self._table[0], -1)] = 0.0
        self.link_name = {index: name for name, index in self.link_index.items()}
        #: per link with a box shape: the bodies its distances are measured on
        self._hulls = self.box_hulls(robot)
        #: every movable joint's value as set (name -> radians or metres)
        self.values = {joint.name: 0.0 for joint in self.model.joints if joint.movable}
        self._tree = joint_tree(self.model, self.model.base_link)
        #: the rounded links' poses at the joint values set (:meth:`model_pose`)
        self._rounded_poses: dict[str, np.ndarray] | None = None
        #: joint values staged but not yet set in pybullet (pybullet joint index -> value)
        self._pending: dict[int, float] = {}
        #: per link, its gap and its exact pair at the current state (cleared on any change)
        self._gaps: dict[str, float] = {}
        self._pairs: dict[str, tuple] = {}
        #: rounded links within the exact band at their last measurement
        self._near: set[str] = set()
        #: the links made of capsules and spheres alone: their exact parts (link frame)
        self.rounded = {link: geometry.rounded
                        for link, geometry in robot_link_geometry(description).items()
                        if geometry.rounded and not geometry.parts}
        self._band = {link: min(EXACT_BAND, min(part.radius for part in parts))
                      for link, parts in self.rounded.items()}
        #: per rounded link, its parts' core ends (m, 3) each and radii (m,), link frame
        self._cores = {link: (np.array([p.a for p in parts]), np.array([p.b for p in parts]),
                              np.array([p.radius for p in parts]))
                       for link, parts in self.rounded.items()}
        self._rounded_links = list(self.rounded)
        hand = hand_links(description)
        self._flange = flange_link(description)
        self._arm_links = tuple(link for link in self.link_index if link not in hand)
        self._hand_links = tuple(sorted(hand))
        #: the object's pose in this world: ``obj.pose``, but where a palm or object error
        #: places it for a closing
        self.placed = obj.pose
        self._placed_inverse = rigid_inverse(obj.pose)

    # ------------------------------------------------------------------ state
    def set_configuration(self, q: np.ndarray) -> dict[str, float]:
        """Set every movable joint from the actuated vector q (dof,); returns the values."""
        values = {name: float(v) for name, v in self.model.expand(np.asarray(q, float)).items()}
        self.set_joint_values(values)
        return values

    def set_joint_values(self, values: dict[str, float]) -> None:
        """Set the named joints (name -> radians or metres); the others keep theirs."""
        self.stage_joint_values(values)
        self.sync()

    def stage_joint_values(self, values: dict[str, float]) -> None:
        """Set the named joints (name -> radians or metres) in the scene's state; pybullet
        takes them before its next query (:meth:`sync`), so a closing that measures a rounded
        link exactly costs no pybullet call."""
        changed = False
        for name, value in values.items():
            value = float(value)
            if self.values[name] != value:
                self.values[name] = value
                self._pending[self.joint_index[name]] = value
                changed = True
        if changed:
            self._forget()

    def sync(self) -> None:
        """Set the staged joint values in pybullet (one call)."""
        if self._pending:
            self.bullet.resetJointStatesMultiDof(self.bodies["robot"], list(self._pending),
                                                 [[v] for v in self._pending.values()])
            self._pending = {}

    def _forget(self) -> None:
        """Drop what was measured at the previous state."""
        self._rounded_poses = None
        self._gaps = {}
        self._pairs = {}

    def link_pose(self, link: str) -> np.ndarray:
        """(4, 4) world pose of a robot link's URDF frame (pybullet's kinematics; the base's
        from its centre-of-mass frame, which is what pybullet gives for a base, and its
        inertial offset)."""
        self.sync()
        bullet, robot = self.bullet, self.bodies["robot"]
        index = self.link_index[link]
        if index < 0:
            position, quaternion = bullet.getBasePositionAndOrientation(robot)
            offset = bullet.getDynamicsInfo(robot, -1)[3:5]  # inertial frame in the URDF's
            position, quaternion = bullet.multiplyTransforms(
                position, quaternion, *bullet.invertTransform(*offset))
        else:
            state = bullet.getLinkState(robot, index, computeForwardKinematics=True)
            position, quaternion = state[4], state[5]
        pose = np.eye(4)
        pose[:3, :3] = np.reshape(bullet.getMatrixFromQuaternion(quaternion), (3, 3))
        pose[:3, 3] = position
        return pose

    def closest(self, max_distance: float, link: str | None = None) -> list[tuple]:
        """pybullet closest points between the robot (or one of its links) and the object
        (rows as pybullet gives them; their distance: :meth:`distance`)."""
        self.sync()
        return self._rows(self.bodies["object"], max_distance, link)

    def _rows(self, other: int, max_distance: float, link: str | None = None) -> list[tuple]:
        """pybullet closest points between the robot (or one of its links) and body
        ``other``, a link with box shapes measured on its hulls (:meth:`box_hulls`)."""
        if link in self._hulls:
            return self._hull_rows(other, max_distance, link)
        kwargs = {} if link is None else {"linkIndexA": self.link_index[link]}
        rows = self.bullet.getClosestPoints(self.bodies["robot"], other, max_distance, **kwargs)
        if link is None and self._hulls:
            rows = [row for row in rows if self.link_name.get(row[3]) not in self._hulls]
            rows += [row for name in self._hulls
                     for row in self._hull_rows(other, max_distance, name)]
        return rows

    def box_hulls(self, robot: int) -> dict[str, list[int]]:
        """Per link of ``robot`` (its pybullet body) whose collision shapes are boxes (at least
        one) and meshes: a pybullet body for each convex part of its geometry
        (:func:`~kinegrasp_env.closing.link_geometry.robot_link_geometry`: the parts the fast
        closing measures), a convex hull of collision margin 0, parked out of the way. Its
        closest points are measured on them (:meth:`closest`, :meth:`in_table`): the URDF
        importer keeps a 1 mm margin on a box (the child of the link's compound shape, which
        changeDynamics does not reach), so pybullet measures a box shrunk by 1 mm and
        rounded by 1 mm at its edges and corners, exact only where a face is nearest (a pad
        tilted by t touching with an edge measured 1 mm x (cos t + sin t - 1) too far, its
        finger stopping late). A link that also has a sphere, capsule or cylinder keeps
        pybullet's own shapes (their distances are those its rounded parts need)."""
        bullet, out = self.bullet, {}
        geometry = robot_link_geometry(self.description)
        for name, index in self.link_index.items():
            kinds = {shape[2] for shape in bullet.getCollisionShapeData(robot, index)}
            if (name not in geometry or not geometry[name].parts
                    or pybullet.GEOM_BOX not in kinds
                    or not kinds <= {pybullet.GEOM_BOX, GEOM_MESH}):
                continue
            out[name] = []
            for part in geometry[name].parts:
                shape = bullet.createCollisionShape(pybullet.GEOM_MESH,
                                                    vertices=np.asarray(part.vertices).tolist())
                body = bullet.createMultiBody(0.0, shape, basePosition=PARKED)
                bullet.changeDynamics(body, -1, collisionMargin=0.0)
                out[name].append(body)
        return out

    def _hull_rows(self, other: int, max_distance: float, link: str) -> list[tuple]:
        """pybullet closest points between a link of :meth:`box_hulls` and body ``other``,
        on the link's margin-free hulls (placed at the link's pose for the query, parked
        again after it), as rows of the link itself (body and link index the robot's)."""
        position, orientation = matrix_to_pose(self.model_pose(link))
        robot, index, out = self.bodies["robot"], self.link_index[link], []
        for body in self._hulls[link]:
            self.bullet.resetBasePositionAndOrientation(body, position, orientation)
            for row in self.bullet.getClosestPoints(body, other, max_distance):
                out.append((row[0], robot, row[2], index, *row[4:]))
            self.bullet.resetBasePositionAndOrientation(body, PARKED, (0.0, 0.0, 0.0, 1.0))
        return out

    def distance(self, row: tuple) -> float:
        """The distance (metres) of the geometry of a closest-point row: pybullet's, plus
        the collision margins of the two shapes (which pybullet's distance subtracts)."""
        return (row[8] + self.margins[(row[1], row[3])] + self.margins[(row[2], row[4])])

    def bullet_gap(self, link: str) -> float:
        """pybullet's distance (metres, :meth:`distance`) of ``link`` to the object, capped
        at QUERY_DISTANCE."""
        return min((self.distance(row) for row in self.closest(QUERY_DISTANCE, link)),
                   default=QUERY_DISTANCE)

    def link_gap(self, link: str) -> float:
        """The distance (metres) of ``link`` to the object, capped at QUERY_DISTANCE:
        :meth:`bullet_gap`, or, for a link of rounded parts within :meth:`in_band` of the
        object, the exact one (:meth:`rounded_pair`: pybullet's distances of a capsule to a
        convex hull carry GJK's tolerance, 8.3e-6 m off measured, and its link frames are
        single precision)."""
        gap = self._gaps.get(link)
        if gap is not None:
            return gap
        if link in self._near:  # near contact before: the exact gap, where it settles it
            exact = self.rounded_pair(link)[0]
            if self.surely_in_band(link, exact):
                self._gaps[link] = exact
                return exact
        gap = self.bullet_gap(link)
        if self.in_band(link, gap):
            gap = min(self.rounded_pair(link)[0], QUERY_DISTANCE)
            self._near.add(link)
        else:
            self._near.discard(link)
        self._gaps[link] = gap
        return gap

    def gap(self, links: tuple[str, ...]) -> tuple[float, int]:
        """(smallest :meth:`link_gap` of ``links``, capped at QUERY_DISTANCE; queries)."""
        return min((self.link_gap(link) for link in links), default=QUERY_DISTANCE), len(links)

    def in_band(self, link: str, gap: float) -> bool:
        """Whether ``link`` is a rounded link whose pybullet ``gap`` (metres) puts it within
        the exact band of the object: above -:data:`~kinegrasp_env.closing.close_rules.
        EXACT_BAND` and below it, and less deep than its thinnest part's radius (deeper, its
        core could cross the object, where the exact pair is not exact)."""
        return link in self.rounded and -self._band[link] <= gap <= EXACT_BAND

    def surely_in_band(self, link: str, exact: float) -> bool:
        """Whether a rounded link's exact gap (metres) lies so far inside the exact band that
        pybullet's distance, within :data:`BULLET_TOLERANCE` of it, is in the band too: the
        exact gap is then the link's gap (:meth:`link_gap`) without asking pybullet."""
        return (-self._band[link] + BULLET_TOLERANCE <= exact
                <= EXACT_BAND - BULLET_TOLERANCE)

    def rounded_pair(self, link: str) -> tuple[float, np.ndarray, np.ndarray, int]:
        """(distance (metres), core point (3,), object point (3,), the object's convex part)
        of the closest pair of a rounded link (:attr:`rounded`) and the object, in the
        object's frame as placed (:attr:`placed`): the exact pair of each part's core
        segment (:func:`~kinegrasp_env.closing.segment_distance.closest_to_segments`), less
        its radius, the least over the parts. Exact where the cores are apart from the
        object (a rounded link near contact: its gap is its core's less a radius)."""
        pair = self._pairs.get(link)
        if pair is None:
            pair = self._pairs[link] = self._exact_pair(link)
        return pair

    def _exact_pair(self, link: str) -> tuple[float, np.ndarray, np.ndarray, int]:
        """:meth:`rounded_pair`, computed."""
        pose = self._placed_inverse @ self._rounded_pose(link)
        a, b, radii = self._cores[link]
        a = a @ pose[:3, :3].T + pose[:3, 3]
        b = b @ pose[:3, :3].T + pose[:3, 3]
        # beyond the exact band the pair is not needed: its distance is then a lower bound
        on_obj, on_core, distance, part = closest_to_segments(
            self.obj, a, b, float(radii.max()) + 2.0 * EXACT_BAND)
        gaps = distance - radii
        k = int(np.argmin(gaps))
        return float(gaps[k]), on_core[k], on_obj[k], int(part[k])

    def model_pose(self, link: str) -> np.ndarray:
        """(4, 4) world pose of ``link``'s URDF frame at the joint values set, by the
        robot model's own kinematics in double precision (one compiled pass:
        :func:`~kinegrasp_env.closing.finger_paths.joint_tree`; pybullet's link frames,
        :meth:`link_pose`, were measured up to 1e-7 m off them). The rounded links' poses
        are computed together, once per joint state."""
        if link not in self.rounded:
            values = np.array([[self.values[name] for name in self._tree.model.actuated]])
            return self._tree.pose(values, link)[0]
        return self._rounded_pose(link).copy()

    def _rounded_pose(self, link: str) -> np.ndarray:
        """:meth:`model_pose` of a rounded link, the cached array itself (not to be
        changed)."""
        if self._rounded_poses is None:
            values = np.array([[self.values[name] for name in self._tree.model.actuated]])
            self._rounded_poses = self._tree.forward(values, self._rounded_links)
        return self._rounded_poses[link][0]

    def penetrates(self, rows: list[tuple], start_tol: float) -> bool:
        """Whether some closest-point row (robot link and object) goes deeper than
        ``start_tol`` (metres) into the object: for a rounded link within the exact band,
        by :meth:`rounded_pair`'s distance (whichever side of ``start_tol`` pybullet's puts
        it), else by pybullet's."""
        for row in rows:
            depth = self.distance(row)
            link = self.link_name[row[3]]
            if self.in_band(link, depth):
                depth = self.rounded_pair(link)[0]
            if depth < -start_tol:
                return True
        return False

    def place_object(self, pose: np.ndarray) -> None:
        """The object body at ``pose`` (4, 4), where the contacts' frame follows it, and its
        support table with it."""
        self.placed = pose
        self._placed_inverse = rigid_inverse(pose)
        self._forget()
        position, orientation = matrix_to_pose(pose)
        self.bullet.resetBasePositionAndOrientation(self.bodies["object"], position,
                                                    orientation)
        if self._table is not None:
            self.bullet.resetBasePositionAndOrientation(
                self._table[0], *matrix_to_pose(pose @ self._table[1]))

    def in_table(self, links: tuple[str, ...] | None = None) -> bool:
        """Whether ``links`` (default: the whole robot) touch or enter the object's support
        table (pybullet's closest points at 0 m; never without a table)."""
        if self._table is None:
            return False
        self.sync()
        table = self._table[0]
        rows = (self._rows(table, 0.0) if links is None else
                [row for link in links for row in self._rows(table, 0.0, link)])
        return any(self.distance(row) <= 0.0 for row in rows)

