"""The paper's closing under dynamics: finger motors close the hand until they stall.

One draw (:func:`physics_close`): the hand root is put at the draw's flange pose and held
there (:class:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld`), the hand at its pre-shape.
A hand already penetrating the object by more than ``START_TOL`` (pybullet's distance, hand
links against the object's convex parts) is a start collision, as in the kinematic closing.
Otherwise, with gravity off, every flexion joint is driven by a velocity motor towards closing
at ``closing_speed`` with a torque limit (:class:`MotorSettings`: by default the stated
assumptions :data:`~kinegrasp_env.physics.protocol.ASSUMED_TORQUES`, 2.1 N m proximal, 1.4 N m
distal, no measured values); the spread joints hold the pre-shape. The kinematic
closing's joint logic is kept, as a controller reacting to pybullet's contacts (records within
``touch_distance``, checked every step):

* a finger with any link touching has its proximal joint held from then on (a position
  controller at the angle where it stopped, ``hold_torque``: the joint's gear holds it);
* its distal joint creeps on at ``creep_speed`` while the distal link touches (pressing the
  object lightly, following it if it gives way) and closes at ``closing_speed`` again when it
  does not (a finger whose first touch pushed the object away closes again until it touches).

Motors that keep closing at full speed and torque after contact (tried first) let the proximal
joint be back-driven and the fingers roll over edges or slide off slanted faces: with the
object fixed their contacts ended up to 5 cm from the kinematic ones; with this controller
they are within 1 mm (tests). The holding test's grip follows the closing
(:mod:`~kinegrasp_env.physics.grip_forces`). The object, when free, is pushed by whatever
touches it, palm and knuckles included, unless it is pinned (``pin=True``: the holding test's
closing). The closing ends when every flexion joint has stalled (mean speed below
``stall_speed`` over ``stall_checks`` consecutive windows of ``stall_window``) or after
``max_time``. Contacts are then read from
``getContactPoints``: per finger link the records within ``touch_distance`` are merged into one
contact, as the kinematic closing has one contact per link (:func:`merge_records`: the deepest
record, the kinematic closing's closest pair, and the records on the same face, averaged by
normal force: the centre of pressure of a line or patch contact), in the object's frame *where
the object is now* (it may have been pushed). Normals point into the object (minus pybullet's
``contactNormalOnB``, which points from the object to the finger). Only finger links make
contacts, as in the kinematic closing (the palm may push the object, but its contact does not
enter Q). A finger without contact has missed.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from kinegrasp_env.closing.close_rules import CONTACT_TOL, START_TOL
from kinegrasp_env.physics.grip_forces import GripContact
from kinegrasp_env.physics.hand_result import CloseResult
from kinegrasp_env.physics.hold_runner import FLEXION_JOINTS, SPREAD_JOINTS, close_fingers
from kinegrasp_env.physics.protocol import ASSUMED_TORQUES, TorqueLimits
from kinegrasp_env.physics.pybullet_world import PhysicsWorld
from kinegrasp_env.robot.default_robot import FINGERS, hand_joint_values

#: Contact records of one link whose normals are within this angle of the deepest record's
#: are merged into one contact (the same face), radians.
MERGE_ANGLE = np.radians(10.0)


@dataclass(frozen=True)
class MotorSettings:
    """The finger motors and the closing's end.

    Attributes:
        closing_speed: target speed of a closing joint, rad/s (the URDF's velocity limit).
        proximal_torque, distal_torque: torque limits of the closing motors, N m (stated
            assumptions, :data:`~kinegrasp_env.physics.protocol.ASSUMED_TORQUES`).
        hold_torque: torque limit of the position controllers that hold the spread and a
            stopped proximal joint, N m (the URDF's effort limit: the joint's gear holds).
        creep_speed: a distal joint whose link touches is driven at this speed towards
            closing while the hand closes, rad/s, with its torque limit: it follows the object
            slowly if the object gives way and presses it lightly (blocked, pybullet's
            iterative solver builds up only ~0.3 N m for so slow a target).
        touch_distance: a contact record within this distance (metres) is a contact.
        stall_speed: a joint whose mean speed over ``stall_window`` seconds is below this
            (rad/s) has stalled; the closing ends when every flexion joint has, at
            ``stall_checks`` consecutive windows (a pressing finger chatters by ~0.003 rad).
        max_time: longest closing, seconds.
    """

    closing_speed: float = 1.0
    proximal_torque: float = ASSUMED_TORQUES.proximal
    distal_torque: float = ASSUMED_TORQUES.distal
    hold_torque: float = ASSUMED_TORQUES.hold
    creep_speed: float = 0.05
    touch_distance: float = CONTACT_TOL
    stall_speed: float = 0.1
    stall_window: float = 0.1
    stall_checks: int = 2
    max_time: float = 3.5

    def __post_init__(self) -> None:
        for name in ("closing_speed", "proximal_torque", "distal_torque", "hold_torque",
                     "touch_distance", "stall_speed", "stall_window", "max_time"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not (np.isfinite(self.creep_speed) and self.creep_speed >= 0):
            raise ValueError(f"creep_speed must be >= 0, got {self.creep_speed!r}")
        if self.stall_checks < 1:
            raise ValueError(f"stall_checks must be >= 1, got {self.stall_checks!r}")

    def with_torques(self, torques: TorqueLimits) -> MotorSettings:
        """These settings with the torque limits ``torques``."""
        return replace(self, proximal_torque=torques.proximal, distal_torque=torques.distal,
                       hold_torque=torques.hold)


@dataclass
class PhysicsClose(CloseResult):
    """A :class:`~kinegrasp_env.physics.hand_result.CloseResult` (``iterations``: simulation
    steps) and where the object ended.

    Attributes:
        object_pose: (4, 4) world pose of the object frame after closing (None for a start
            collision).
    """

    object_pose: np.ndarray | None = field(default=None, repr=False)


class FingerMotors:
    """The joint controller of the closing (see the module docstring).

    Args:
        world: the physics world (hand reset to its pre-shape).
        settings: :class:`MotorSettings`.
        spread: {spread joint name: value to hold}, radians.
    """

    def __init__(self, world: PhysicsWorld, settings: MotorSettings,
                 spread: dict[str, float]) -> None:
        self.world, self.settings = world, settings
        self.held = [False] * 3  # per finger: its proximal joint is held
        self.pressing = [False] * 3  # per finger: its distal joint presses (link touching)
        bullet, hand = world.bullet, world.hand
        for name, value in spread.items():
            bullet.setJointMotorControl2(hand, world.joint_index[name], bullet.POSITION_CONTROL,
                                         targetPosition=value, force=settings.hold_torque)
        torques = [settings.proximal_torque, settings.distal_torque] * 3
        bullet.setJointMotorControlArray(
            hand, [world.joint_index[j] for j in FLEXION_JOINTS], bullet.VELOCITY_CONTROL,
            targetVelocities=[settings.closing_speed] * 6, forces=torques)

    def hold(self, finger: int) -> None:
        """Hold a finger's proximal joint where it is (``hold_torque``)."""
        self.held[finger] = True
        bullet, hand = self.world.bullet, self.world.hand
        index = self.world.joint_index[FINGERS[finger][0]]
        bullet.setJointMotorControl2(hand, index, bullet.POSITION_CONTROL,
                                     targetPosition=bullet.getJointState(hand, index)[0],
                                     force=self.settings.hold_torque)

    def press(self, finger: int, on: bool) -> None:
        """Drive a finger's distal joint at ``creep_speed`` (on: its link touches) or at
        ``closing_speed`` (off), with its torque limit."""
        self.pressing[finger] = on
        speed = self.settings.creep_speed if on else self.settings.closing_speed
        self.world.bullet.setJointMotorControl2(
            self.world.hand, self.world.joint_index[FINGERS[finger][1]],
            self.world.bullet.VELOCITY_CONTROL, targetVelocity=speed,
            force=self.settings.distal_torque)

    def update(self, touching: set[tuple[int, int]]) -> None:
        """React to the touching (finger, link)s: a finger with any link touching has its
        proximal joint held from then on; its distal joint presses while the distal link
        touches and closes again when it does not."""
        for finger in range(3):
            if not self.held[finger] and ((finger, 0) in touching or (finger, 1) in touching):
                self.hold(finger)
            if ((finger, 1) in touching) != self.pressing[finger]:
                self.press(finger, not self.pressing[finger])


def finger_links(world: PhysicsWorld) -> dict[int, tuple[int, int]]:
    """pybullet link index -> (finger 0-2, link 0 proximal / 1 distal)."""
    return {world.link_index[FINGERS[f][2 + k]]: (f, k) for f in range(3) for k in range(2)}


def finger_forces(world: PhysicsWorld, links: dict[int, tuple[int, int]], fingers: int
                  ) -> np.ndarray:
    """(fingers,) each finger's total normal force on the object from the last step, newtons
    (the sum of pybullet's ``normalForce`` over the contact records of its links; ``links``:
    pybullet link index -> (finger, link), as :func:`finger_links` gives them for the
    default robot's hand and :func:`~kinegrasp_env.physics.jaw_motors.finger_link_indices`
    for a description robot's)."""
    forces = np.zeros(fingers)
    for rec in world.contact_points():
        if rec[3] in links:
            forces[links[rec[3]][0]] += rec[9]
    return forces


def touching_links(world: PhysicsWorld, links: dict[int, tuple[int, int]],
                   distance: float) -> set[tuple[int, int]]:
    """(finger, link) of the finger links with a contact record within ``distance`` (m)."""
    return {links[rec[3]] for rec in world.contact_points()
            if rec[3] in links and rec[8] <= distance}


def merge_records(records: list[tuple], max_angle: float = MERGE_ANGLE
                  ) -> tuple[np.ndarray, np.ndarray]:
    """One contact from a link's pybullet contact records (world frame): (point (3,), inward
    unit normal (3,)).

    The deepest record (smallest ``contactDistance``: pybullet's closest pair, the contact
    the kinematic closing takes) gives the face; the records whose normals are within
    ``max_angle`` (radians) of its normal (the same face: a line or patch contact) are
    averaged, weighted by their normal forces (plain average when every force is zero).
    """
    deepest = min(records, key=lambda rec: rec[8])
    face = np.asarray(deepest[7])
    same = [rec for rec in records
            if rec is deepest or np.dot(rec[7], face) >= np.cos(max_angle)]
    force = np.array([rec[9] for rec in same])
    weight = force / force.sum() if force.sum() > 0 else np.full(len(same), 1.0 / len(same))
    point = weight @ np.array([rec[6] for rec in same])
    normal = -(weight @ np.array([rec[7] for rec in same]))
    return point, normal / np.linalg.norm(normal)


def world_contacts(world: PhysicsWorld, distance: float) -> list[GripContact]:
    """One contact per touching finger link (:func:`merge_records`), world frame,
    finger-major, proximal before distal."""
    links = finger_links(world)
    records: dict[tuple[int, int], list[tuple]] = {}
    for rec in world.contact_points():
        if rec[3] in links and rec[8] <= distance:
            records.setdefault(links[rec[3]], []).append(rec)
    return [GripContact(finger, link, *merge_records(records[(finger, link)]))
            for finger, link in sorted(records)]


def physics_close(world: PhysicsWorld, root_pose: np.ndarray, preshape: np.ndarray,
                  settings: MotorSettings | None = None, pin: bool = False) -> PhysicsClose:
    """Close the hand at ``root_pose`` from ``preshape`` under dynamics (module docstring).

    Args:
        world: the physics world.
        root_pose: (4, 4) world pose of the hand root (the arm's flange frame).
        preshape: (7,) hand DOF (``HAND_JOINTS`` order), radians.
        settings: :class:`MotorSettings` (default values when None).
        pin: pin the (free) object where it is placed while the hand closes (it stays
            pinned after: :meth:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld.
            release_object` frees it).
    """
    settings = settings or MotorSettings()
    preshape = np.asarray(preshape, dtype=float)
    values = hand_joint_values(preshape)
    world.reset(root_pose, values)
    if pin:
        world.pin_object()
    if world.penetration() > START_TOL:
        return PhysicsClose(start_collision=True)
    motors = FingerMotors(world, settings, {name: values[name] for name in SPREAD_JOINTS})
    links = finger_links(world)
    steps, contacts, missed, positions = close_fingers(
        world, lambda: motors.update(touching_links(world, links, settings.touch_distance)),
        lambda: world_contacts(world, settings.touch_distance), settings)
    return PhysicsClose(False, contacts, missed, positions, steps, world.object_pose())
