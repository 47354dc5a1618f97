"""The pybullet dynamics world of a description robot's holding test: its hand, cut from the
robot's URDF, free-floating and held by a constraint, and one catalog object.

The hand is the subtree of the URDF below the description's ``palm_link`` (every link
beyond it and the joints between them, mimic tags kept), written to a temporary URDF
(:func:`hand_urdf`) whose root is a link of its own, ``kinegrasp_root``, fixed to the palm
frame with the identity transform and as heavy as
:data:`~kinegrasp_env.physics.pybullet_world.ROOT_MASS` (it stands in for the arm behind
the palm). Meshes are written as the absolute paths the
description resolved; the URDF's ``<contact>`` elements (soft contact stiffness and
damping, extra friction) are dropped, so every robot's contacts are the same rigid
contacts with the friction product mu (hand links 1.0, the object mu).

Hand and object are loaded with Bullet's polyhedral contact features
(``URDF_INITIALIZE_SAT_FEATURES``; the object as
:class:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld`):
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

import pybullet

from kinegrasp_env.physics.pybullet_world import (
    HAND_FLAGS,
    ROOT_INERTIA,
    ROOT_MASS,
    PhysicsWorld,
    WorldSettings,
)
from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.robot.catalog import as_description
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.objects import GraspObject, as_object
from kinegrasp_env.world.sim import body_indices

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
        description: the robot (or a catalog robot's name).
        obj: the catalog object (or its name; placed at ``obj.pose``).
        settings: :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings`.

    Attributes:
        joint_index, link_index: hand joint / link name -> pybullet index (the root: -1).
    """

    def __init__(self, description: RobotDescription | str, obj: GraspObject | str,
                 settings: WorldSettings | None = None) -> None:
        self.description = as_description(description)
        super().__init__(as_object(obj), settings)

    def _load_hand(self) -> int:
        bullet = self.bullet
        with tempfile.TemporaryDirectory(prefix="kinegrasp_hand_") as folder:
            path = Path(folder) / "hand.urdf"
            hand_urdf(self.description, path)
            with quiet_c_output():  # the mesh loader's notes (a missing texture) off stdout
                hand = bullet.loadURDF(str(path), useFixedBase=False, flags=HAND_FLAGS)
        self.joint_index, self.link_index = body_indices(bullet, hand, ROOT_LINK)
        for link in self.link_index.values():
            bullet.changeDynamics(hand, link, collisionMargin=0.0)
            bullet.changeDynamics(hand, link, lateralFriction=1.0)
            bullet.changeDynamics(hand, link, rollingFriction=0.0, spinningFriction=0.0)
        bullet.changeDynamics(hand, -1, linearDamping=0.0, angularDamping=0.0)
        # the root as its URDF states it (pybullet recomputes a link's inertia from its
        # collision shape, and the root has none: 6.7e-5 kg m^2 for 100 kg)
        bullet.changeDynamics(hand, -1, mass=ROOT_MASS, localInertiaDiagonal=[ROOT_INERTIA] * 3)
        for j in self.joint_index.values():  # no default velocity motors: ours drive
            bullet.setJointMotorControl2(hand, j, pybullet.VELOCITY_CONTROL, force=0.0)
        return hand
