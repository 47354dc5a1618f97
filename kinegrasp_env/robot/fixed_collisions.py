"""Collision shapes of links fixed below a finger's moving link, moved onto that link.

A finger touches the object with the links its closing joints move. Many grippers' URDFs
carry a finger's pad on a link of its own, fixed to the moving link (Robotiq-style
``*_pad`` links): rigidly the same body, but a closing that measures the moving link's gap
would never see the pad. ``kinegrasp robots add`` moves such a pad's ``<collision>``
elements onto the moving link in its copy of the URDF (:func:`move_fixed_collisions`),
each re-expressed in that link's frame (the fixed joints' origins down to the pad, then the
collision's own origin), so every engine and both simulators collide the same shapes at the
same place; the pad link keeps its visual and inertial elements. The user's files are never
changed. pybullet takes a link's inertia from its collision shapes, so there the moving
link's inertia becomes that of its shapes and the pad's.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation

from kinegrasp_env.robot.model import RobotModel, origin_matrix
from kinegrasp_env.robot.urdf_tree import UrdfTree


def pad_in_link(tree: UrdfTree, pad: str, link: str) -> np.ndarray:
    """(4, 4) the pose of link ``pad``'s frame in link ``link``'s frame: the product of the
    joints' origins from ``link`` down to ``pad`` (:meth:`~kinegrasp_env.robot.urdf_tree.
    UrdfTree.path_joints`; fixed joints, each at its origin; ValueError where a joint on
    that path moves)."""
    pose = np.eye(4)
    for joint in tree.path_joints(link, pad):
        if joint.movable:
            raise ValueError(f"link {pad!r} is not fixed below {link!r}")
        pose = pose @ joint.origin
    return pose


def origin_element(pose: np.ndarray) -> ET.Element:
    """A URDF ``<origin>`` element of the (4, 4) pose: xyz in metres, rpy the fixed-axis
    roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) in radians, each to full precision."""
    with warnings.catch_warnings():  # at pitch +-pi/2 the split of roll and yaw is arbitrary,
        warnings.simplefilter("ignore", UserWarning)  # and the rotation still exact
        rpy = Rotation.from_matrix(pose[:3, :3]).as_euler("xyz")
    return ET.Element("origin", {"xyz": " ".join(repr(float(v)) for v in pose[:3, 3]),
                                 "rpy": " ".join(repr(float(v)) for v in rpy)})


def move_fixed_collisions(text: str, model: RobotModel, pads: list[tuple[str, str]]) -> str:
    """The URDF ``text`` with each pad's ``<collision>`` elements moved onto its link, for
    (pad, link) in ``pads`` (pad fixed below link; ``model``: the URDF's model), re-expressed
    in the link's frame: the pad's frame in the link's (:func:`pad_in_link`) times the
    collision's own origin. The text is written anew: its comments kept, its XML
    declaration plain (UTF-8), its layout ElementTree's."""
    tree = UrdfTree(model, model.urdf_path, model.urdf_path.name)
    root = ET.fromstring(text, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    links = {element.get("name"): element for element in root.findall("link")}
    for pad, link in pads:
        to_link = pad_in_link(tree, pad, link)
        for collision in links[pad].findall("collision"):
            links[pad].remove(collision)
            old = collision.find("origin")
            pose = to_link @ origin_matrix(old)
            if old is not None:
                collision.remove(old)
            collision.insert(0, origin_element(pose))
            links[link].append(collision)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
