"""The closing and holding test's sequence, simulator-independent.

:mod:`~kinegrasp_env.physics.protocol` states the protocol; this module runs it once, over
the primitives a simulator supplies (:class:`HoldSteps`: step the grip, read the fingers'
forces and the object's pose in the palm frame, release the pin, save and restore a state,
move the hand). Each simulator implements those primitives
(:mod:`~kinegrasp_env.physics.pybullet_hold`, :mod:`~kinegrasp_env.physics.mujoco_hold`),
and its holding test (:mod:`~kinegrasp_env.physics.robot_hold`,
:mod:`~kinegrasp_env.physics.mujoco_robot_hold`) calls :func:`hold_test`; its closing calls
:func:`close_until_stall`, and both state their contacts in the object's frame with
:func:`in_object_frame`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np

from kinegrasp_env.physics.grip_forces import GripContact
from kinegrasp_env.physics.hand_result import Contact
from kinegrasp_env.physics.motion import hand_path, lift_motion, shake_motion
from kinegrasp_env.physics.protocol import (
    GRAVITY_PHASES,
    HELD,
    NO_GRIP,
    REST_PHASE,
    HoldProtocol,
    HoldResult,
    final_outcome,
    grip_verdict,
    pose_change,
    steady,
    within,
)


def steps_of(seconds: float, time_step: float) -> int:
    """The number of time steps (at least one) closest to ``seconds``."""
    return max(1, round(seconds / time_step))


class StallRule(Protocol):
    """The closing's stall rule (:class:`~kinegrasp_env.physics.robot_hold.
    RobotMotorSettings`): seconds, travel per second, a count."""

    max_time: float
    stall_window: float
    stall_speed: float
    stall_checks: int


def close_until_stall(step: Callable[[], None], flexion: Callable[[], np.ndarray],
                      rule: StallRule, time_step: float) -> int:
    """Call ``step()`` (one time step and the controller's update) until the closing joints'
    travel ``flexion()`` (J,) moves less than ``stall_speed`` per second over
    ``stall_window``, ``stall_checks`` windows in a row, or ``max_time``: the number of
    steps.

    Speeds are measured from position changes over a window: a simulator's reported joint
    velocity of a finger pressing on the object need not go to zero.
    """
    max_steps = int(np.ceil(rule.max_time / time_step))
    window = max(1, round(rule.stall_window / time_step))
    still = rule.stall_speed * window * time_step  # travel per window
    last = flexion()
    quiet = 0
    for count in range(1, max_steps + 1):
        step()
        if count % window == 0:
            positions = flexion()
            quiet = quiet + 1 if np.abs(positions - last).max() < still else 0
            last = positions
            if quiet >= rule.stall_checks:
                return count
    return max_steps


def in_object_frame(contacts: list[GripContact], object_pose: np.ndarray) -> list[Contact]:
    """World-frame contacts as :class:`~kinegrasp_env.physics.hand_result.Contact` in the frame
    of an object at ``object_pose`` (4, 4)."""
    inverse = np.linalg.inv(object_pose)
    return [Contact(c.finger, c.link, inverse[:3, :3] @ c.point + inverse[:3, 3],
                    inverse[:3, :3] @ c.normal) for c in contacts]


def object_in_palm(world, palm: str) -> np.ndarray:
    """(4, 4) the object's pose in the frame of the hand's link ``palm`` now (a simulator's
    world: ``link_pose``, ``object_pose``)."""
    return np.linalg.inv(world.link_pose(palm)) @ world.object_pose()


class HoldSteps(Protocol):
    """What a simulator supplies to :func:`hold_test`, on a hand just closed on the pinned
    object.

    Attributes:
        time_step: seconds per step.
        center_of_mass: (3,) the object's centre of mass, object frame, metres.
    """

    time_step: float
    center_of_mass: np.ndarray

    def grip(self) -> bool:
        """Switch the grip's joint rule on (False: no contact forces in equilibrium)."""

    def advance(self, steps: int = 1) -> None:
        """``steps`` time steps under the grip's joint rule."""

    def finger_forces(self) -> np.ndarray:
        """(fingers,) each finger's total normal force on the object, newtons."""

    def object_in_palm(self) -> np.ndarray:
        """(4, 4) the object's pose in the palm frame."""

    def pin_load(self) -> tuple[float, float]:
        """The net force (N) and torque (N m) the pin holds."""

    def release(self) -> None:
        """The pin off and the support table (if any) out of reach."""

    def save(self) -> None:
        """Keep the state now; every phase but the shake starts from it."""

    def start_phase(self, gravity: np.ndarray) -> None:
        """Back to the saved state, the grip's rule on, gravity (3,) m/s^2."""

    def hand_start(self) -> tuple[np.ndarray, np.ndarray]:
        """The saved state's hand root pose (4, 4) and palm centre (3,), world frame."""

    def move_hand(self, position: np.ndarray, orientation: np.ndarray) -> None:
        """The hand's root at ``position`` (3,) and quaternion ``orientation`` (4,)
        (x, y, z, w)."""

    def discard(self) -> None:
        """Forget the saved state."""


class WorldSteps:
    """The primitives of :class:`HoldSteps` that read a simulator's world alone (its
    ``link_pose``, ``object_pose``, ``pin_load``, ``release_object``, ``remove_table``,
    ``settings.time_step``, ``obj``): the base of each simulator's steps.

    Args:
        world: the world right after the closing.
        protocol: the holding test's settings.
        palm_link: the hand's link whose frame the object's pose is measured in.
    """

    def __init__(self, world, protocol: HoldProtocol, palm_link: str) -> None:
        self.world, self.protocol, self.palm_link = world, protocol, palm_link
        self.time_step = world.settings.time_step
        self.center_of_mass = world.obj.center_of_mass

    def object_in_palm(self) -> np.ndarray:
        return object_in_palm(self.world, self.palm_link)

    def pin_load(self) -> tuple[float, float]:
        return self.world.pin_load()

    def release(self) -> None:
        self.world.release_object()
        self.world.remove_table()


def grip_until_steady(sim: HoldSteps, protocol: HoldProtocol) -> tuple[np.ndarray, float]:
    """Press until the fingers' forces are steady twice in a row (after at least
    ``grip_min_time``) or ``grip_max_time``: (the forces (3,), newtons; seconds run)."""
    dt = sim.time_step
    window = steps_of(protocol.steady_window, dt)
    previous, calm, steps = None, 0, 0
    while steps * dt < protocol.grip_max_time - 1e-12:
        sim.advance(window)
        steps += window
        forces = sim.finger_forces()
        calm = calm + 1 if previous is not None and steady(previous, forces, protocol) else 0
        previous = forces
        if calm >= 2 and steps * dt >= protocol.grip_min_time - 1e-12:
            break
    return previous, steps * dt


def watch(sim: HoldSteps, protocol: HoldProtocol, reference: np.ndarray, steps: int,
          path: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[bool, float, float]:
    """Step ``steps`` times (the hand's root along ``path``, positions (steps, 3) and
    orientations (steps, 4), if given), checking the object against ``reference`` (its pose in
    the palm frame) every ``check_interval`` and at the end; stop at the first failed check:
    (held, largest distance m, largest angle rad; NaN where the object's pose is not a
    number: the simulation blew up). With ``protocol.early_exit`` a phase
    without a path also ends early by :func:`projected_verdict`."""
    every = steps_of(protocol.check_interval, sim.time_step)
    worst_distance = worst_angle = 0.0
    previous, streak = None, 0
    for k in range(steps):
        if path is not None:
            sim.move_hand(path[0][k], path[1][k])
        sim.advance()
        if (k + 1) % every and k + 1 < steps:
            continue
        distance, angle = pose_change(reference, sim.object_in_palm(), sim.center_of_mass)
        if math.isnan(distance) or math.isnan(angle):  # the simulation blew up: no movement
            return False, math.nan, math.nan
        worst_distance, worst_angle = max(worst_distance, distance), max(worst_angle, angle)
        if not within(protocol, distance, angle):
            return False, worst_distance, worst_angle
        if protocol.early_exit and path is None and previous is not None:
            verdict = projected_verdict(protocol, (distance, angle), previous,
                                        every * sim.time_step, (k + 1) * sim.time_step,
                                        (steps - k - 1) * sim.time_step)
            streak = streak + 1 if verdict is not None else 0
            if verdict is not None and streak >= EXIT_CHECKS:
                return verdict, worst_distance, worst_angle
        previous = (distance, angle)
    return True, worst_distance, worst_angle


#: Consecutive checks that must agree before a phase ends early (:func:`projected_verdict`).
EXIT_CHECKS = 2
#: A phase ends early only after this long, seconds (the object's first sag under a new
#: load is over by then).
EXIT_MIN_TIME = 0.02
#: A phase ends early as held where the object stays within the holding criterion moving
#: on at this many times its present rate to the phase's end.
EXIT_RATE_FACTOR = 2.0


def projected_verdict(protocol: HoldProtocol, now: tuple[float, float],
                      before: tuple[float, float], interval: float, elapsed: float,
                      remaining: float) -> bool | None:
    """A phase's verdict before its end, from two checks ``interval`` seconds apart
    ((distance m, angle rad) from the reference, ``before`` then ``now``), ``elapsed``
    seconds into it with ``remaining`` to go: True where the object, moving on at
    :data:`EXIT_RATE_FACTOR` times its present rate (away from the reference) to the phase's
    end, stays within the holding criterion, after :data:`EXIT_MIN_TIME`; None (go on)
    otherwise. A phase fails only by the criterion itself (an object moving away may yet
    stop: a jaw pushing it reaches its joint limit)."""
    if elapsed < EXIT_MIN_TIME:
        return None
    speed = max(now[0] - before[0], 0.0) / interval
    turn = max(now[1] - before[1], 0.0) / interval
    far = now[0] + EXIT_RATE_FACTOR * speed * remaining
    wide = now[1] + EXIT_RATE_FACTOR * turn * remaining
    return True if within(protocol, far, wide) else None


def run_phases(sim: HoldSteps, protocol: HoldProtocol, reference: np.ndarray,
               result: HoldResult) -> None:
    """Every phase of ``protocol`` from the saved state, recorded in ``result``: the rest and
    the gravity phases and the lift each from the saved state, the shake right after a held
    lift, from where it left the hand."""
    dt = sim.time_step
    root = palm = None
    for name in protocol.phases:
        path = None
        if name == "shake":
            if not result.phase_held.get("lift", False):
                continue
            lifted = np.eye(4)
            lifted[:3, 3] = [0.0, 0.0, protocol.lift_height]
            times = dt * np.arange(1, steps_of(protocol.shake_time, dt) + 1)
            shifts, angles = shake_motion(protocol, times)
            path = hand_path(shifts, angles, lifted @ root, palm + lifted[:3, 3])
            steps = times.size
        elif name == "lift":
            sim.start_phase(np.array([0.0, 0.0, -protocol.gravity]))
            root, palm = sim.hand_start()
            times = dt * np.arange(1, steps_of(protocol.lift_time + protocol.hold_time, dt) + 1)
            path = hand_path(lift_motion(protocol, times), np.zeros(times.size), root, palm)
            steps = times.size
        else:
            direction = np.zeros(3) if name == REST_PHASE else np.asarray(GRAVITY_PHASES[name])
            sim.start_phase(protocol.gravity * direction)
            steps = steps_of(protocol.gravity_time, dt)
        outcome = watch(sim, protocol, reference, steps, path)
        result.phase_held[name], result.phase_shift[name], result.phase_turn[name] = outcome
        if protocol.early_exit and not outcome[0]:
            return


def hold_test(sim: HoldSteps, protocol: HoldProtocol) -> HoldResult:
    """The holding test (grip, release, phases: :mod:`~kinegrasp_env.physics.protocol`) of a
    hand just closed on the pinned object."""
    if not sim.grip():
        return HoldResult(NO_GRIP)
    gripped, grip_time = grip_until_steady(sim, protocol)
    pin_force, pin_torque = sim.pin_load()
    pinned = sim.object_in_palm()
    sim.release()
    sim.advance(steps_of(protocol.settle_time, sim.time_step))
    released = sim.finger_forces()
    reference = sim.object_in_palm()
    shift, turn = pose_change(pinned, reference, sim.center_of_mass)
    result = HoldResult(grip_verdict(gripped, released, protocol), shift, turn, gripped,
                        released, grip_time, pin_force, pin_torque)
    if result.outcome != HELD:
        return result
    sim.save()
    try:
        run_phases(sim, protocol, reference, result)
    finally:
        sim.discard()
    result.outcome = final_outcome(HELD, result.phase_held)
    return result
