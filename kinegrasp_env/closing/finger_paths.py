"""How each finger of a description robot closes, for the batched closing: its closing joints
and their rates and limits, the joint chain from the palm to each of its links, its speed
bound (:class:`FingerPath`), and the links' poses along the way (:func:`link_poses`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.generic_reference import finger_speed
from kinegrasp_env.closing.link_geometry import LinkGeometry
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics, axis_angle_matrix

__all__ = ["FingerPath", "finger_paths", "link_poses"]


@dataclass(frozen=True)
class FingerPath:
    """One finger's closing by its parameter t: closing joint j at its pre-shape value plus
    ``rates[j] * t``, clipped to [lower[j], upper[j]].

    Attributes:
        joints: the closing joints' names (J,).
        rates: (J,) d(joint value)/dt (the mimic multiplier times the close direction).
        lower, upper: (J,) the joints' limits (metres or radians).
        links: the finger's links with collision geometry.
        chains: link -> the joints from the palm to it, palm first.
        speed: bound on the speed (metres per unit t) of any point of its links
            (:func:`~kinegrasp_env.closing.generic_reference.finger_speed`).
        translating: every closing joint is prismatic (the links translate).
    """

    joints: tuple[str, ...]
    rates: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    links: tuple[str, ...]
    chains: dict[str, list]
    speed: float
    translating: bool


def finger_paths(description: RobotDescription, geometry: dict[str, LinkGeometry],
                 kinematics: Kinematics) -> list[FingerPath]:
    """Every finger's :class:`FingerPath` (its links: those of ``geometry``, link name ->
    collision geometry; ``kinematics``: the robot's, whose chains from the base give those
    from the palm)."""
    model = description.model
    drivers = model.drivers()
    palm = len(kinematics.chain(description.palm_link))
    out = []
    for finger in description.fingers:
        rates, lower, upper, kinds = [], [], [], []
        for name in finger.joints:
            joint = model.joint(name)
            driver, mult, _ = drivers[name]
            rates.append(mult * description.close[model.actuated[driver]])
            lower.append(joint.lower)
            upper.append(joint.upper)
            kinds.append(joint.kind)
        links = tuple(link for link in finger.links if link in geometry)
        chains = {link: kinematics.chain(link)[palm:] for link in links}
        reach = []
        for name in finger.joints:  # largest distance from the joint to points it moves
            far = 0.0
            for link in links:
                names = [j.name for j in chains[link]]
                if name in names:
                    vertices = geometry[link].extent_points
                    far = max(far, float(np.linalg.norm(vertices, axis=1).max())
                              + sum(float(np.linalg.norm(j.origin[:3, 3]))
                                    for j in chains[link][names.index(name) + 1:]))
            reach.append(far)
        out.append(FingerPath(tuple(finger.joints), np.array(rates), np.array(lower),
                              np.array(upper), links, chains,
                              finger_speed(kinds, np.array(rates), np.array(reach)),
                              all(kind == "prismatic" for kind in kinds)))
    return out


def link_poses(palm: np.ndarray, values: dict[str, np.ndarray], chain: list) -> np.ndarray:
    """(n, 4, 4) object-frame pose of the link at the end of ``chain`` (joints from the palm)
    from the palm's (n, 4, 4) object-frame pose and the joint values (name -> (n,))."""
    pose = palm
    for joint in chain:
        step = np.broadcast_to(joint.origin, pose.shape).copy()
        if joint.movable:
            v = values[joint.name]
            if joint.kind == "prismatic":
                step[:, :3, 3] += (joint.origin[:3, :3] @ joint.axis) * v[:, None]
            else:
                step[:, :3, :3] = joint.origin[:3, :3] @ axis_angle_matrix(joint.axis, v)
        pose = pose @ step
    return pose
