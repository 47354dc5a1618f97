"""The holding test (:mod:`~kinegrasp_env.physics.protocol`) executed in MuJoCo.

:class:`MujocoHold` is the ``mujoco`` simulator: the same draw interface, protocol, phases,
thresholds and hand motion (:mod:`~kinegrasp_env.physics.motion`) as
:class:`~kinegrasp_env.physics.pybullet_hold.PybulletHold`, in
:class:`~kinegrasp_env.physics.mujoco_world.MujocoWorld`. One draw:

1. closing, the object pinned (a weld at its catalog pose): the closing controller of
   :mod:`~kinegrasp_env.physics.pybullet_closing` with the same rules and numbers
   (:class:`~kinegrasp_env.physics.pybullet_closing.MotorSettings`): flexion joints closing at
   ``closing_speed`` with their torque limits, spread joints held; a finger whose link touches
   (a contact within ``touch_distance``) has its proximal joint held, its distal joint creeps
   at ``creep_speed`` while the distal link touches; the end when every flexion joint has
   stalled. Contacts: one per touching finger link, merged from MuJoCo's records by the same
   rule (:func:`~kinegrasp_env.physics.pybullet_closing.merge_records`), object frame;
2. grip: pybullet's rule (:mod:`~kinegrasp_env.physics.grip_forces`): the closing's
   contacts give balanced joint torques, each loaded flexion or spread joint a spring (a ``general``
   actuator: gain k, bias -k q, its torque limit as force range), the others held, until the
   fingers' normal forces are steady;
3. release (pin off, table away), ``settle_time``; ``grip_shift`` and the grip verdict;
4. the phases from the saved state (``mj_getState`` / ``mj_setState``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from kinegrasp_env.closing.close_rules import START_TOL
from kinegrasp_env.physics import hold_runner
from kinegrasp_env.physics.grip_forces import GripContact, spring_grip
from kinegrasp_env.physics.hand_result import CloseResult
from kinegrasp_env.physics.hold_runner import (
    FLEXION_JOINTS,
    GRIP_JOINTS,
    SPREAD_JOINTS,
    WorldSteps,
    close_fingers,
    grip_joints,
)
from kinegrasp_env.physics.mujoco_world import CREEP_TORQUE, MujocoWorld
from kinegrasp_env.physics.protocol import START_COLLISION, HoldProtocol, HoldResult
from kinegrasp_env.physics.pybullet_closing import MotorSettings, merge_records
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.robot.default_robot import FINGERS, FINGERTIP_LINKS, hand_joint_values
from kinegrasp_env.world.objects import GraspObject


class ClosingMotors:
    """The closing controller (module docstring, step 1) on a :class:`MujocoWorld`."""

    def __init__(self, world: MujocoWorld, settings: MotorSettings,
                 spread: dict[str, float]) -> None:
        self.world, self.settings = world, settings
        self.held = [False] * 3
        self.pressing = [False] * 3
        world.position(list(spread), list(spread.values()))
        world.velocity(FLEXION_JOINTS, settings.closing_speed,
                       [settings.proximal_torque, settings.distal_torque] * 3)

    def update(self, touching: set[tuple[int, int]]) -> None:
        s, world = self.settings, self.world
        for finger in range(3):
            if not self.held[finger] and ((finger, 0) in touching or (finger, 1) in touching):
                self.held[finger] = True
                joint = FINGERS[finger][0]
                angle, _ = world.joint_states([joint])
                world.position([joint], angle)
            if ((finger, 1) in touching) != self.pressing[finger]:
                self.pressing[finger] = not self.pressing[finger]
                if self.pressing[finger]:
                    world.velocity([FINGERS[finger][1]], s.creep_speed,
                                   min(CREEP_TORQUE, s.distal_torque))
                else:
                    world.velocity([FINGERS[finger][1]], s.closing_speed, s.distal_torque)


def touching(world: MujocoWorld, distance: float) -> set[tuple[int, int]]:
    """(finger, link) of the finger links with a contact within ``distance`` (m)."""
    return {world.finger_geom[rec[0]] for rec in world.contact_records()
            if rec[0] in world.finger_geom and rec[3] <= distance}


def world_contacts(world: MujocoWorld, distance: float, weighted: bool = True
                   ) -> list[GripContact]:
    """One contact per touching finger link, world frame (pybullet's merge rule on records
    laid out as pybullet's: [6] point on the object, [7] normal object -> finger, [8]
    distance, [9] normal force; ``weighted=False``: the records averaged without their
    forces, as :func:`~kinegrasp_env.physics.robot_hold.world_contacts` averages a pad's)."""
    records: dict[tuple[int, int], list[tuple]] = {}
    for geom, point, normal, dist, force in world.contact_records():
        if geom in world.finger_geom and dist <= distance:
            rec = (None,) * 6 + (point, -normal, dist, force if weighted else 0.0)
            records.setdefault(world.finger_geom[geom], []).append(rec)
    return [GripContact(finger, link, *merge_records(records[(finger, link)]))
            for finger, link in sorted(records)]


def mujoco_close(world: MujocoWorld, root_pose: np.ndarray, preshape: np.ndarray,
                 settings: MotorSettings) -> CloseResult:
    """The closing on the pinned object (step 1): a :class:`CloseResult` (``iterations``:
    simulation steps)."""
    values = hand_joint_values(np.asarray(preshape, dtype=float))
    world.reset(root_pose, values, pin=True)
    if world.penetration() > START_TOL:
        return CloseResult(start_collision=True)
    motors = ClosingMotors(world, settings, {n: values[n] for n in SPREAD_JOINTS})
    steps, contacts, missed, positions = close_fingers(
        world, lambda: motors.update(touching(world, settings.touch_distance)),
        lambda: world_contacts(world, settings.touch_distance), settings)
    return CloseResult(False, contacts, missed, positions, steps)


class MujocoHold:
    """The holding test in MuJoCo, one draw at a time (the ``mujoco`` simulator).

    Args:
        obj: the catalog object.
        friction: Coulomb friction between finger and object (the quality's mu).
        protocol: :class:`~kinegrasp_env.physics.protocol.HoldProtocol`; its torque limits
            replace ``motors``'.
        world: density and time step (:class:`~kinegrasp_env.physics.pybullet_world.
            WorldSettings`).
        motors: the closing controller's settings.
    """

    name = "mujoco"

    def __init__(self, obj: GraspObject, friction: float, protocol: HoldProtocol,
                 world: WorldSettings | None = None, motors: MotorSettings | None = None) -> None:
        settings = replace(world or WorldSettings(), friction=friction)
        self.protocol = protocol
        self.motors = (motors or MotorSettings()).with_torques(protocol.torques)
        self.world = MujocoWorld(obj, settings)

    def run_draw(self, root_pose: np.ndarray, preshape: np.ndarray
                 ) -> tuple[CloseResult, HoldResult]:
        closing = mujoco_close(self.world, root_pose, preshape, self.motors)
        if closing.start_collision:
            return closing, HoldResult(START_COLLISION)
        return closing, self.hold_test()

    def hold_test(self) -> HoldResult:
        """The holding test (:func:`~kinegrasp_env.physics.hold_runner.hold_test`) of the
        hand just closed on the pinned object."""
        return hold_runner.hold_test(MujocoSteps(self.world, self.motors, self.protocol),
                                     self.protocol)

    def close(self) -> None:
        """Nothing to disconnect (MuJoCo's model and data are freed with this object)."""


class MujocoWorldSteps(WorldSteps):
    """The holding test's primitives (:class:`~kinegrasp_env.physics.hold_runner.HoldSteps`)
    that any hand in a :class:`MujocoWorld` shares: time steps, the fingers' forces, the
    object in the palm frame (the hand's ``palm``), a saved state MuJoCo's integration state
    (``mj_getState`` / ``mj_setState``), the hand's root moved by its mocap anchor. A hand's
    steps add its grip.

    Args:
        world: the world right after the closing.
        motors, protocol: the closing controller's settings and the holding test's.
    """

    def __init__(self, world: MujocoWorld, motors, protocol: HoldProtocol) -> None:
        super().__init__(world, motors, protocol)
        self.palm_link = world.hand.palm
        self.state = self.start = None

    def advance(self, steps: int = 1) -> None:
        self.world.step(steps)

    def finger_forces(self) -> np.ndarray:
        return self.world.finger_forces()

    def save(self) -> None:
        world = self.world
        self.state = world.save_state()
        self.start = world.link_pose(world.hand.root), world.link_pose(self.palm_link)[:3, 3]

    def start_phase(self, gravity: np.ndarray) -> None:
        self.world.restore_state(self.state)
        self.world.set_gravity(gravity)

    def hand_start(self) -> tuple[np.ndarray, np.ndarray]:
        return self.start

    def move_hand(self, position: np.ndarray, orientation: np.ndarray) -> None:
        self.world.root_at(position, orientation)

    def discard(self) -> None:
        self.state = self.start = None


class MujocoSteps(MujocoWorldSteps):
    """The SDH's holding test primitives in a :class:`MujocoWorld`: the grip's joint rule
    as MuJoCo servos (the loaded joints ``general`` springs, the others held)."""

    def grip(self) -> bool:
        """The grip's joint rule (pybullet's :func:`~kinegrasp_env.physics.pybullet_hold.
        grip_control`): False when no contact forces in equilibrium exist."""
        m, world = self.motors, self.world
        axes, origins = world.joint_frames(GRIP_JOINTS)
        tips = np.array([world.link_pose(tip)[:3, 3] for tip in FINGERTIP_LINKS])
        stall, _ = world.joint_states(GRIP_JOINTS)
        spring = spring_grip(world_contacts(world, m.touch_distance),
                             grip_joints(axes, origins, tips, m), world.object_pose(),
                             world.obj.center_of_mass, stall, world.settings.friction,
                             self.protocol.grip_advance)
        if spring is None:
            return False
        names = np.array(GRIP_JOINTS)
        loaded = spring.loaded
        world.uncouple()  # each spread joint set on its own, as in pybullet
        if (~loaded).any():
            world.position(list(names[~loaded]), spring.stall[~loaded])
        if loaded.any():
            world.spring(list(names[loaded]), spring.targets[loaded],
                         spring.stiffness[loaded], spring.limits[loaded])
        return True
