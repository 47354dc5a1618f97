"""The holding test (:mod:`~kinegrasp_env.physics.protocol`) executed in pybullet.

:class:`PybulletHold` is the ``pybullet`` simulator of the registry
(:mod:`~kinegrasp_env.physics.simulators`): one draw is :func:`physics_close` with the object
pinned (:meth:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld.pin_object`), then
:func:`hold_test`:

* grip: :func:`grip_control` (the balanced torques of the closing's contacts,
  :mod:`~kinegrasp_env.physics.grip_forces`, on the flexion and spread joints, as joint
  springs, applied as joint torques at every step), stepped in windows of
  ``steady_window`` until the fingers' normal forces
  (:func:`~kinegrasp_env.physics.pybullet_closing.finger_forces`) are steady;
* release: the pin removed, the support table (if any) put out of reach, object damping off,
  gravity off, ``settle_time``; then the state is saved (``saveState``);
* each phase (the rest control first, then the disturbances) starts from that saved state
  (``restoreState``; the motors' commands are set again), the object's pose in the palm frame
  checked every ``check_interval``. The lift and the shake move the constraint that holds the
  hand's root along :func:`~kinegrasp_env.physics.motion.hand_path`.

Every phase starts from the saved state with no contact cached from the phase before
(:meth:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld.restore_without_contacts`: every
phase's first step solved cold; whether it is warm-started from the contacts of the saved
state changed the verdicts of 4 of 24 shipped-grasp draws at twice the assumed torques), so a
phase's verdict does not depend on which phases ran before it, and a draw's result depends
only on its inputs (the world's :meth:`reset` drops the previous draw's contact caches).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from kinegrasp_env.physics import hold_runner
from kinegrasp_env.physics.grip_forces import GripJoints, SpringGrip, spring_grip
from kinegrasp_env.physics.hand_result import CloseResult
from kinegrasp_env.physics.hold_runner import GRIP_JOINTS, WorldSteps, grip_joints
from kinegrasp_env.physics.hold_runner import object_in_palm as object_in_palm  # re-exported
from kinegrasp_env.physics.protocol import START_COLLISION, HoldProtocol, HoldResult
from kinegrasp_env.physics.pybullet_closing import (
    MotorSettings,
    finger_forces,
    finger_links,
    physics_close,
    world_contacts,
)
from kinegrasp_env.physics.pybullet_world import PhysicsWorld, WorldSettings
from kinegrasp_env.robot.default_robot import FINGERS, FINGERTIP_LINKS
from kinegrasp_env.world.objects import GraspObject


class GripControl:
    """The grip (:class:`~kinegrasp_env.physics.grip_forces.SpringGrip`) in pybullet: the
    loaded grip joints (:data:`~kinegrasp_env.physics.hold_runner.GRIP_JOINTS`) torque-
    controlled at every step (their motors off), the others held by their position
    controllers (``hold_torque``) where they stalled; set again after a ``restoreState``.

    Args:
        world: the physics world right after the closing.
        motors: the finger motors (``hold_torque``).
        spring: the grip's joint rule.
        joints: the grip joints' names (default the SDH's); hold_torques: (J,) each one's
            holding torque where it is held, N m (default the motors' ``hold_torque``).
    """

    def __init__(self, world: PhysicsWorld, motors: MotorSettings | None, spring: SpringGrip,
                 joints: tuple[str, ...] = GRIP_JOINTS,
                 hold_torques: np.ndarray | None = None) -> None:
        self.world, self.motors, self.spring = world, motors, spring
        self.indices = [world.joint_index[j] for j in joints]
        self.hold_torques = (np.full(len(joints), motors.hold_torque) if hold_torques is None
                             else np.asarray(hold_torques, dtype=float))
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


def grip_joints_now(world: PhysicsWorld, motors: MotorSettings) -> GripJoints:
    """The hand's grip joints in ``world`` now (:func:`~kinegrasp_env.physics.hold_runner.
    grip_joints`)."""
    axes, origins = world.joint_frames(GRIP_JOINTS)
    tips = np.array([world.link_pose(tip)[:3, 3] for tip in FINGERTIP_LINKS])
    return grip_joints(axes, origins, tips, motors)


def grip_control(world: PhysicsWorld, motors: MotorSettings,
                 protocol: HoldProtocol) -> GripControl | None:
    """The grip of a hand just closed on the pinned object: the balanced torques of its
    contacts (:func:`~kinegrasp_env.physics.grip_forces.spring_grip`, the world's friction,
    the motors' torque limits) as springs (``protocol.grip_advance``); None when no contact
    forces in equilibrium exist."""
    stall, _ = world.joint_states(GRIP_JOINTS)
    spring = spring_grip(world_contacts(world, motors.touch_distance),
                         grip_joints_now(world, motors), world.object_pose(),
                         world.obj.center_of_mass, stall, world.settings.friction,
                         protocol.grip_advance)
    return None if spring is None else GripControl(world, motors, spring)


class PybulletSteps(WorldSteps):
    """The holding test's primitives (:class:`~kinegrasp_env.physics.hold_runner.HoldSteps`)
    in a :class:`PhysicsWorld`: the grip is :class:`GripControl`; a saved state is pybullet's
    ``saveState``, each phase restored from it without cached contacts and with the hand's
    anchor (which ``restoreState`` does not restore) put back where the state has the hand's
    root.

    Args:
        world: the physics world right after the closing.
        motors, protocol: the finger motors and the holding test's settings.
        control: the grip, when it is already on.
        state: a saved state, when there is one.
    """

    #: the hand's root link (the anchor constraint holds it)
    root_link = "hand_root"

    def __init__(self, world: PhysicsWorld, motors: MotorSettings, protocol: HoldProtocol,
                 control: GripControl | None = None, state: int | None = None) -> None:
        super().__init__(world, motors, protocol)
        self.control, self.state, self.anchor = control, state, None

    def grip(self) -> bool:
        self.control = grip_control(self.world, self.motors, self.protocol)
        return self.control is not None

    def advance(self, steps: int = 1) -> None:
        self.control.step(steps)

    def finger_forces(self) -> np.ndarray:
        return finger_forces(self.world, finger_links(self.world), len(FINGERS))

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


def grip_until_steady(world: PhysicsWorld, control: GripControl,
                      protocol: HoldProtocol) -> tuple[np.ndarray, float]:
    """:func:`~kinegrasp_env.physics.hold_runner.grip_until_steady` with ``control``: (the
    fingers' forces (3,), newtons; seconds run)."""
    return hold_runner.grip_until_steady(
        PybulletSteps(world, control.motors, protocol, control), protocol)


def hold_test(world: PhysicsWorld, motors: MotorSettings, protocol: HoldProtocol) -> HoldResult:
    """The holding test of a hand just closed on a pinned object (module docstring).

    Args:
        world: the physics world right after ``physics_close(..., pin=True)``.
        motors: the finger motors (their torque limits are the protocol's).
        protocol: :class:`~kinegrasp_env.physics.protocol.HoldProtocol`.
    """
    if world.pin is None:
        raise ValueError("the holding test starts from a pinned object (physics_close pin=True)")
    world.damp_object(False)
    return hold_runner.hold_test(PybulletSteps(world, motors, protocol), protocol)


def run_phases(world: PhysicsWorld, control: GripControl, protocol: HoldProtocol,
               reference: np.ndarray, state: int, result: HoldResult) -> None:
    """Every phase of ``protocol`` from the saved ``state`` (kept: the caller removes it),
    recorded in ``result`` (:func:`~kinegrasp_env.physics.hold_runner.run_phases`)."""
    steps = PybulletSteps(world, control.motors, protocol, control, state)
    hold_runner.run_phases(steps, protocol, reference, result)


class PybulletHold:
    """The holding test in pybullet, one draw at a time (the ``pybullet`` simulator).

    Args:
        obj: the catalog object.
        friction: Coulomb friction between finger and object (the quality's mu).
        protocol: :class:`~kinegrasp_env.physics.protocol.HoldProtocol`; its torque limits
            replace ``motors``'.
        world: :class:`~kinegrasp_env.physics.pybullet_world.WorldSettings` (object free).
        motors: :class:`~kinegrasp_env.physics.pybullet_closing.MotorSettings`.
    """

    name = "pybullet"

    def __init__(self, obj: GraspObject, friction: float, protocol: HoldProtocol,
                 world: WorldSettings | None = None, motors: MotorSettings | None = None) -> None:
        settings = replace(world or WorldSettings(), friction=friction)
        if not settings.object_free:
            raise ValueError("the holding test needs a free object (object_free=True)")
        self.protocol = protocol
        self.motors = (motors or MotorSettings()).with_torques(protocol.torques)
        self.world = PhysicsWorld(obj, settings)

    def run_draw(self, root_pose: np.ndarray, preshape: np.ndarray
                 ) -> tuple[CloseResult, HoldResult]:
        """One draw: the closing on the pinned object (its contacts in the object frame, as
        the kinematic closing reports them) and the holding test."""
        closing = physics_close(self.world, root_pose, preshape, self.motors, pin=True)
        if closing.start_collision:
            return closing, HoldResult(START_COLLISION)
        return closing, hold_test(self.world, self.motors, self.protocol)

    def close(self) -> None:
        self.world.close()

