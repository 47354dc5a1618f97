"""Contacts from pybullet's own collision queries: a reference independent of both engines.

Both engines stop the fingers and place the contacts with the same exact near-contact
geometry (:mod:`kinegrasp_env.closing.segment_distance`,
:mod:`kinegrasp_env.closing.hand_geometry`) and score them with the same
:func:`~kinegrasp_env.montecarlo.description_engine.score_batch`, so their agreement says that the
batched closing finds the contacts of the per-draw one, not that the contacts are right. Here
a draw's final configuration (the arm joints and the closed hand,
:attr:`~kinegrasp_env.montecarlo.draws.DrawBatch.hand`) is placed in a pybullet world of its
own (the full arm+hand URDF, pybullet doing the forward kinematics) and every finger link's
collision capsule is queried against the object's convex parts with ``getClosestPoints``: a
link within :data:`TOUCH_DISTANCE` touches; its contact is pybullet's closest point on the
object, its inward normal minus pybullet's ``contactNormalOnB`` (which points from the object,
B, towards the finger, A), and Q follows from
:func:`kinegrasp_env.quality.epsilon.ferrari_canny`. Start collisions are decided from
pybullet too, at the draw's pre-grasp configuration, from every hand link (the palm and
knuckle cylinders as pybullet's implicit cylinders, not its default tessellation).

The object's parts are static bodies of their own (:func:`object_part_bodies`), not the links
of one body: pybullet keeps its default 1 mm collision margin on a multi-link body's links
whatever ``changeDynamics`` asks.

Shared with the engines: the object's convex parts, the URDF, the coupled-joint rule
(``RobotModel.expand``), the tolerance constants and the quality measure. Not shared: forward
kinematics, distances, contact points, normals.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.assets import asset_path
from kinegrasp_env.closing.close_rules import CONTACT_TOL, START_TOL
from kinegrasp_env.montecarlo.draws import (
    FORCE_CLOSURE,
    MISSED,
    NO_FORCE_CLOSURE,
    START_COLLISION,
)
from kinegrasp_env.quality.epsilon import ferrari_canny
from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.robot.default_robot import ARM_JOINTS, FINGERS, kuka_sdh, urdf_path
from kinegrasp_env.world.objects import GraspObject, load_object
from kinegrasp_env.world.sim import BulletWorld, body_indices, matrix_to_pose

with quiet_c_output():  # pybullet prints its build time on import
    import pybullet

#: A finger link whose pybullet distance to the object is at most this touches (metres): the
#: engines' own rule (``CONTACT_TOL``). After the closing polish the contact that stopped a
#: finger is at gap zero, but a second link of the same finger touching at the same time may
#: be anywhere within the tolerance.
TOUCH_DISTANCE = CONTACT_TOL
#: Radius of the sphere that probes a point's distances, and how far outside the object it
#: measures the distance to the object from (metres; both taken back off).
PROBE_RADIUS = 1e-5
PROBE_LIFT = 1e-4
#: Contact slots of a draw: one per phalanx (two on each of the default robot's three
#: fingers: the links its closing moves and stops).
MAX_CONTACTS = 2 * len(FINGERS)
#: Outcome of a draw whose engine gave no closed configuration (a start collision there)
#: while pybullet sees none: the reference cannot place its contacts.
UNDETERMINED = -1


@dataclass
class BulletContacts:
    """The pybullet-only contacts and outcomes of n draws.

    Attributes:
        outcome: (n,) int8 index into ``OUTCOMES`` (or :data:`UNDETERMINED`).
        quality: (n,) Ferrari-Canny Q (0 unless force closure).
        n_contacts: (n,) touching finger links.
        points: (n, 6, 3) pybullet's closest points on the object (object frame, metres).
        normals: (n, 6, 3) inward unit normals (object frame).
        distance: (n, 6) pybullet's link-object distances (metres; < 0: penetration).
        finger, link: (n, 6) int8 finger 0-2 and link (0 proximal, 1 distal), -1 padded.
        Contacts are ordered finger-major, proximal before distal, as in the engines.
    """

    outcome: np.ndarray
    quality: np.ndarray
    n_contacts: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    distance: np.ndarray
    finger: np.ndarray
    link: np.ndarray

    @classmethod
    def empty(cls, n: int) -> BulletContacts:
        return cls(np.full(n, UNDETERMINED, np.int8), np.zeros(n), np.zeros(n, np.int16),
                   np.full((n, MAX_CONTACTS, 3), np.nan), np.full((n, MAX_CONTACTS, 3), np.nan),
                   np.full((n, MAX_CONTACTS), np.nan), np.full((n, MAX_CONTACTS), -1, np.int8),
                   np.full((n, MAX_CONTACTS), -1, np.int8))


class BulletContactReference:
    """The arm+hand and one catalog object in a pybullet world of their own.

    Args:
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure.
        touch: :data:`TOUCH_DISTANCE` (metres).
    """

    def __init__(self, object_name: str, friction: float = 0.5, num_edges: int = 8,
                 touch: float = TOUCH_DISTANCE) -> None:
        self.obj = load_object(object_name)
        self.friction, self.num_edges, self.touch = friction, num_edges, touch
        self.model = kuka_sdh()
        self.world = BulletWorld()
        bullet = self.world.bullet
        self.robot = bullet.loadURDF(str(urdf_path()), useFixedBase=True,
                                     flags=pybullet.URDF_USE_IMPLICIT_CYLINDER)
        self.joint_index, link_index = body_indices(bullet, self.robot, self.model.base_link)
        for link in link_index.values():
            bullet.changeDynamics(self.robot, link, collisionMargin=0.0)
        self.parts = object_part_bodies(self.world, self.obj)
        #: (finger, link, pybullet link index) of the six finger links
        self.finger_links = [(f, k, link_index[FINGERS[f][2 + k]]) for f in range(3)
                             for k in range(2)]
        self.link_of = {(f, k): index for f, k, index in self.finger_links}
        # a small sphere that measures a point's distances (see probe_point)
        sphere = bullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=PROBE_RADIUS)
        self.probe = bullet.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=sphere,
                                            basePosition=[0.0, 0.0, -10.0])
        bullet.changeDynamics(self.probe, -1, collisionMargin=0.0)
        hand = hand_link_names()
        #: pybullet indices of the hand's links that have a collision shape
        self.hand_links = [j for name, j in link_index.items()
                           if name in hand and bullet.getCollisionShapeData(self.robot, j)]

    def close(self) -> None:
        self.world.close()

    def place(self, q: np.ndarray) -> None:
        """Set the robot's joints to the actuated configuration q (14,) (radians)."""
        bullet = self.world.bullet
        for name, value in self.model.expand(q).items():
            bullet.resetJointState(self.robot, self.joint_index[name], float(value))

    def nearest(self, link: int, max_distance: float) -> tuple | None:
        """pybullet's closest-point record of a robot link and the object (the nearest over
        the object's parts), or None when farther than ``max_distance`` (metres)."""
        bullet = self.world.bullet
        records = [rec for part in self.parts for rec in bullet.getClosestPoints(
            self.robot, part, max_distance, linkIndexA=link)]
        return min(records, key=lambda r: r[8]) if records else None

    def start_collision(self, q: np.ndarray) -> bool:
        """True when a hand link penetrates the object by more than ``START_TOL`` at the
        configuration q (14,) (the draw's pre-grasp one)."""
        self.place(q)
        return any((rec := self.nearest(link, 0.0)) is not None and rec[8] < -START_TOL
                   for link in self.hand_links)

    def link_contacts(self, q: np.ndarray) -> list[tuple[int, int, np.ndarray, np.ndarray,
                                                           float]]:
        """Touching finger links at the closed configuration q (14,): (finger, link, point
        (3,) on the object, inward normal (3,), distance), object frame, metres."""
        self.place(q)
        rotation = self.obj.pose_inverse[:3, :3]
        contacts = []
        for finger, link, index in self.finger_links:
            rec = self.nearest(index, self.touch)
            if rec is None or rec[8] > self.touch:
                continue
            # rec: positionOnA (finger), positionOnB (object), contactNormalOnB (B -> A)
            point = self.obj.to_object(np.asarray(rec[6]))
            inward = -(rotation @ np.asarray(rec[7]))
            contacts.append((finger, link, point, inward / np.linalg.norm(inward), rec[8]))
        return contacts

    def probe_point(self, point: np.ndarray, link: int) -> tuple[float, float, np.ndarray]:
        """pybullet's view of a point (3,) (object frame) at the current configuration: its
        distance to a robot link (metres), the direction d (3,) from that link towards it
        (object frame: the object's inward normal if the point is where the link touches the
        object), and its distance to the object, measured from ``PROBE_LIFT`` outside along
        -d (a probe centred on the surface would need pybullet's penetration depth, which
        is off by up to 0.5 mm at edges; from outside it is the exact GJK distance)."""
        bullet = self.world.bullet

        def move(position: np.ndarray) -> None:
            world = self.obj.to_world(position[None])[0]
            bullet.resetBasePositionAndOrientation(self.probe, world.tolist(), [0, 0, 0, 1])

        point = np.asarray(point, dtype=float)
        move(point)
        rec = min(bullet.getClosestPoints(self.probe, self.robot, 1.0, linkIndexB=link),
                  key=lambda r: r[8])
        # rec's contactNormalOnB points from the link (B) towards the probe (A)
        direction = self.obj.pose_inverse[:3, :3] @ np.asarray(rec[7])
        direction /= np.linalg.norm(direction)
        move(point - PROBE_LIFT * direction)
        to_object = min(r[8] for part in self.parts
                        for r in bullet.getClosestPoints(self.probe, part, 1.0))
        return rec[8] + PROBE_RADIUS, to_object + PROBE_RADIUS - PROBE_LIFT, direction

    def check_contacts(self, q: np.ndarray, draws) -> tuple[np.ndarray, np.ndarray]:
        """Each contact of an engine's ``draws`` (a ``DrawBatch`` of the configurations q
        (n, 14)) held to pybullet's geometry at the engine's closed configuration.

        Returns (n, 6) offsets: max(|distance to the object|, |distance to its link - that
        link's distance to the object|), metres, zero for any closest point of the link and
        the object; and (n, 6) angles (degrees) between the contact's normal and pybullet's
        direction from the link to the point. NaN where there is no contact.

        Unlike a comparison with pybullet's own closest point, this holds also where the
        closest point is not unique: a finger lying along a face touches along a line, one
        across a seam of two convex parts touches both, and pybullet may pick another point.
        """
        offsets = np.full(draws.finger.shape, np.nan)
        angles = np.full(draws.finger.shape, np.nan)
        for i in np.flatnonzero(draws.n_contacts > 0):
            self.place(np.concatenate([q[i, :len(ARM_JOINTS)], draws.hand[i]]))
            for j in range(draws.n_contacts[i]):
                link = self.link_of[(int(draws.finger[i, j]), int(draws.link[i, j]))]
                gap = self.nearest(link, 1.0)[8]
                to_link, to_object, direction = self.probe_point(draws.points[i, j], link)
                offsets[i, j] = max(abs(to_object), abs(to_link - gap))
                cosine = np.clip(direction @ draws.normals[i, j], -1.0, 1.0)
                angles[i, j] = np.degrees(np.arccos(cosine))
        return offsets, angles

    def run(self, q: np.ndarray, hand: np.ndarray) -> BulletContacts:
        """Outcomes of draws with pre-grasp configurations q (n, 14) whose hands closed to
        ``hand`` (n, 7) (``DrawBatch.hand``; NaN rows: the engine saw a start collision)."""
        q, hand = np.atleast_2d(q), np.atleast_2d(hand)
        out = BulletContacts.empty(len(q))
        for i in range(len(q)):
            if self.start_collision(q[i]):
                out.outcome[i] = START_COLLISION
            elif np.isfinite(hand[i]).all():
                closed = np.concatenate([q[i, :len(ARM_JOINTS)], hand[i]])
                self._fill(out, i, self.link_contacts(closed))
        return out

    def _fill(self, out: BulletContacts, i: int, contacts: list) -> None:
        """Draw i's contacts, outcome and Q."""
        k = min(len(contacts), MAX_CONTACTS)
        out.n_contacts[i] = k
        for j, (finger, link, point, normal, distance) in enumerate(contacts[:k]):
            out.finger[i, j], out.link[i, j] = finger, link
            out.points[i, j], out.normals[i, j], out.distance[i, j] = point, normal, distance
        every_finger = len({c[0] for c in contacts}) == 3
        out.outcome[i] = MISSED if k < 2 or not every_finger else NO_FORCE_CLOSURE
        if out.outcome[i] == NO_FORCE_CLOSURE:
            out.quality[i] = ferrari_canny(
                out.points[i, :k], out.normals[i, :k], friction=self.friction,
                num_edges=self.num_edges, torque_scale=self.obj.torque_scale,
                center=self.obj.center_of_mass)
            if out.quality[i] > 0:
                out.outcome[i] = FORCE_CLOSURE


def hand_link_names() -> set[str]:
    """Names of the links of the hand alone (``sdh_hand.urdf``)."""
    root = ET.parse(asset_path("robots", "sdh_hand.urdf")).getroot()
    return {link.get("name") for link in root.findall("link")}


def object_part_bodies(world: BulletWorld, obj: GraspObject) -> list[int]:
    """The object's convex parts as static bodies of their own (at ``obj.pose``), margins zero.

    One body per part, not one multi-link body as in
    :class:`~kinegrasp_env.world.sim.ObjectWorld`: pybullet keeps its default 1 mm collision
    margin on the links of a multi-link body whatever ``changeDynamics`` sets (measured: the
    parts after the first report distances 1e-3 m short and closest points 1e-3 m outside the
    surface), while a base's margin does go to zero.
    """
    bullet = world.bullet
    position, orientation = matrix_to_pose(obj.pose)
    bodies = []
    for i, part in enumerate(obj.parts):
        shape = bullet.createCollisionShape(pybullet.GEOM_MESH, vertices=part.tolist())
        body = bullet.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape,
                                      basePosition=position, baseOrientation=orientation)
        bullet.changeDynamics(body, -1, collisionMargin=0.0)
        world.bodies[f"part_{i}"] = body
        bodies.append(body)
    return bodies
