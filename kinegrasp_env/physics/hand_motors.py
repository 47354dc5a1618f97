"""The closing motors of a description robot's hand, whatever the simulator: each closing
joint's effort and speed limits (:func:`motor_efforts`), which joints a motor of their own
drives (:func:`finger_leaders`: a finger's first closing joint and each independently
actuated phalanx), the rule by which the others follow them (:func:`closing_followers`), and
the kinematic closing's touch rule as motor switches (:class:`TouchRule`).

Motor efforts: a joint's ``<limit effort>`` in the URDF (N for a prismatic joint, N m for a
revolute one), unless the description's ``efforts`` overrides it (for a mimic joint not
named there, its driver's override: the two jaws of a gripper overridden by naming the
actuated one push alike); its closing speed is the URDF's ``<limit velocity>``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegrasp_env.physics.protocol import check_number
from kinegrasp_env.robot.description import Finger, RobotDescription
from kinegrasp_env.robot.touch_rule import touch_stops


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


def joint_effort(description: RobotDescription, limits: dict[str, tuple[float, float]],
                 joint: str) -> tuple[float, str]:
    """(effort, where it came from) of ``joint``: the description's ``efforts`` override
    (for a mimic joint not named there, its driver's), else the URDF's ``<limit effort>``
    (``limits``: :func:`urdf_limits`; 0 where neither gives one)."""
    mimic = description.model.joint(joint).mimic
    for name in (joint, *(() if mimic is None else (mimic[0],))):
        if name in description.efforts:
            return float(description.efforts[name]), "description"
    return limits.get(joint, (0.0, 0.0))[0], "urdf"


def required_effort(description: RobotDescription, limits: dict[str, tuple[float, float]],
                    joint: str) -> tuple[float, str]:
    """:func:`joint_effort` of a joint that must have one (a closing motor's, a held
    spread's).

    Raises:
        ValueError: none in the URDF and no override (one line, naming the joint and the
            key to add).
    """
    effort, source = joint_effort(description, limits, joint)
    if not effort > 0:
        raise ValueError(f"robot {description.name!r}: joint {joint!r} has no effort "
                         f"limit in {description.urdf.name}; give one in the "
                         f"description's efforts: {{{joint}: ...}}")
    return effort, source


def motor_efforts(description: RobotDescription, scale: float = 1.0) -> list[JointMotor]:
    """The motors of every closing joint of the description's fingers (finger-major, palm to
    tip; a joint shared by two fingers once), efforts times ``scale``.

    Raises:
        ValueError: a closing joint with no effort (none in the URDF, no override) or no
            velocity limit (one line, naming the joint and the key to add); a ``scale``
            that is not a finite number > 0.
    """
    check_number("scale", scale, positive=True)
    limits = urdf_limits(description.urdf)
    motors, seen = [], set()
    for finger in description.fingers:
        for joint, direction in zip(finger.joints, finger.directions, strict=True):
            if joint in seen:
                continue
            seen.add(joint)
            effort, source = required_effort(description, limits, joint)
            velocity = limits.get(joint, (0.0, 0.0))[1]
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


def hold_efforts(description: RobotDescription, motors: list[JointMotor]) -> dict[str, float]:
    """What holds each hand joint where it stands when it does not push, N m or N (not scaled
    by the holding test's ``torque_scale``, which scales what the motors push):

    * a closing motor's joint, once the touch rule stops it (:class:`TouchRule`): its URDF
      ``<limit effort>``, the joint's own limit (its gear; the description's ``efforts`` are
      its motor's: the paper's hand pushes at 2.1 and 1.4 N m and holds a stopped joint at
      the URDF's 10), else the description's;
    * a hand joint that closes no finger and follows no closing joint (a spread, and a
      mimic twin of one): its effort (:func:`joint_effort`: the description's ``efforts``
      or the URDF's), as the balanced grip holds it
      (:func:`~kinegrasp_env.physics.balanced_grip.grip_layout`). A mimic joint of a
      closing joint (a linkage's bar) follows its motor instead (:func:`closing_followers`).

    Raises:
        ValueError: a spread (or its twin) without an effort (one line, naming the joint
            and the key to add), as the balanced grip refuses it.
    """
    limits = urdf_limits(description.urdf)
    out = {m.joint: limits.get(m.joint, (0.0, 0.0))[0]
           or joint_effort(description, limits, m.joint)[0] for m in motors}
    closing = {joint for finger in description.fingers for joint in finger.joints}
    model = description.model
    for name, (index, _, _) in model.drivers().items():
        driver = model.actuated[index]
        if name in closing or driver in closing or driver not in description.hand_joints:
            continue
        out[name] = required_effort(description, limits, name)[0]
    return out


@dataclass(frozen=True)
class JointHold:
    """A hand joint held where the pre-shape puts it while the hand closes and holds: its
    ``value`` (radians or metres), with ``effort`` (N m or N)."""

    joint: str
    value: float
    effort: float


def preshape_holds(description: RobotDescription, holds: dict[str, float],
                   start: dict[str, float]) -> list[JointHold]:
    """The hand's actuated joints that close no finger (a spread: pre-shape only), each held
    at its value in ``start`` (name -> value; the joints a simulator has) by its effort in
    ``holds`` (:func:`hold_efforts`), as the paper's hand holds its spread: left free, a
    spread joint turns under the contact forces and the fingers slide off."""
    closing = {joint for finger in description.fingers for joint in finger.joints}
    return [JointHold(joint, float(start[joint]), holds[joint])
            for joint in description.hand_joints if joint not in closing and joint in start]


def finger_motor_joints(description: RobotDescription, finger: Finger) -> tuple[str, ...]:
    """The closing joints of ``finger`` that a motor of their own drives, palm to tip: its
    first, and each later one that another degree of freedom drives than every joint before
    it in the finger (an independently actuated phalanx: the paper's hand's distal joint).
    A joint that an earlier joint's degree of freedom drives (a linkage's mimic joints)
    follows that joint (:func:`closing_followers`)."""
    drivers = description.model.drivers()
    out, seen = [], set()
    for joint in finger.joints:
        if drivers[joint][0] not in seen:
            seen.add(drivers[joint][0])
            out.append(joint)
    return tuple(out)


def finger_leaders(description: RobotDescription) -> set[str]:
    """Every finger's motor joints (:func:`finger_motor_joints`): the joints a motor
    drives."""
    return {joint for finger in description.fingers
            for joint in finger_motor_joints(description, finger)}


def closing_followers(description: RobotDescription, motors: list[JointMotor],
                      start: dict[str, float], coupled: bool = False,
                      holds: dict[str, float] | None = None) -> list[Follower]:
    """The joints that follow a motor (:func:`finger_leaders`), from the hand's joint values
    at the pre-shape ``start`` (name -> value; the joints a simulator has):

    * a finger's other closing joints follow the earlier joint of the finger that their
      degree of freedom drives (:func:`finger_motor_joints`) at the kinematic closing's
      rates (the mimic multiplier times the close direction, of each), from their values
      now, with their own efforts;
    * a mimic joint that closes no finger follows its driver's mimic value, with its
      driver's motor's effort (a linkage's bars), or where its driver is no motor (a
      spread's twin) its own holding effort (``holds``: :func:`hold_efforts`; without, the
      largest motor's); with ``coupled``, so do the fingers' motor joints that are mimic
      joints of another finger's (:func:`coupled_leaders`: the jaws one actuator moves),
      with their driver's effort, which otherwise close on their own motors.
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
        for k, joint in enumerate(finger.joints[1:], start=1):
            if joint not in followed:
                followed.add(joint)
                leader = next((earlier for earlier in finger.joints[:k]
                               if drivers[earlier][0] == drivers[joint][0]), None)
                if leader is None:  # a coupled finger's motor joint: the mimic rule below
                    followed.discard(joint)
                    continue
                out.append(Follower(joint, leader, rate(joint) / rate(leader), start[leader],
                                    start[joint], efforts[joint]))
    for joint in model.joints:
        if (joint.mimic is None or joint.name in followed or joint.name not in start
                or joint.mimic[0] not in start):
            continue
        source, multiplier, offset = joint.mimic
        effort = (efforts[source] if source in efforts
                  else (holds or {}).get(joint.name) or max(efforts.values()))
        out.append(Follower(joint.name, source, multiplier, 0.0, offset, effort))
    return out


def coupled_leaders(description: RobotDescription) -> list[str]:
    """The fingers' motor joints (:func:`finger_leaders`) that are mimic joints of another
    finger's motor joint: one actuator moves them with that finger (a parallel gripper's
    second jaw, a linkage gripper's second side)."""
    model = description.model
    leaders = finger_leaders(description)
    return sorted(name for name in leaders
                  if model.joint(name).mimic is not None and model.joint(name).mimic[0] in leaders)


def independent_jaws(description: RobotDescription) -> frozenset[str]:
    """The motor joints of the fingers of one motor (:func:`finger_motor_joints`) that move
    no other finger (no other finger's motor joint mimics them): jaws and one-joint fingers
    driven each on its own. On a free object such a finger, left at full speed once it
    touches, shoves the object into the others (two prismatic jaws: the coupled jaws' push
    of the first to touch; two revolute fingers: a contest of their efforts, unstable, the
    finger with the shorter lever pushing the other open)."""
    model = description.model
    coupled = set(coupled_leaders(description))
    driving = {model.joint(name).mimic[0] for name in coupled}
    out = set()
    for finger in description.fingers:
        own = finger_motor_joints(description, finger)
        if len(own) == 1 and own[0] not in driving | coupled:
            out.add(own[0])
    return frozenset(out)


#: A finger of several motors (or a jaw driven on its own, on a free object): its last
#: motor, while a link it moves touches the object,
#: closes at this fraction of its closing speed (within its effort), pressing the object
#: and following it where it gives way (the paper's hand's distal creep: 0.05 rad/s of
#: 1 rad/s). At full speed the SDH's distal phalanges shoved the free cube up to 6 cm and
#: rolled over its edges, one finger of three missing it on 7 of 20 draws.
CREEP_FRACTION = 0.05
#: A pressing motor closes at full speed again once no link it moves has touched for this
#: long, seconds (a finger whose touch pushed the object away closes until it touches
#: again). Released at the first step without contact, MuJoCo's SDH distal phalanges
#: bounced off the cube, switching 55-369 times a closing, and ended off it.
RELEASE_TIME = 0.02


class TouchRule:
    """The kinematic closing's touch rule (:func:`~kinegrasp_env.robot.touch_rule.
    touch_stops`: a touching link stops the joints that move it) as switches of the closing
    motors while the hand closes, whatever the simulator. When link k of a finger touches,
    the finger's motor joints that the touch stops are held where they are from then on (by
    :attr:`efforts`), except the finger's last motor joint (nearest the tip), which presses:
    it closes at :data:`CREEP_FRACTION` of its speed, with its full effort, while a link it
    moves touches (and :data:`RELEASE_TIME` after), at full speed otherwise. A finger of one
    motor (a jaw, a linkage) is left alone: its motor pushes at full speed and effort
    throughout (a gripper's jaws close until they grip), except, on a free object, a finger
    whose motor moves no other finger (jaws driven each on its own: ``free``), which presses
    as a last motor does. A finger of independently actuated
    phalanges closes as GraspIt's auto-close and the paper's hand close: a touching proximal
    phalanx stops, the distal one closes on until it touches and presses. The switches stay
    where the closing left them through the holding test's phases.

    Args:
        description: the robot.
        motors: the closing motors that drive now (:func:`finger_leaders`, less the
            coupled jaws' followers).
        holds: :func:`hold_efforts`.
        time_step: the simulator's step, seconds (one :meth:`update` a step).
        free: the object is free (the physics engine's closing, not the holding test's
            pinned one): the fingers of one motor that drives no other finger
            (:func:`independent_jaws`) press as a last motor does, not left alone.
    """

    def __init__(self, description: RobotDescription, motors: list[JointMotor],
                 holds: dict[str, float], time_step: float, free: bool = False) -> None:
        alone = independent_jaws(description) if free else frozenset()
        #: joint -> what holds it once a touch stopped it (:func:`hold_efforts`)
        self.efforts = {m.joint: holds[m.joint] for m in motors}
        #: per finger, per link: the motor joints its touch holds
        self.rows: list[list[tuple[str, ...]]] = []
        #: per finger that presses (several motors, or one on its own on a free object): its
        #: last motor joint and the first link it moves
        self.pressers: list[tuple[str, int]] = []
        self.fingers: list[int] = []
        for f, finger in enumerate(description.fingers):
            own = [j for j in finger_motor_joints(description, finger) if j in self.efforts]
            holdable = set(own[:-1])
            stops = touch_stops(description.model, finger)
            self.rows.append([tuple(j for j, stop in zip(finger.joints, row, strict=True)
                                    if stop and j in holdable) for row in stops])
            if holdable or (own and own[-1] in alone):
                self.pressers.append((own[-1], finger.joints.index(own[-1])))
                self.fingers.append(f)
        self.release = max(1, round(RELEASE_TIME / time_step))
        #: the joints held so far; the last motors pressing now (steps since their touch)
        self.held: set[str] = set()
        self.pressing: dict[str, int] = {}

    @property
    def active(self) -> bool:
        """Whether any finger presses (several motors, or one on its own on a free object;
        else the closing need not read contacts)."""
        return bool(self.pressers)

    def travel(self, names: list[str], travel: np.ndarray) -> np.ndarray:
        """The motors' travel (m,) (``names``' positions over their closing speeds, seconds)
        as the stall rule reads it: a pressing motor's as 0, stalled (it has touched; its
        creep follows the object, and the closing ends when the other motors stall, as the
        paper's hand's creep speed lies below its stall speed)."""
        return np.where([name in self.pressing for name in names], 0.0, travel)

    def velocity(self, motor: JointMotor) -> float:
        """A closing motor's target speed now, m/s or rad/s: its closing speed towards
        closing, :data:`CREEP_FRACTION` of it while it presses."""
        creep = CREEP_FRACTION if motor.joint in self.pressing else 1.0
        return motor.direction * motor.speed * creep

    def update(self, touching) -> tuple[list[str], list[tuple[str, bool]]]:
        """For the touching (finger, link) pairs after a step: (the motor joints to hold from
        now on, each once; the last motors whose pressing changes, (joint, pressing now))."""
        new = []
        for finger, link in sorted(touching):
            for joint in self.rows[finger][link]:
                if joint not in self.held:
                    self.held.add(joint)
                    new.append(joint)
        changed = []
        for f, (joint, first) in zip(self.fingers, self.pressers, strict=True):
            if any(finger == f and link >= first for finger, link in touching):
                if joint not in self.pressing:
                    changed.append((joint, True))
                self.pressing[joint] = 0
            elif joint in self.pressing:
                self.pressing[joint] += 1
                if self.pressing[joint] >= self.release:
                    del self.pressing[joint]
                    changed.append((joint, False))
        return new, changed
