"""The holding test (:mod:`~kinegrasp_env.physics.protocol`) executed in pybullet.

:class:`PybulletHold` is the ``pybullet`` simulator of the registry
(:mod:`~kinegrasp_env.physics.simulators`): one draw is :func:`physics_close` with the object
pinned (:meth:`~kinegrasp_env.physics.pybullet_world.PhysicsWorld.pin_object`), then
:func:`hold_test`:

* grip: :func:`grip_control` (the balanced torques of the closing's contacts,
  :mod:`~kinegrasp_env.physics.grip_forces`, as joint springs, applied as joint torques at
  every step), stepped in windows of ``steady_window`` until the fingers' normal forces
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

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from kinegrasp_env.closing.reference import CloseResult
from kinegrasp_env.physics.grip_forces import (
    SpringGrip,
    balanced_torques,
    loaded_joints,
    tip_offsets,
)
from kinegrasp_env.physics.motion import hand_path, lift_motion, shake_motion
from kinegrasp_env.physics.protocol import (
    GRAVITY_PHASES,
    HELD,
    NO_GRIP,
    REST_PHASE,
    START_COLLISION,
    HoldProtocol,
    HoldResult,
    final_outcome,
    grip_verdict,
    pose_change,
    steady,
    within,
)
from kinegrasp_env.physics.pybullet_closing import (
    FLEXION_JOINTS,
    MotorSettings,
    finger_forces,
    joint_frames,
    physics_close,
    world_contacts,
)
from kinegrasp_env.physics.pybullet_world import PhysicsWorld, WorldSettings
from kinegrasp_env.world.objects import GraspObject


def object_in_palm(world: PhysicsWorld) -> np.ndarray:
    """(4, 4) the object's pose in the palm frame now."""
    return np.linalg.inv(world.link_pose("palm")) @ world.object_pose()


def steps_of(seconds: float, time_step: float) -> int:
    return max(1, round(seconds / time_step))


class GripControl:
    """The grip (:class:`~kinegrasp_env.physics.grip_forces.SpringGrip`) in pybullet: the
    loaded flexion joints torque-controlled at every step (their motors off), the others
    held by their position controllers (``hold_torque``) where they stalled; set again
    after a ``restoreState``.

    Args:
        world: the physics world right after the closing.
        motors: the finger motors (``hold_torque``).
        spring: the grip's joint rule.
    """

    def __init__(self, world: PhysicsWorld, motors: MotorSettings, spring: SpringGrip) -> None:
        self.world, self.motors, self.spring = world, motors, spring
        self.indices = [world.joint_index[j] for j in FLEXION_JOINTS]
        self.loaded = [i for i, on in zip(self.indices, spring.loaded, strict=True) if on]
        self.restart()

    def restart(self) -> None:
        bullet, hand, spring = self.world.bullet, self.world.hand, self.spring
        held = [i for i, on in zip(self.indices, spring.loaded, strict=True) if not on]
        if held:
            bullet.setJointMotorControlArray(
                hand, held, bullet.POSITION_CONTROL,
                targetPositions=spring.stall[~spring.loaded].tolist(),
                forces=[self.motors.hold_torque] * len(held))
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


def grip_control(world: PhysicsWorld, motors: MotorSettings,
                 protocol: HoldProtocol) -> GripControl | None:
    """The grip of a hand just closed on the pinned object: the balanced torques of its
    contacts (:func:`~kinegrasp_env.physics.grip_forces.balanced_torques`, the world's
    friction, the motors' torque limits) as springs (``protocol.grip_advance``); None when
    no contact forces in equilibrium exist."""
    contacts = world_contacts(world, motors.touch_distance)
    axes, origins, tips = joint_frames(world)
    pose = world.object_pose()
    center = pose[:3, :3] @ world.obj.center_of_mass + pose[:3, 3]
    limits = np.array([motors.proximal_torque, motors.distal_torque] * 3)
    solution = balanced_torques(contacts, axes, origins, center, limits,
                                world.settings.friction)
    if solution is None:
        return None
    stall, _ = world.joint_states(FLEXION_JOINTS)
    offsets = tip_offsets(axes, origins, tips, protocol.grip_advance)
    return GripControl(world, motors, SpringGrip.of(stall, solution, offsets, limits,
                                                    loaded_joints(contacts)))


def grip_until_steady(world: PhysicsWorld, control: GripControl,
                      protocol: HoldProtocol) -> tuple[np.ndarray, float]:
    """Press until the fingers' forces are steady twice in a row (after at least
    ``grip_min_time``) or ``grip_max_time``: (the forces (3,), newtons; seconds run)."""
    dt = world.settings.time_step
    window = steps_of(protocol.steady_window, dt)
    previous, calm, steps = None, 0, 0
    while steps * dt < protocol.grip_max_time - 1e-12:
        control.step(window)
        steps += window
        forces = finger_forces(world)
        calm = calm + 1 if previous is not None and steady(previous, forces, protocol) else 0
        previous = forces
        if calm >= 2 and steps * dt >= protocol.grip_min_time - 1e-12:
            break
    return previous, steps * dt


def watch(world: PhysicsWorld, control: GripControl, protocol: HoldProtocol,
          reference: np.ndarray, steps: int, before_step=None) -> tuple[bool, float, float]:
    """Step ``steps`` times (calling ``before_step(k)`` before step k, 0-based), checking the
    object against ``reference`` (its pose in the palm frame) every ``check_interval`` and at
    the end; stop at the first failed check: (held, largest distance m, largest angle rad)."""
    every = steps_of(protocol.check_interval, world.settings.time_step)
    com = world.obj.center_of_mass
    worst_distance = worst_angle = 0.0
    for k in range(steps):
        if before_step is not None:
            before_step(k)
        control.step()
        if (k + 1) % every and k + 1 < steps:
            continue
        distance, angle = pose_change(reference, object_in_palm(world), com)
        worst_distance, worst_angle = max(worst_distance, distance), max(worst_angle, angle)
        if not within(protocol, distance, angle):
            return False, worst_distance, worst_angle
    return True, worst_distance, worst_angle


def follow(world: PhysicsWorld, path) -> Callable[[int], None]:
    """A ``before_step`` for :func:`watch` that moves the hand's anchor along ``path``
    (positions (s, 3), orientations (s, 4), :func:`hand_path`)."""
    positions, orientations = path[0], path[1]

    def move(k: int) -> None:
        world.anchor_at(positions[k].tolist(), orientations[k].tolist())
    return move


def hold_test(world: PhysicsWorld, motors: MotorSettings, protocol: HoldProtocol) -> HoldResult:
    """The holding test of a hand just closed on a pinned object (module docstring).

    Args:
        world: the physics world right after ``physics_close(..., pin=True)``.
        motors: the finger motors (their torque limits are the protocol's).
        protocol: :class:`~kinegrasp_env.physics.protocol.HoldProtocol`.
    """
    if world.pin is None:
        raise ValueError("the holding test starts from a pinned object (physics_close pin=True)")
    dt = world.settings.time_step
    world.damp_object(False)
    control = grip_control(world, motors, protocol)
    if control is None:
        return HoldResult(NO_GRIP)
    gripped, grip_time = grip_until_steady(world, control, protocol)
    pinned = object_in_palm(world)
    pin_force, pin_torque = world.pin_load()
    world.release_object()
    world.remove_table()
    control.step(steps_of(protocol.settle_time, dt))
    released = finger_forces(world)
    reference = object_in_palm(world)
    shift, turn = pose_change(pinned, reference, world.obj.center_of_mass)
    result = HoldResult(grip_verdict(gripped, released, protocol), shift, turn, gripped,
                        released, grip_time, pin_force, pin_torque)
    if result.outcome != HELD:
        return result
    state = world.bullet.saveState()
    try:
        run_phases(world, control, protocol, reference, state, result)
    finally:
        world.bullet.removeState(state)
    result.outcome = final_outcome(HELD, result.phase_held)
    return result


def run_phases(world: PhysicsWorld, control: GripControl, protocol: HoldProtocol,
               reference: np.ndarray, state: int, result: HoldResult) -> None:
    """Every phase of ``protocol`` from the saved ``state``, recorded in ``result`` (the
    hand's anchor, which ``restoreState`` does not restore, put back where the state has the
    hand's root)."""
    dt = world.settings.time_step
    world.restore_without_contacts(state)
    anchor = world.link_pose("hand_root")

    def record(name: str, outcome: tuple[bool, float, float]) -> None:
        result.phase_held[name], result.phase_shift[name], result.phase_turn[name] = outcome

    def restart(gravity: np.ndarray) -> None:
        world.restore_without_contacts(state)
        world.move_anchor(anchor)
        control.restart()
        world.set_gravity(gravity)

    restart(np.zeros(3))
    record(REST_PHASE, watch(world, control, protocol, reference,
                             steps_of(protocol.gravity_time, dt)))
    for name, direction in GRAVITY_PHASES.items():
        restart(protocol.gravity * np.asarray(direction))
        steps = steps_of(protocol.gravity_time, dt)
        record(name, watch(world, control, protocol, reference, steps))
    restart(np.array([0.0, 0.0, -protocol.gravity]))
    root, palm = world.link_pose("hand_root"), world.link_pose("palm")[:3, 3]
    times = dt * np.arange(1, steps_of(protocol.lift_time + protocol.hold_time, dt) + 1)
    path = hand_path(lift_motion(protocol, times), np.zeros(times.size), root, palm)
    record("lift", watch(world, control, protocol, reference, times.size, follow(world, path)))
    if protocol.shake and result.phase_held["lift"]:
        lifted = np.eye(4)
        lifted[:3, 3] = [0.0, 0.0, protocol.lift_height]
        times = dt * np.arange(1, steps_of(protocol.shake_time, dt) + 1)
        shifts, angles = shake_motion(protocol, times)
        path = hand_path(shifts, angles, lifted @ root, palm + lifted[:3, 3])
        record("shake", watch(world, control, protocol, reference, times.size, follow(world, path)))


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

