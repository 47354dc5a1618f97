"""The default robot's names and model, read from its description
(``assets/robots/kuka_sdh.yaml``, :data:`~kinegrasp_env.robot.default.DEFAULT_ROBOT`) on first
use: what its analytic IK, the elbow angle's links, the environments' default picture and the
tests' pybullet-only contact reference (:mod:`~kinegrasp_env.montecarlo.bullet_contacts`)
read.

``ARM_JOINTS`` (base to flange), ``HAND_JOINTS`` (the hand's actuated vector), ``PALM_LINK``,
``FINGERTIP_LINKS``, ``FINGERS`` (per finger: proximal joint, distal joint, proximal link,
distal link), ``SHOULDER_LINK``, ``ELBOW_LINK``, ``WRIST_LINK`` (the elbow angle's links):
module attributes (:func:`default_names`).
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.default import DEFAULT_ROBOT
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.model import RobotModel, load_urdf

#: The names this module gives (:func:`default_names`).
DEFAULT_NAMES = ("ARM_JOINTS", "HAND_JOINTS", "PALM_LINK", "FINGERTIP_LINKS", "FINGERS",
                 "SHOULDER_LINK", "ELBOW_LINK", "WRIST_LINK")


@lru_cache(maxsize=1)
def default_description() -> RobotDescription:
    """The default robot's description, read once per process."""
    return load_robot(DEFAULT_ROBOT)


@lru_cache(maxsize=1)
def default_names() -> dict[str, object]:
    """The default robot's names of :data:`DEFAULT_NAMES`, from its description."""
    description = default_description()
    shoulder, elbow, wrist = description.arm_angle_links
    return {"ARM_JOINTS": description.arm_joints, "HAND_JOINTS": description.hand_joints,
            "PALM_LINK": description.palm_link,
            "FINGERTIP_LINKS": description.fingertip_links,
            "FINGERS": tuple((*finger.joints, *finger.links)
                             for finger in description.fingers),
            "SHOULDER_LINK": shoulder, "ELBOW_LINK": elbow,
            "WRIST_LINK": wrist}


def __getattr__(name: str):
    if name in DEFAULT_NAMES:
        return default_names()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def urdf_path() -> Path:
    """Path of the default robot's URDF (for ``pybullet.loadURDF``)."""
    return default_description().urdf


def default_hand_mount() -> str:
    """The default robot's hand mount (its description's ``hand_mount``): the link whose
    pose places its hand, and the frame its palm errors are given in."""
    return default_description().flange_link


@lru_cache(maxsize=1)
def kuka_sdh() -> RobotModel:
    """The default robot's model (the KUKA iiwa + SDH-like hand): its URDF, configuration =
    its arm joints + its hand's actuated vector (7 + 7)."""
    names = default_names()
    return load_urdf(urdf_path(), actuated=names["ARM_JOINTS"] + names["HAND_JOINTS"])


def hand_joint_values(preshape) -> dict[str, float]:
    """Every movable hand joint's value (radians), the mimic followers of the spread
    expanded, from the hand's actuated vector (7,) (``HAND_JOINTS``' order)."""
    model, names = kuka_sdh(), default_names()
    q = np.zeros(model.dof)
    q[model.index(names["HAND_JOINTS"])] = np.asarray(preshape, dtype=float)
    arm = set(names["ARM_JOINTS"])
    return {name: float(value) for name, value in model.expand(q).items() if name not in arm}
