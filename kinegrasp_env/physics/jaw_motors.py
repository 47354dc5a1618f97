"""The closing motors of a description robot's hand in pybullet (:class:`JawMotors`): each
finger's first closing joint by a velocity motor at its effort limit, its other closing joints
following by position motors, the touch rule's switches while the hand closes, and the
coupling of the jaws one actuator moves (the holding test's steps 1 and 2:
:mod:`~kinegrasp_env.physics.robot_hold`)."""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_rules import CONTACT_TOL
from kinegrasp_env.physics.hand_motors import (
    JointMotor,
    TouchRule,
    closing_followers,
    coupled_leaders,
    finger_leaders,
    preshape_holds,
)
from kinegrasp_env.physics.pybullet_contacts import touching_links
from kinegrasp_env.physics.robot_world import RobotPhysicsWorld

#: pybullet's position gain of the followers' motors in the coupled closing (the gripper's
#: own mechanism: one actuator, rigid linkages): 1 corrects a follower's whole error each
#: step, within its effort. At pybullet's default 0.1, which the holding test's closing
#: keeps (each finger on its own, the figures of docs/guides/physics.md), an xArm finger
#: joint lagged its knuckle by 0.03-0.06 rad under the contact force, tilting its pad so
#: that the pads touched a cube's faces 2-4 cm apart (its planned cube grasp at sigma 0 out
#: of force closure in the physics engine).
COUPLED_FOLLOWER_GAIN = 1.0
#: pybullet's default position gain, the followers' in the holding test's closing.
FOLLOWER_GAIN = 0.1


class JawMotors:
    """The closing motors (:mod:`~kinegrasp_env.physics.robot_hold`, steps 1 and 2) of a
    :class:`~kinegrasp_env.physics.robot_world.RobotPhysicsWorld`.

    Args:
        world: the world, hand at its pre-shape.
        motors: :func:`~kinegrasp_env.physics.hand_motors.motor_efforts`.
        holds: what holds a joint that does not push
            (:func:`~kinegrasp_env.physics.hand_motors.hold_efforts`).
        coupled: the jaws one actuator moves follow it
            (:func:`~kinegrasp_env.physics.hand_motors.coupled_leaders`), as the gripper's
            own coupling makes them, and every follower stiffly
            (:data:`COUPLED_FOLLOWER_GAIN`); else every finger closes on its own, its
            followers at pybullet's default gain.
        touch_distance: a contact record within this distance (metres) is a touch.
    """

    def __init__(self, world: RobotPhysicsWorld, motors: list[JointMotor],
                 holds: dict[str, float], coupled: bool = False,
                 touch_distance: float = CONTACT_TOL) -> None:
        self.world, self.touch_distance = world, touch_distance
        leaders = finger_leaders(world.description)
        if coupled:
            leaders -= set(coupled_leaders(world.description))
        self.motors = [m for m in motors if m.joint in leaders]
        self.indices = [world.joint_index[m.joint] for m in self.motors]
        self.speeds = np.array([m.speed for m in self.motors])
        start = {name: world.bullet.getJointState(world.hand, index)[0]
                 for name, index in world.joint_index.items()}
        #: (follower's index, followed joint's index, its rule), pybullet's joint indices
        #: looked up once (the followers are set at every step)
        self.gain = COUPLED_FOLLOWER_GAIN if coupled else FOLLOWER_GAIN
        self.followers = [(world.joint_index[f.joint], world.joint_index[f.source], f)
                          for f in closing_followers(world.description, motors, start,
                                                     coupled, holds)]
        #: the pre-shape joints held where they start
        self.fixed = preshape_holds(world.description, holds, start)
        self.touch = TouchRule(world.description, self.motors, holds,
                               world.settings.time_step, free=coupled)
        #: the touch rule acts while the hand closes (the holding test's phases keep its
        #: switches where the closing left them: :meth:`restart` sets them again)
        self.closing = True
        #: the motors the touch rule holds: joint name -> the value held (radians or metres)
        self.held: dict[str, float] = {}
        self.links = finger_link_indices(world)
        self.restart()

    def restart(self) -> None:
        """Every closing motor on (again: after a ``restoreState``), the held ones held, the
        pressing ones pressing."""
        bullet, hand = self.world.bullet, self.world.hand
        bullet.setJointMotorControlArray(
            hand, self.indices, bullet.VELOCITY_CONTROL,
            targetVelocities=[self.touch.velocity(m) for m in self.motors],
            forces=[m.effort for m in self.motors])
        for fixed in self.fixed:
            bullet.setJointMotorControl2(hand, self.world.joint_index[fixed.joint],
                                         bullet.POSITION_CONTROL, targetPosition=fixed.value,
                                         force=fixed.effort)
        for name, value in self.held.items():
            self.hold(name, value)
        self.follow()

    def hold(self, name: str, value: float) -> None:
        """Hold motor joint ``name`` at ``value`` (a position motor with its holding effort:
        :attr:`~kinegrasp_env.physics.hand_motors.TouchRule.efforts`)."""
        self.held[name] = value
        self.world.bullet.setJointMotorControl2(
            self.world.hand, self.world.joint_index[name], self.world.bullet.POSITION_CONTROL,
            targetPosition=value, force=self.touch.efforts[name])

    def touched(self) -> None:
        """Apply the touch rule (:class:`~kinegrasp_env.physics.hand_motors.TouchRule`) to
        the finger links touching the object now."""
        bullet, hand = self.world.bullet, self.world.hand
        held, pressing = self.touch.update(
            touching_links(self.world, self.links, self.touch_distance))
        for name in held:
            self.hold(name, bullet.getJointState(hand, self.world.joint_index[name])[0])
        for name, _ in pressing:
            motor = self.motors[[m.joint for m in self.motors].index(name)]
            bullet.setJointMotorControl2(hand, self.world.joint_index[name],
                                         bullet.VELOCITY_CONTROL,
                                         targetVelocity=self.touch.velocity(motor),
                                         force=motor.effort)

    def follow(self) -> None:
        """The followers' position motors at their values now."""
        bullet, hand = self.world.bullet, self.world.hand
        for index, source, f in self.followers:
            value = bullet.getJointState(hand, source)[0]
            bullet.setJointMotorControl2(
                hand, index, bullet.POSITION_CONTROL,
                targetPosition=f.target_start + f.ratio * (value - f.source_start),
                force=f.effort, positionGain=self.gain)

    def step(self, steps: int = 1) -> None:
        for _ in range(steps):
            if self.followers:
                self.follow()
            self.world.bullet.stepSimulation()
            if self.closing and self.touch.active:
                self.touched()

    def travel(self) -> np.ndarray:
        """(m,) the closing joints' positions in seconds of travel (value / closing speed; a
        pressing motor's 0: :meth:`~kinegrasp_env.physics.hand_motors.TouchRule.travel`)."""
        states = self.world.bullet.getJointStates(self.world.hand, self.indices)
        return self.touch.travel([m.joint for m in self.motors],
                                 np.array([s[0] for s in states]) / self.speeds)


def finger_link_indices(world: RobotPhysicsWorld) -> dict[int, tuple[int, int]]:
    """pybullet link index -> (finger, index of the link in the finger's ``links``)."""
    out: dict[int, tuple[int, int]] = {}
    for f, finger in enumerate(world.description.fingers):
        for k, link in enumerate(finger.links):
            out.setdefault(world.link_index[link], (f, k))
    return out

