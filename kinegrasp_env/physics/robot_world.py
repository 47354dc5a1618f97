"""The pybullet dynamics world of a description robot's holding test: its hand, cut from the
robot's URDF, free-floating and held by a constraint, and one catalog object.

The hand is the subtree of the URDF below the description's ``palm_link`` (every link
beyond it and the joints between them, mimic tags kept), written to a temporary URDF
(:func:`hand_urdf`) whose root is a link of its own, ``kinegrasp_root``, fixed to the palm
frame with the identity transform and as heavy as
:data:`~kinegrasp_env.physics.pybullet_world.ROOT_MASS` (it stands in for the arm behind
the palm, as the SDH world's hand root does). Meshes are written as the absolute paths the
description resolved; the URDF's ``<contact>`` elements (soft contact stiffness and
damping, extra friction) are dropped, so every robot's contacts are the same rigid
contacts with the friction product mu as the SDH world's (hand links 1.0, the object mu).

Hand and object are loaded with Bullet's polyhedral contact features
(``URDF_INITIALIZE_SAT_FEATURES``; the object from a URDF of its own with
:class:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld`'s shape, mass and inertia):
without them a flat pad pressed on a face touched it at one arbitrary corner of the overlap
(one contact record per pad, 11 mm from the patch centre on the Panda's cube grasps), with
them at the overlap's corners.

Everything else is :class:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld`'s: the anchor
constraint that holds the hand root at the palm pose the arm's forward kinematics gives,
the object as a rigid body of its exact convex parts (pinned while the hand closes), the
support table, the saved start state and the collision pass that drops contact caches.

The hand's motors and their limits: :mod:`~kinegrasp_env.physics.hand_motors`.
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pybullet
from scipy.spatial.transform import Rotation

from kinegrasp_env.physics.pybullet_world import (
    ROOT_INERTIA,
    ROOT_MASS,
    PhysicsWorld,
    WorldSettings,
    mass_properties,
    write_parts_obj,
)
from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sim import BulletWorld, body_indices, matrix_to_pose
from kinegrasp_env.world.table_probe import table_body

#: The root link of the cut-out hand (the palm frame).
ROOT_LINK = "kinegrasp_root"


def hand_urdf(description: RobotDescription, path: Path) -> None:
    """Write the hand below ``palm_link`` as a URDF of its own at ``path`` (module
    docstring)."""
    root = ET.parse(description.urdf).getroot()
    joints = root.findall("joint")
    below, frontier = set(), {description.palm_link}
    while frontier:
        frontier = {j.find("child").get("link") for j in joints
                    if j.find("parent").get("link") in frontier}
        below |= frontier
    keep = below | {description.palm_link}
    meshes = {(m.link, m.filename): m.path for m in description.meshes}
    robot = ET.Element("robot", name=f"{description.name}_hand")
    base = ET.SubElement(robot, "link", name=ROOT_LINK)
    inertial = ET.SubElement(base, "inertial")
    ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=repr(ROOT_MASS))
    ET.SubElement(inertial, "inertia", ixx=repr(ROOT_INERTIA), iyy=repr(ROOT_INERTIA),
                  izz=repr(ROOT_INERTIA), ixy="0", ixz="0", iyz="0")
    fixed = ET.SubElement(robot, "joint", name=f"{ROOT_LINK}_palm", type="fixed")
    ET.SubElement(fixed, "parent", link=ROOT_LINK)
    ET.SubElement(fixed, "child", link=description.palm_link)
    ET.SubElement(fixed, "origin", xyz="0 0 0", rpy="0 0 0")
    for link in root.findall("link"):
        if link.get("name") not in keep:
            continue
        for contact in link.findall("contact"):
            link.remove(contact)
        for mesh in link.iter("mesh"):
            mesh.set("filename", str(meshes[(link.get("name"), mesh.get("filename"))]))
        robot.append(link)
    for joint in joints:
        if joint.find("child").get("link") in below:
            robot.append(joint)
    ET.ElementTree(robot).write(path)


class RobotPhysicsWorld(PhysicsWorld):
    """A description robot's free hand, its anchor and one object (module docstring).

    Args:
        description: the robot.
        obj: the catalog object (placed at ``obj.pose``).
        settings: :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings`.

    Attributes:
        joint_index, link_index: hand joint / link name -> pybullet index (the root: -1).
    """

    def __init__(self, description: RobotDescription, obj: GraspObject,
                 settings: WorldSettings | None = None) -> None:
        BulletWorld.__init__(self, gui=False)  # PhysicsWorld's, with this robot's hand
        self.description, self.obj = description, obj
        self.settings = settings or WorldSettings()
        bullet = self.bullet
        bullet.setTimeStep(self.settings.time_step)
        bullet.setPhysicsEngineParameter(numSolverIterations=self.settings.solver_iterations,
                                         deterministicOverlappingPairs=1)
        self.bodies["hand"] = self._load_hand()
        self.mass, moments, self.inertial = mass_properties(obj, self.settings.object_density(obj))
        self.inertial_inverse = np.linalg.inv(self.inertial)
        self.bodies["object"] = self._object_body(moments)
        if obj.table is not None:
            self.bodies["table"] = table_body(bullet, obj, self.settings.friction)
            self.table_pose = bullet.getBasePositionAndOrientation(self.bodies["table"])
        self.pin: int | None = None
        self.anchor = bullet.createConstraint(self.hand, -1, -1, -1, pybullet.JOINT_FIXED,
                                              [0, 0, 0], [0, 0, 0], [0, 0, 0])
        bullet.setGravity(0, 0, 0)
        self.initial_state = bullet.saveState()

    def _object_body(self, moments: np.ndarray) -> int:
        """The object as :class:`PhysicsWorld` builds it (its convex parts, mass, inertia,
        friction), loaded from a URDF of its own with Bullet's polyhedral features (SAT) as
        the hand is: a flat pad pressed on a face then touches it at the corners of the
        overlap (a patch, up to four points), not at one arbitrary corner."""
        bullet, obj = self.bullet, self.obj
        free = self.settings.object_free
        xyz, rpy = self.inertial[:3, 3], Rotation.from_matrix(self.inertial[:3, :3]).as_euler("xyz")
        with tempfile.TemporaryDirectory(prefix="kinegrasp_parts_") as folder:
            parts = Path(folder) / f"{obj.name}_parts.obj"
            write_parts_obj(obj.parts, parts)
            path = Path(folder) / "object.urdf"
            path.write_text(
                f'<robot name="object"><link name="object"><inertial>'
                f'<origin xyz="{" ".join(map(repr, map(float, xyz)))}" '
                f'rpy="{" ".join(map(repr, map(float, rpy)))}"/>'
                f'<mass value="{self.mass if free else 0.0!r}"/>'
                f'<inertia ixx="{moments[0]!r}" iyy="{moments[1]!r}" izz="{moments[2]!r}" '
                f'ixy="0" ixz="0" iyz="0"/></inertial><collision><geometry>'
                f'<mesh filename="{parts}"/></geometry></collision></link></robot>')
            position, orientation = matrix_to_pose(obj.pose)
            body = bullet.loadURDF(str(path), position, orientation, useFixedBase=not free,
                                   flags=pybullet.URDF_INITIALIZE_SAT_FEATURES)
        bullet.changeDynamics(body, -1, collisionMargin=0.0, lateralFriction=self.settings.friction,
                              rollingFriction=0.0, spinningFriction=0.0, restitution=0.0,
                              linearDamping=0.0, angularDamping=0.0)
        return body

    def _load_hand(self) -> int:
        bullet = self.bullet
        with tempfile.TemporaryDirectory(prefix="kinegrasp_hand_") as folder:
            path = Path(folder) / "hand.urdf"
            hand_urdf(self.description, path)
            with quiet_c_output():  # the mesh loader's notes (a missing texture) off stdout
                hand = bullet.loadURDF(str(path), useFixedBase=False,
                                       flags=pybullet.URDF_INITIALIZE_SAT_FEATURES)
        self.joint_index, self.link_index = body_indices(bullet, hand, ROOT_LINK)
        for link in self.link_index.values():
            bullet.changeDynamics(hand, link, collisionMargin=0.0)
            bullet.changeDynamics(hand, link, lateralFriction=1.0)
            bullet.changeDynamics(hand, link, rollingFriction=0.0, spinningFriction=0.0)
        bullet.changeDynamics(hand, -1, linearDamping=0.0, angularDamping=0.0)
        for j in self.joint_index.values():  # no default velocity motors: ours drive
            bullet.setJointMotorControl2(hand, j, pybullet.VELOCITY_CONTROL, force=0.0)
        return hand
