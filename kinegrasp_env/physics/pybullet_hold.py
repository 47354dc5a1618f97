"""The holding test's primitives in pybullet (:class:`PybulletSteps`) and the balanced grip
as joint springs (:class:`GripControl`).

A hand's holding test (:class:`~kinegrasp_env.physics.robot_hold.RobotHold`) runs
:func:`~kinegrasp_env.physics.hold_runner.hold_test` over these primitives: the grip stepped
in windows of ``steady_window`` until the fingers' normal forces are steady; the release
(the pin removed, the support table, if any, put out of reach, object damping off, gravity
off, ``settle_time``), after which the state is saved (``saveState``); each phase (the rest
control first, then the disturbances) from that saved state (``restoreState``; the motors'
commands set again), the object's pose in the palm frame checked every ``check_interval``.
The lift and the shake move the constraint that holds the hand's root along
:func:`~kinegrasp_env.physics.motion.hand_path`.

Every phase starts from the saved state with no contact cached from the phase before
(:meth:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld.restore_without_contacts`: every
phase's first step solved cold; whether it is warm-started from the contacts of the saved
state changed the verdicts of 4 of 24 shipped-grasp draws at twice the assumed torques), so a
phase's verdict does not depend on which phases ran before it, and a draw's result depends
only on its inputs (the world's ``reset`` drops the previous draw's contact caches).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.physics.grip_forces import SpringGrip
from kinegrasp_env.physics.hold_runner import WorldSteps
from kinegrasp_env.physics.protocol import HoldProtocol
from kinegrasp_env.physics.pybullet_world import PhysicsWorld


class GripControl:
    """The grip (:class:`~kinegrasp_env.physics.grip_forces.SpringGrip`) in pybullet: the
    loaded grip joints torque-controlled at every step (their motors off), the others held
    by their position controllers (their holding torques) where they stalled; set again
    after a ``restoreState``.

    Args:
        world: the physics world right after the closing.
        spring: the grip's joint rule.
        joints: the grip joints' names; hold_torques: (J,) each one's holding torque where it
            is held, N m.
    """

    def __init__(self, world: PhysicsWorld, spring: SpringGrip, joints: tuple[str, ...],
                 hold_torques: np.ndarray) -> None:
        self.world, self.spring = world, spring
        self.indices = [world.joint_index[j] for j in joints]
        self.hold_torques = np.asarray(hold_torques, dtype=float)
        self.loaded = [i for i, on in zip(self.indices, spring.loaded, strict=True) if on]
        self.restart()

    def restart(self) -> None:
        bullet, hand, spring = self.world.bullet, self.world.hand, self.spring
        held = [i for i, on in zip(self.indices, spring.loaded, strict=True) if not on]
        if held:
            bullet.setJointMotorControlArray(
                hand, held, bullet.POSITION_CONTROL,
                targetPositions=spring.stall[~spring.loaded].tolist(),
                forces=self.hold_torques[~spring.loaded].tolist())
        if self.loaded:
            bullet.setJointMotorControlArray(hand, self.loaded, bullet.VELOCITY_CONTROL,
                                             targetVelocities=[0.0] * len(self.loaded),
                                             forces=[0.0] * len(self.loaded))

    def step(self, steps: int = 1) -> None:
        bullet, hand = self.world.bullet, self.world.hand
        for _ in range(steps):
            if self.loaded:
                angles = np.array([s[0] for s in bullet.getJointStates(hand, self.indices)])
                torques = self.spring.torques(angles)[self.spring.loaded]
                bullet.setJointMotorControlArray(hand, self.loaded, bullet.TORQUE_CONTROL,
                                                 forces=torques.tolist())
            bullet.stepSimulation()


class PybulletSteps(WorldSteps):
    """The holding test's primitives (:class:`~kinegrasp_env.physics.hold_runner.HoldSteps`)
    in a :class:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld` that any hand shares:
    the grip's control (``control``: ``step(steps)`` and ``restart()``, e.g.
    :class:`GripControl`) steps the world; a saved state is pybullet's ``saveState``, each
    phase restored from it without cached contacts and with the hand's anchor (which
    ``restoreState`` does not restore) put back where the state has the hand's root. A
    hand's steps add its grip and its fingers' forces.

    Args:
        world: the physics world right after the closing.
        protocol: the holding test's settings.
        palm_link, root_link: the hand's palm (the object's pose is measured in its frame)
            and its root (the anchor constraint holds it).
        control: the grip, when it is already on.
    """

    def __init__(self, world: PhysicsWorld, protocol: HoldProtocol, palm_link: str,
                 root_link: str, control=None) -> None:
        super().__init__(world, protocol, palm_link)
        self.root_link = root_link
        self.control, self.state, self.anchor = control, None, None

    def advance(self, steps: int = 1) -> None:
        self.control.step(steps)

    def save(self) -> None:
        self.state, self.anchor = self.world.bullet.saveState(), None

    def start_phase(self, gravity: np.ndarray) -> None:
        world = self.world
        if self.anchor is None:
            world.restore_without_contacts(self.state)
            self.anchor = world.link_pose(self.root_link)
        world.restore_without_contacts(self.state)
        world.move_anchor(self.anchor)
        self.control.restart()
        world.set_gravity(gravity)

    def hand_start(self) -> tuple[np.ndarray, np.ndarray]:
        world = self.world
        return world.link_pose(self.root_link), world.link_pose(self.palm_link)[:3, 3]

    def move_hand(self, position: np.ndarray, orientation: np.ndarray) -> None:
        self.world.anchor_at(position.tolist(), orientation.tolist())

    def discard(self) -> None:
        self.world.bullet.removeState(self.state)
        self.state = None
