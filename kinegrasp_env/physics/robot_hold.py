"""The holding test (:mod:`~kinegrasp_env.physics.protocol`) of any description robot, in
pybullet: its hand (:class:`~kinegrasp_env.physics.robot_world.RobotPhysicsWorld`) at the
palm pose the draw's arm joints give (forward kinematics of the URDF), the object pinned.

One draw (:meth:`RobotHold.run_draw`):

1. **closing**, gravity off, the object pinned: a hand link penetrating the object by more
   than :data:`~kinegrasp_env.closing.close_rules.START_TOL` at the pre-shape is a start
   collision. Otherwise every finger (the description's fingers: the chain from the palm to
   a fingertip, its closing joints the hand joints with a ``close`` direction and the mimic
   joints that follow them) closes as the kinematic closing closes it, on its own
   (:class:`~kinegrasp_env.physics.jaw_motors.JawMotors`): its first
   closing joint (from the palm) by a velocity motor of its own towards closing at its URDF
   velocity limit, with its effort limit
   (:func:`~kinegrasp_env.physics.hand_motors.motor_efforts`: the URDF's ``<limit effort>``
   unless the description's ``efforts`` overrides it); the finger's other closing joints
   follow it by position motors (their effort limits) at the values the kinematic closing's
   one parameter gives them (each moving at its rate: the mimic multiplier times the close
   direction). A closing joint that another hand joint drives (an independently actuated
   phalanx) has a motor of its own, switched while the hand closes by the kinematic
   closing's touch rule (:class:`~kinegrasp_env.physics.hand_motors.TouchRule`: a
   touching link's joints held by their holding efforts, the finger's last motor pressing at a
   creep); a hand joint that closes no finger (a spread) is held at its pre-shape value
   (:func:`~kinegrasp_env.physics.hand_motors.preshape_holds`; both efforts:
   :func:`~kinegrasp_env.physics.hand_motors.hold_efforts`). The fingers are not coupled to
   each other: each stops where it touches, as the kinematic closing's self-centring jaws do
   (:mod:`~kinegrasp_env.closing.generic_reference`; the hand is held by the anchor, so a
   coupled pair could not centre itself on the pinned object). On a free object (the physics
   engine's closing: :meth:`RobotHold.close_hand` with ``pin=False``) the jaws one actuator
   moves are coupled as the gripper couples them (a finger's motor joint that is a mimic
   joint of another finger's follows it:
   :func:`~kinegrasp_env.physics.hand_motors.coupled_leaders`), so the first jaw to touch
   pushes the object until the other meets it. A mimic joint that closes no finger follows
   its driver's mimic value (a position motor, its holding effort). The closing ends when
   the motors stall (a pressing one counts as stalled:
   :func:`~kinegrasp_env.physics.hold_runner.close_until_stall` on positions divided by
   their closing speeds: moving at less than ``stall_fraction`` of the closing speed) or
   after ``max_time``; then one contact per touching finger link (pybullet's contact records
   within ``touch_distance`` on the deepest record's face,
   :func:`~kinegrasp_env.physics.pybullet_contacts.merge_records`, averaged without force
   weights: :func:`world_contacts`), in the object frame
   (:func:`~kinegrasp_env.physics.hold_runner.in_object_frame`). Hand and object carry
   Bullet's polyhedral (SAT) contact features, so a pad on a face touches it at the corners
   of their overlap (:class:`~kinegrasp_env.physics.robot_world.RobotPhysicsWorld`).
2. **grip**: the rule for jaws. The balanced-grip linear programme
   (:mod:`~kinegrasp_env.physics.grip_forces`) maps contact forces to revolute joint
   torques through levers a x (p - o); a prismatic jaw has no lever (its force is the joint
   force along its axis), so it is not used here. Instead **every closing motor keeps
   pushing with its full effort limit** (the velocity motor of the closing, held on through
   the grip, the release and every phase): two opposed jaws with equal efforts press the
   object with equal and opposite forces along the closing axis, an internal force when the
   contacts face each other. Fewer than two touching fingers: ``no_grip``. The same rule
   holds a revolute finger (its motors at their effort limits; no balance of its torques);
   the touch rule's switches stay where the closing left them (a held joint held, a
   pressing motor pressing, in every phase). A hand of revolute fingers driven on their own
   grips by the balanced grip instead (:mod:`~kinegrasp_env.physics.balanced_grip`).
3. the release and the phases: :func:`~kinegrasp_env.physics.hold_runner.hold_test`, the
   protocol's sequence and rules (grip until steady, ``grip_shift_mm``, ``grip_lost``, the
   rest control, six gravity directions, the lift, the optional shake), over the primitives
   of :class:`RobotSteps`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult, RobotContact
from kinegrasp_env.closing.close_rules import CONTACT_TOL, START_TOL
from kinegrasp_env.physics import hold_runner
from kinegrasp_env.physics.balanced_grip import GripLayout, balances, grip_layout
from kinegrasp_env.physics.grip_forces import GripContact
from kinegrasp_env.physics.hand_motors import (
    hold_efforts,
    motor_efforts,
)
from kinegrasp_env.physics.hold_runner import close_until_stall, in_object_frame
from kinegrasp_env.physics.jaw_motors import JawMotors, finger_link_indices
from kinegrasp_env.physics.protocol import START_COLLISION, HoldProtocol, HoldResult
from kinegrasp_env.physics.pybullet_contacts import finger_forces, merge_records
from kinegrasp_env.physics.pybullet_hold import GripControl, PybulletSteps
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.physics.robot_world import ROOT_LINK, RobotPhysicsWorld
from kinegrasp_env.robot.catalog import as_description
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.world.objects import GraspObject


@dataclass(frozen=True)
class RobotMotorSettings:
    """The closing's end (the motors themselves: :func:`~kinegrasp_env.physics.hand_motors.
    motor_efforts`).

    Attributes:
        stall_fraction: a closing joint has stalled when it moves at less than this fraction
            of its closing speed, averaged over ``stall_window`` seconds; the closing ends
            when every closing joint has, at ``stall_checks`` consecutive windows.
        max_time: longest closing, seconds.
        touch_distance: a contact record within this distance (metres) is a contact.
    """

    stall_fraction: float = 0.02
    stall_window: float = 0.05
    stall_checks: int = 2
    max_time: float = 2.0
    touch_distance: float = CONTACT_TOL

    @property
    def stall_speed(self) -> float:
        """The stall rule of :func:`~kinegrasp_env.physics.hold_runner.close_until_stall` on
        positions in seconds of travel (position / closing speed)."""
        return self.stall_fraction


#: The closing's end for the quick holding test
#: (:data:`~kinegrasp_env.physics.protocol.QUICK_PROTOCOL`): stalled over two 10 ms windows.
QUICK_MOTORS = RobotMotorSettings(stall_window=0.01)
def world_contacts(world: RobotPhysicsWorld, distance: float) -> list[GripContact]:
    """One contact per touching finger link, world frame, finger-major: its records on the
    deepest record's face (:func:`~kinegrasp_env.physics.pybullet_contacts.merge_records`)
    averaged without force weights, i.e. the centre of the corners of the pad's overlap
    with the face (a rigid pad tilted by a fraction of a degree puts its whole force on one
    corner, whichever the solver picks: the centre of pressure is not the patch's)."""
    links = finger_link_indices(world)
    records: dict[tuple[int, int], list[tuple]] = {}
    for rec in world.contact_points():
        if rec[3] in links and rec[8] <= distance:
            records.setdefault(links[rec[3]], []).append(rec)
    return [GripContact(finger, link,
                        *merge_records([(*r[:9], 0.0, *r[10:]) for r in records[(f, link)]]))
            for f, link in sorted(records) for finger in (f,)]


class RobotSteps(PybulletSteps):
    """The holding test's primitives (:class:`~kinegrasp_env.physics.pybullet_hold.
    PybulletSteps`) in a :class:`RobotPhysicsWorld`: the grip is the closing motors held on
    (:class:`JawMotors`, the steps' ``control``), the fingers and the palm the description's."""

    def __init__(self, world: RobotPhysicsWorld, jaws: JawMotors, protocol: HoldProtocol,
                 layout: GripLayout | None = None) -> None:
        super().__init__(world, protocol, world.description.palm_link, ROOT_LINK,
                         control=jaws)
        self.layout = layout

    def grip(self) -> bool:
        contacts = world_contacts(self.world, CONTACT_TOL)
        if len({c.finger for c in contacts}) < 2:
            return False
        if self.layout is None:  # jaws: the closing motors stay on
            return True
        spring = self.layout.world_spring(self.world, contacts, self.protocol.grip_advance)
        if spring is None:
            return False
        self.control = GripControl(self.world, spring, self.layout.names, self.layout.upper)
        return True

    def finger_forces(self) -> np.ndarray:
        return finger_forces(self.world, finger_link_indices(self.world),
                             len(self.world.description.fingers))


def closing_result(found: list[GripContact], object_pose: np.ndarray, fingers: int,
                   joints: dict[str, float]) -> RobotCloseResult:
    """A finished physics closing as the engines score it: the contacts ``found`` (world
    frame, one per touching finger link) in the frame of the object at ``object_pose``
    (4, 4), each finger that touches none ``missed`` (``fingers`` in all), and every closing
    joint's value (name -> radians or metres)."""
    contacts = [RobotContact(c.finger, c.link, c.point, c.normal, 0.0)
                for c in in_object_frame(found, object_pose)]
    touched = {c.finger for c in contacts}
    return RobotCloseResult(False, contacts, tuple(f not in touched for f in range(fingers)),
                            joints=joints)


class DescriptionHold:
    """What the holding test of a description robot's hand keeps in any simulator: the
    robot, the protocol, the closing's end, the motors, and the palm pose and hand joint
    values of a configuration (arguments: :class:`RobotHold`'s).

    Attributes:
        motors: the closing motors (their efforts and where they came from).
    """

    def __init__(self, description: RobotDescription | str, protocol: HoldProtocol,
                 settings: RobotMotorSettings | None = None) -> None:
        self.description = description = as_description(description)
        self.protocol = protocol
        self.settings = settings or RobotMotorSettings()
        self.motors = motor_efforts(description, protocol.torque_scale)
        #: what holds a joint that does not push (:func:`~kinegrasp_env.physics.hand_motors.
        #: hold_efforts`; checked here, before any draw)
        self.holds = hold_efforts(description, self.motors)
        #: the balanced grip's joints for a hand of revolute fingers, else None (jaws)
        self.layout = (grip_layout(description, protocol.torque_scale)
                       if balances(description) else None)
        self.kinematics = Kinematics(description.model)

    def palm_poses(self, q: np.ndarray) -> np.ndarray:
        """(n, 4, 4) the palm poses of configurations q (n, dof) (forward kinematics)."""
        return self.kinematics.pose(np.atleast_2d(np.asarray(q, dtype=float)),
                                    self.description.palm_link)

    def hand_values(self, q: np.ndarray, joints) -> dict[str, float]:
        """The values (radians or metres) of configuration q (dof,) of the joints among
        ``joints`` (the names a simulator's hand has)."""
        return {name: value for name, value in self.description.model.expand(
            np.asarray(q, dtype=float)).items() if name in joints}


class RobotHold(DescriptionHold):
    """The holding test of a description robot in pybullet, one draw at a time.

    Args:
        description: the robot (or a catalog robot's name).
        obj: the catalog object (or its name).
        friction: Coulomb friction between finger and object (the quality's mu).
        protocol: the holding test's settings; ``torque_scale`` multiplies every motor's
            effort.
        world: :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings` (object free).
        settings: :class:`RobotMotorSettings`.

    Attributes:
        motors: the closing motors (their efforts and where they came from).
    """

    name = "pybullet"

    def __init__(self, description: RobotDescription | str, obj: GraspObject | str,
                 friction: float, protocol: HoldProtocol, world: WorldSettings | None = None,
                 settings: RobotMotorSettings | None = None) -> None:
        world_settings = replace(world or WorldSettings(), friction=friction)
        if not world_settings.object_free:
            raise ValueError("the holding test needs a free object (object_free=True)")
        super().__init__(description, protocol, settings)
        self.world = RobotPhysicsWorld(self.description, obj, world_settings)

    def close_hand(self, q: np.ndarray, pin: bool = True
                   ) -> tuple[RobotCloseResult, JawMotors | None]:
        """The closing of configuration q (dof,) on the pinned object (module docstring,
        step 1; ``pin=False``: the object free, with its support damping, as the physics
        engine closes, and the jaws one actuator moves coupled): its
        contacts in the object frame where the object ended, and the motors (None: start
        collision)."""
        world, fingers = self.world, self.description.fingers
        world.reset(self.palm_poses(q)[0], self.hand_values(q, world.joint_index))
        if pin:
            world.pin_object()
        if world.penetration() > START_TOL:
            return RobotCloseResult(True, missed=(False,) * len(fingers)), None
        jaws = JawMotors(world, self.motors, self.holds, coupled=not pin,
                         touch_distance=self.settings.touch_distance)
        close_until_stall(jaws.step, jaws.travel, self.settings, world.settings.time_step)
        jaws.closing = False
        joints = {m.joint: world.bullet.getJointState(world.hand, world.joint_index[m.joint])[0]
                  for m in self.motors}
        return closing_result(world_contacts(world, self.settings.touch_distance),
                              world.object_pose(), len(fingers), joints), jaws

    def run_draw(self, q: np.ndarray) -> tuple[RobotCloseResult, HoldResult]:
        """One draw at configuration q (dof,): the closing on the pinned object and the
        holding test."""
        closing, jaws = self.close_hand(q)
        if jaws is None:
            return closing, HoldResult(START_COLLISION)
        self.world.damp_object(False)
        return closing, hold_runner.hold_test(
            RobotSteps(self.world, jaws, self.protocol, self.layout), self.protocol)

    def close(self) -> None:
        self.world.close()
