"""Where a palm or an object pose error puts a robot's links relative to the object.

A palm error P (4, 4) is the hand's rigid error relative to the flange, in the flange frame:
the hand root truly is at W_F P, with W_F the flange's pose from the arm's kinematics. An
object error D (4, 4) is the object's, in the frame it was believed at: the object truly is
at W_O D, with W_O the believed pose. Closing and scoring only need every link's pose in the
true object's frame, so the object stays where it was believed to be and the links move:

* an arm link (every link but the hand's) at world pose W: D^-1 W_O^-1 W
  (:func:`arm_to_object`);
* a hand link: D^-1 W_O^-1 W_F P W_F^-1 W (:func:`world_to_object`), the hand root itself
  at X = D^-1 W_O^-1 W_F P (:func:`hand_in_object`).

For a description robot the flange is the child link of the last arm joint and the hand is
the palm link with every link below it (:func:`hand_links`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import rigid_inverse


def hand_in_object(flange: np.ndarray, object_pose: np.ndarray, palm: np.ndarray | None,
                   object_offset: np.ndarray | None) -> np.ndarray:
    """X (n, 4, 4): the hand root in the true object's frame, D^-1 W_O^-1 W_F P, for flange
    poses W_F (n, 4, 4), the believed object pose W_O (4, 4), palm errors P and object
    errors D (n, 4, 4; None = identity)."""
    rel = rigid_inverse(object_pose) @ flange
    if palm is not None:
        rel = rel @ palm
    if object_offset is not None:
        rel = rigid_inverse(object_offset) @ rel
    return rel


def world_to_object(flange: np.ndarray, object_pose: np.ndarray, palm: np.ndarray | None,
                    object_offset: np.ndarray | None) -> np.ndarray:
    """M (n, 4, 4) = X W_F^-1: maps a hand link's world pose from the arm's kinematics
    (W_F times the link's pose in the hand) to its pose in the true object's frame."""
    return hand_in_object(flange, object_pose, palm, object_offset) @ rigid_inverse(flange)


def arm_to_object(object_pose: np.ndarray, object_offset: np.ndarray | None,
                  n: int) -> np.ndarray:
    """(n, 4, 4) D^-1 W_O^-1: maps an arm link's world pose to its pose in the true object's
    frame (object errors D (n, 4, 4), None = identity; W_O (4, 4) the believed pose)."""
    inverse = np.broadcast_to(rigid_inverse(object_pose), (n, 4, 4))
    return inverse if object_offset is None else rigid_inverse(object_offset) @ inverse


def flange_link(description: RobotDescription) -> str:
    """The link a palm error is relative to (:attr:`RobotDescription.flange_link`: the
    description's ``hand_mount``, by default the child of the last arm joint)."""
    return description.flange_link


def hand_links(description: RobotDescription) -> frozenset[str]:
    """The links a palm error moves: the palm link and every link below it."""
    model = description.model
    below = {description.palm_link}
    changed = True
    while changed:
        changed = False
        for joint in model.joints:
            if joint.parent in below and joint.child not in below:
                below.add(joint.child)
                changed = True
    return frozenset(below)
