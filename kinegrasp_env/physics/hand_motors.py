"""The closing motors of a description robot's hand, whatever the simulator: each closing
joint's effort and speed limits (:func:`motor_efforts`) and the rule by which the joints of a
finger follow its first joint (:func:`closing_followers`).

Motor efforts: a joint's ``<limit effort>`` in the URDF (N for a prismatic joint, N m for a
revolute one), unless the description's ``efforts`` overrides it (for a mimic joint not
named there, its driver's override: the two jaws of a gripper overridden by naming the
actuated one push alike); its closing speed is the URDF's ``<limit velocity>``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from kinegrasp_env.robot.description import RobotDescription


@dataclass(frozen=True)
class JointMotor:
    """One hand joint's motor.

    Attributes:
        joint: the joint's name; kind: ``prismatic`` or ``revolute``.
        effort: its force (N) or torque (N m) limit; source: ``urdf`` (the URDF's
            ``<limit effort>``) or ``description`` (the description's ``efforts``).
        speed: its closing speed, m/s or rad/s (the URDF's ``<limit velocity>``).
        direction: +1 or -1, the sign of its motion when the hand closes.
    """

    joint: str
    kind: str
    effort: float
    source: str
    speed: float
    direction: int

    def to_json(self) -> dict:
        unit = "N" if self.kind == "prismatic" else "N m"
        return {"joint": self.joint, "effort": self.effort, "unit": unit,
                "source": self.source, "speed": self.speed}


def urdf_limits(urdf: Path) -> dict[str, tuple[float, float]]:
    """joint name -> (effort, velocity) of the URDF's ``<limit>`` (0 where not given)."""
    out = {}
    for joint in ET.parse(urdf).getroot().findall("joint"):
        limit = joint.find("limit")
        attributes = {} if limit is None else limit.attrib
        out[joint.get("name")] = (float(attributes.get("effort", 0.0)),
                                  float(attributes.get("velocity", 0.0)))
    return out


def motor_efforts(description: RobotDescription, scale: float = 1.0) -> list[JointMotor]:
    """The motors of every closing joint of the description's fingers (finger-major, palm to
    tip; a joint shared by two fingers once), efforts times ``scale``.

    Raises:
        ValueError: a closing joint with no effort (none in the URDF, no override) or no
            velocity limit (one line, naming the joint and the key to add).
    """
    limits = urdf_limits(description.urdf)
    motors, seen = [], set()
    for finger in description.fingers:
        for joint, direction in zip(finger.joints, finger.directions, strict=True):
            if joint in seen:
                continue
            seen.add(joint)
            effort, velocity = limits.get(joint, (0.0, 0.0))
            source = "urdf"
            mimic = description.model.joint(joint).mimic
            for name in (joint, *(() if mimic is None else (mimic[0],))):
                if name in description.efforts:
                    effort, source = description.efforts[name], "description"
                    break
            if not effort > 0:
                raise ValueError(f"robot {description.name!r}: joint {joint!r} has no effort "
                                 f"limit in {description.urdf.name}; give one in the "
                                 f"description's efforts: {{{joint}: ...}}")
            if not velocity > 0:
                raise ValueError(f"robot {description.name!r}: joint {joint!r} has no "
                                 f"velocity limit in {description.urdf.name}")
            motors.append(JointMotor(joint, description.model.joint(joint).kind,
                                     float(effort) * scale, source, float(velocity),
                                     int(direction)))
    return motors


@dataclass(frozen=True)
class Follower:
    """A hand joint that follows another: its target is ``target_start + ratio (source -
    source_start)`` (radians or metres), held with ``effort`` (N m or N).

    Attributes:
        joint, source: the follower's and the followed joint's names.
    """

    joint: str
    source: str
    ratio: float
    source_start: float
    target_start: float
    effort: float


def finger_leaders(description: RobotDescription) -> set[str]:
    """The first closing joint (from the palm) of every finger: the joints a motor drives."""
    return {finger.joints[0] for finger in description.fingers if finger.joints}


def closing_followers(description: RobotDescription, motors: list[JointMotor],
                      start: dict[str, float], coupled: bool = False) -> list[Follower]:
    """The joints that follow a motor (:func:`finger_leaders`), from the hand's joint values
    at the pre-shape ``start`` (name -> value; the joints a simulator has):

    * a finger's other closing joints follow its first at the kinematic closing's rates (the
      mimic multiplier times the close direction, of each), from their values now, with
      their own efforts;
    * a mimic joint that closes no finger follows its driver's mimic value, with its
      driver's effort (or the largest motor's when its driver has none); with ``coupled``,
      so do the fingers' first joints that are mimic joints (:func:`coupled_leaders`: the
      jaws one actuator moves), which otherwise close on their own motors.
    """
    model = description.model
    drivers = model.drivers()

    def rate(joint: str) -> float:  # d(value)/dt of the kinematic closing's parameter t
        index, multiplier, _ = drivers[joint]
        return multiplier * description.close[model.actuated[index]]

    efforts = {m.joint: m.effort for m in motors}
    followed = set(finger_leaders(description))
    if coupled:
        followed -= set(coupled_leaders(description))
    out: list[Follower] = []
    for finger in description.fingers:
        for joint in finger.joints[1:]:
            if joint not in followed:
                followed.add(joint)
                leader = finger.joints[0]
                out.append(Follower(joint, leader, rate(joint) / rate(leader), start[leader],
                                    start[joint], efforts[joint]))
    for joint in model.joints:
        if (joint.mimic is None or joint.name in followed or joint.name not in start
                or joint.mimic[0] not in start):
            continue
        source, multiplier, offset = joint.mimic
        out.append(Follower(joint.name, source, multiplier, 0.0, offset,
                            efforts.get(source, max(efforts.values()))))
    return out


def coupled_leaders(description: RobotDescription) -> list[str]:
    """The fingers' first closing joints (:func:`finger_leaders`) that are mimic joints of
    another finger's first joint: one actuator moves them with that finger (a parallel
    gripper's second jaw, a linkage gripper's second side)."""
    model = description.model
    leaders = finger_leaders(description)
    return sorted(name for name in leaders
                  if model.joint(name).mimic is not None and model.joint(name).mimic[0] in leaders)
