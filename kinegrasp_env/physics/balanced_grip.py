"""The balanced grip of a description robot whose fingers are chains of revolute joints, each
driven on its own (no mimic coupling: the SDH's kind of hand), in any simulator.

Pressing every closing motor at its full effort is the rule for parallel jaws: two opposed
jaws with equal efforts squeeze the object with equal and opposite forces. Three or more
fingers of revolute joints at full effort push the object with an unbalanced net force, and
the release slides it away. Such a hand grips as the default robot's holding test grips
(:mod:`~kinegrasp_env.physics.grip_forces`): the contacts of the closing give joint torques
whose contact forces are in equilibrium, inside the friction cones, each joint between 0 and
its motor's effort (:func:`~kinegrasp_env.physics.hand_motors.motor_efforts`; a spread
joint either way within its effort), applied as
joint springs that press with those torques at the stall angle
(:class:`~kinegrasp_env.physics.grip_forces.SpringGrip`); a joint that carries no contact is
held where it stalled.

A joint carries a contact when it lies on the chain from the palm to the contact's link
(:attr:`GripLayout.first_links`: the first of its finger's links it moves).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from kinegrasp_env.physics.grip_forces import (
    GripContact,
    GripJoints,
    SpringGrip,
    levers,
    spring_grip,
)
from kinegrasp_env.physics.hand_motors import motor_efforts, required_effort, urdf_limits
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics

__all__ = ["GripLayout", "balances", "grip_layout"]


def balances(description: RobotDescription) -> bool:
    """Whether the hand grips by balanced torques (module docstring): every finger's
    closing joints revolute, none a mimic joint, none shared by two fingers."""
    names = [joint for finger in description.fingers for joint in finger.joints]
    return bool(names) and len(set(names)) == len(names) and all(
        description.model.joint(name).kind in ("revolute", "continuous")
        and description.model.joint(name).mimic is None for name in names)


@dataclass(frozen=True)
class GripLayout:
    """The grip joints of a hand that :func:`balances` (J): each finger's closing joints,
    palm to tip, then each finger's other joints below the palm (a spread joint: it turns
    either way within its effort, and carries every contact of its finger).

    Attributes:
        names: the joints; directions: (J,) +1 or -1, each closing joint's closing sign (+1
            for the others).
        fingers: (J,) each joint's finger; first_links: (J,) the index (in its finger's
            ``links``) of the first link the joint moves.
        lower, upper: (J,) torque bounds, N m: [0, effort] for a closing joint, [-effort,
            effort] for another.
        tips: (J,) each joint's fingertip link.
    """

    names: tuple[str, ...]
    directions: np.ndarray
    fingers: np.ndarray
    first_links: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    tips: tuple[str, ...]

    def joints(self, axes: np.ndarray, origins: np.ndarray,
               tips: np.ndarray) -> GripJoints:
        """The grip joints now: their axes (J, 3) as the simulator reports them (the URDF's
        sense), points on them (J, 3) and their fingertips (J, 3), world frame, metres."""
        axes = np.asarray(axes, dtype=float) * self.directions[:, None]  # closing positive
        return GripJoints(axes, np.asarray(origins, dtype=float), self.fingers,
                          self.first_links, self.lower, self.upper,
                          np.asarray(tips, dtype=float))

    def spring(self, contacts: list[GripContact], axes: np.ndarray, origins: np.ndarray,
               tips: np.ndarray, stall: np.ndarray, object_pose: np.ndarray,
               center_of_mass: np.ndarray, friction: float, advance: float
               ) -> SpringGrip | None:
        """The grip of the hand just closed (:func:`~kinegrasp_env.physics.grip_forces.
        spring_grip`): contacts (finger, link index in its finger's ``links``) and joint
        frames in the world frame, ``stall`` (J,) the joints' angles now, radians; None when
        no contact forces in equilibrium exist. The springs are in the URDF's sense of each
        joint (as the simulators set them): the programme solves with every closing joint
        closing positive, and a joint that closes negative has its angles, target and
        torque mirrored."""
        stall = np.asarray(stall, dtype=float)
        tips = reach(self.joints(axes, origins, tips), contacts)
        spring = spring_grip(contacts, self.joints(axes, origins, tips), object_pose,
                             center_of_mass, self.directions * stall, friction, advance)
        if spring is None:
            return None
        return replace(spring, stall=stall, targets=self.directions * spring.targets)

    def world_spring(self, world, contacts: list[GripContact], advance: float
                     ) -> SpringGrip | None:
        """:meth:`spring` of the hand in a simulator's ``world`` now (pybullet's or MuJoCo's:
        ``joint_frames``, ``link_pose``, ``joint_states``, ``object_pose``, the object and its
        friction), the tips advanced ``advance`` metres past the stall."""
        names = list(self.names)
        axes, origins = world.joint_frames(names)
        return self.spring(contacts, axes, origins,
                           np.array([world.link_pose(t)[:3, 3] for t in self.tips]),
                           world.joint_states(names)[0], world.object_pose(),
                           world.obj.center_of_mass, world.settings.friction, advance)


#: A fingertip nearer its joint's axis than this share of the farthest contact the joint
#: carries gives the joint too short a lever to advance by (:func:`reach`).
LEVER_SHARE = 0.5


def reach(joints: GripJoints, contacts: list[GripContact]) -> np.ndarray:
    """(J, 3) the point whose advance sets each joint's spring (:func:`~kinegrasp_env.
    physics.grip_forces.tip_offsets`): its fingertip, or, where that lies nearer the joint's
    axis than :data:`LEVER_SHARE` of the contact it carries farthest from the axis (a
    one-joint finger whose leaf link, its tip, has its frame at the joint), that contact. A
    tip on the axis has a lever of 0, an offset of ``advance / 1e-6`` rad and a spring that
    is a constant torque holding no position: two such fingers pushed the released object
    12.7 mm."""
    tips = np.array(joints.tips, dtype=float)
    carries = joints.carries(contacts)
    for j in range(len(tips)):
        points = np.array([tips[j]] + [contacts[c].point for c in np.nonzero(carries[j])[0]])
        lever = levers(points, joints.origins[j], joints.axes[j])
        if lever[0] < LEVER_SHARE * lever.max():
            tips[j] = points[int(np.argmax(lever))]
    return tips


def grip_layout(description: RobotDescription, torque_scale: float = 1.0) -> GripLayout:
    """The grip joints of a hand that :func:`balances` (ValueError for another): closing
    efforts times ``torque_scale``; another joint's effort the description's ``efforts`` or
    the URDF's ``<limit effort>``. A joint below the palm on two fingers' chains is left
    out (held where it is)."""
    if not balances(description):
        raise ValueError(f"robot {description.name!r}: its fingers are not chains of revolute "
                         "joints driven on their own; it grips as jaws do")
    efforts = {m.joint: m.effort for m in motor_efforts(description, torque_scale)}
    limits = urdf_limits(description.urdf)
    kinematics = Kinematics(description.model)
    palm = len(kinematics.chain(description.palm_link))
    below = [[j.name for j in kinematics.chain(finger.tip)[palm:] if j.kind != "fixed"]
             for finger in description.fingers]
    counts: dict[str, int] = {}
    for names in below:
        for name in names:
            counts[name] = counts.get(name, 0) + 1
    rows = []  # (name, direction, finger, first link, lower, upper, tip)
    for f, finger in enumerate(description.fingers):
        chains = [{joint.name for joint in kinematics.chain(link)} for link in finger.links]
        first = {name: next((k for k, chain in enumerate(chains) if name in chain), 0)
                 for name in below[f]}
        for joint, direction in zip(finger.joints, finger.directions, strict=True):
            rows.append((joint, float(direction), f, first[joint], 0.0, efforts[joint],
                         finger.tip))
        for name in below[f]:
            if name in finger.joints or counts[name] > 1:
                continue
            effort = required_effort(description, limits, name)[0]
            rows.append((name, 1.0, f, first[name], -effort, effort, finger.tip))
    names, directions, fingers, first_links, lower, upper, tips = zip(*rows, strict=True)
    return GripLayout(tuple(names), np.array(directions), np.array(fingers, dtype=int),
                      np.array(first_links, dtype=int), np.array(lower), np.array(upper),
                      tuple(tips))
