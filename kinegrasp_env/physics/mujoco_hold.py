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
   contacts give balanced joint torques, each loaded flexion joint a spring (a ``general``
   actuator: gain k, bias -k q, its torque limit as force range), the others held, until the
   fingers' normal forces are steady;
3. release (pin off, table away), ``settle_time``; ``grip_shift`` and the grip verdict;
4. the phases from the saved state (``mj_getState`` / ``mj_setState``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from kinegrasp_env.closing.reference import START_TOL, CloseResult, Contact, hand_joint_values
from kinegrasp_env.physics.grip_forces import (
    GripContact,
    SpringGrip,
    balanced_torques,
    loaded_joints,
    tip_offsets,
)
from kinegrasp_env.physics.motion import hand_path, lift_motion, shake_motion
from kinegrasp_env.physics.mujoco_world import CREEP_TORQUE, MujocoWorld
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
    SPREAD_JOINTS,
    MotorSettings,
    merge_records,
)
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.robot.model import FINGERS, FINGERTIP_LINKS, HAND_JOINTS
from kinegrasp_env.world.objects import GraspObject


def steps_of(seconds: float, time_step: float) -> int:
    return max(1, round(seconds / time_step))


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


def close_until_stall(world: MujocoWorld, motors: ClosingMotors, settings: MotorSettings) -> int:
    """Step until the flexion joints stall (the rule of pybullet's closing) or ``max_time``."""
    dt = world.settings.time_step
    max_steps = int(np.ceil(settings.max_time / dt))
    window = max(1, round(settings.stall_window / dt))
    still = settings.stall_speed * window * dt
    last, _ = world.joint_states(FLEXION_JOINTS)
    quiet = 0
    for step in range(1, max_steps + 1):
        world.step()
        motors.update(touching(world, settings.touch_distance))
        if step % window == 0:
            positions, _ = world.joint_states(FLEXION_JOINTS)
            quiet = quiet + 1 if np.abs(positions - last).max() < still else 0
            last = positions
            if quiet >= settings.stall_checks:
                return step
    return max_steps


def world_contacts(world: MujocoWorld, distance: float) -> list[GripContact]:
    """One contact per touching finger link, world frame (pybullet's merge rule on records
    laid out as pybullet's: [6] point on the object, [7] normal object -> finger, [8]
    distance, [9] normal force)."""
    records: dict[tuple[int, int], list[tuple]] = {}
    for geom, point, normal, dist, force in world.contact_records():
        if geom in world.finger_geom and dist <= distance:
            rec = (None,) * 6 + (point, -normal, dist, force)
            records.setdefault(world.finger_geom[geom], []).append(rec)
    return [GripContact(finger, link, *merge_records(records[(finger, link)]))
            for finger, link in sorted(records)]


def merged_contacts(world: MujocoWorld, distance: float) -> list[Contact]:
    """:func:`world_contacts` in the object's frame."""
    inverse = np.linalg.inv(world.object_pose())
    return [Contact(c.finger, c.link, inverse[:3, :3] @ c.point + inverse[:3, 3],
                    inverse[:3, :3] @ c.normal) for c in world_contacts(world, distance)]


def mujoco_close(world: MujocoWorld, root_pose: np.ndarray, preshape: np.ndarray,
                 settings: MotorSettings) -> CloseResult:
    """The closing on the pinned object (step 1): a :class:`CloseResult` (``iterations``:
    simulation steps)."""
    values = hand_joint_values(np.asarray(preshape, dtype=float))
    world.reset(root_pose, values, pin=True)
    if world.penetration() > START_TOL:
        return CloseResult(start_collision=True)
    motors = ClosingMotors(world, settings, {n: values[n] for n in SPREAD_JOINTS})
    steps = close_until_stall(world, motors, settings)
    contacts = merged_contacts(world, settings.touch_distance)
    touched = {c.finger for c in contacts}
    positions, _ = world.joint_states(list(HAND_JOINTS))
    return CloseResult(False, contacts, tuple(f not in touched for f in range(3)), positions,
                       steps)


def object_in_palm(world: MujocoWorld) -> np.ndarray:
    return np.linalg.inv(world.link_pose("palm")) @ world.object_pose()


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

    def grip(self) -> bool:
        """The grip's joint rule (step 2, pybullet's :func:`~kinegrasp_env.physics.
        pybullet_hold.grip_control`): False when no contact forces in equilibrium exist."""
        m, world = self.motors, self.world
        contacts = world_contacts(world, m.touch_distance)
        axes, origins = world.joint_frames(FLEXION_JOINTS)
        tips = np.array([world.link_pose(tip)[:3, 3] for tip in FINGERTIP_LINKS])
        pose = world.object_pose()
        center = pose[:3, :3] @ world.obj.center_of_mass + pose[:3, 3]
        limits = np.array([m.proximal_torque, m.distal_torque] * 3)
        solution = balanced_torques(contacts, axes, origins, center, limits,
                                    world.settings.friction)
        if solution is None:
            return False
        stall, _ = world.joint_states(FLEXION_JOINTS)
        offsets = tip_offsets(axes, origins, tips, self.protocol.grip_advance)
        spring = SpringGrip.of(stall, solution, offsets, limits, loaded_joints(contacts))
        names = np.array(FLEXION_JOINTS)
        loaded = spring.loaded
        if (~loaded).any():
            world.position(list(names[~loaded]), spring.stall[~loaded])
        if loaded.any():
            world.spring(list(names[loaded]), spring.targets[loaded],
                         spring.stiffness[loaded], spring.limits[loaded])
        return True

    def grip_until_steady(self) -> tuple[np.ndarray, float]:
        p, world = self.protocol, self.world
        dt = world.settings.time_step
        window = steps_of(p.steady_window, dt)
        previous, calm, steps = None, 0, 0
        while steps * dt < p.grip_max_time - 1e-12:
            world.step(window)
            steps += window
            forces = world.finger_forces()
            calm = calm + 1 if previous is not None and steady(previous, forces, p) else 0
            previous = forces
            if calm >= 2 and steps * dt >= p.grip_min_time - 1e-12:
                break
        return previous, steps * dt

    def watch(self, reference: np.ndarray, steps: int, path=None) -> tuple[bool, float, float]:
        """Step ``steps`` times (the mocap root along ``path`` if given), checking the object
        every ``check_interval``: (held, largest distance m, largest angle rad)."""
        p, world = self.protocol, self.world
        every = steps_of(p.check_interval, world.settings.time_step)
        com = world.obj.center_of_mass
        worst_d = worst_a = 0.0
        for k in range(steps):
            if path is not None:
                world.root_at(path[0][k], path[1][k])
            world.step()
            if (k + 1) % every and k + 1 < steps:
                continue
            distance, angle = pose_change(reference, object_in_palm(world), com)
            worst_d, worst_a = max(worst_d, distance), max(worst_a, angle)
            if not within(p, distance, angle):
                return False, worst_d, worst_a
        return True, worst_d, worst_a

    def hold_test(self) -> HoldResult:
        p, world = self.protocol, self.world
        dt = world.settings.time_step
        if not self.grip():
            return HoldResult(NO_GRIP)
        gripped, grip_time = self.grip_until_steady()
        pin_force, pin_torque = world.pin_load()
        pinned = object_in_palm(world)
        world.release_object()
        world.remove_table()
        world.step(steps_of(p.settle_time, dt))
        released = world.finger_forces()
        reference = object_in_palm(world)
        shift, turn = pose_change(pinned, reference, world.obj.center_of_mass)
        result = HoldResult(grip_verdict(gripped, released, p), shift, turn, gripped, released,
                            grip_time, pin_force, pin_torque)
        if result.outcome != HELD:
            return result
        state = world.save_state()
        root, palm = world.link_pose("hand_root"), world.link_pose("palm")[:3, 3]
        for name in p.phases:
            if name == "shake":  # right after a held lift, from where it left the hand
                if not result.phase_held.get("lift", False):
                    continue
            else:
                world.restore_state(state)
            outcome = self.run_phase(name, reference, root, palm)
            result.phase_held[name], result.phase_shift[name], result.phase_turn[name] = outcome
        result.outcome = final_outcome(HELD, result.phase_held)
        return result

    def run_phase(self, name: str, reference: np.ndarray, root: np.ndarray,
                  palm: np.ndarray) -> tuple[bool, float, float]:
        """One phase of the protocol from the saved post-release state (module docstring),
        the hand root at ``root`` (4, 4) and palm centre at ``palm`` (3,) at its start."""
        p, world = self.protocol, self.world
        dt = world.settings.time_step
        if name == REST_PHASE or name in GRAVITY_PHASES:
            direction = np.zeros(3) if name == REST_PHASE else np.asarray(GRAVITY_PHASES[name])
            world.set_gravity(p.gravity * direction)
            return self.watch(reference, steps_of(p.gravity_time, dt))
        world.set_gravity([0.0, 0.0, -p.gravity])
        if name == "lift":
            times = dt * np.arange(1, steps_of(p.lift_time + p.hold_time, dt) + 1)
            path = hand_path(lift_motion(p, times), np.zeros(times.size), root, palm)
            return self.watch(reference, times.size, path)
        if name == "shake":
            lifted = np.eye(4)
            lifted[:3, 3] = [0.0, 0.0, p.lift_height]
            times = dt * np.arange(1, steps_of(p.shake_time, dt) + 1)
            shifts, angles = shake_motion(p, times)
            path = hand_path(shifts, angles, lifted @ root, palm + lifted[:3, 3])
            return self.watch(reference, times.size, path)
        raise ValueError(f"the MuJoCo holding test has no phase {name!r}")

    def close(self) -> None:
        """Nothing to disconnect (MuJoCo's model and data are freed with this object)."""
