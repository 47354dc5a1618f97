"""The lift test: after the physics closing, does the hand hold the object?

Run right after :func:`~kinegrasp_env.physics.pybullet_closing.physics_close` on the same world. The
hand grips (:func:`~kinegrasp_env.physics.pybullet_closing.grip`: every distal joint's motor presses
with its full torque, the proximal joints stay held) for ``grip_time`` (0.25 s, gravity still
off); then gravity is switched on and the object's support damping off, and the constraint
that holds the hand's root moves it along :class:`LiftProfile`:

1. lift: up (world +z) by ``height`` (0.10 m) in ``lift_time`` (1 s), a minimum-jerk profile
   (zero velocity and acceleration at both ends);
2. hold: still for ``hold_time`` (1 s);
3. shake: for ``shake_time`` (1.5 s) at ``shake_frequency`` (2 Hz), a translation of amplitude
   ``shake_amplitude`` (0.03 m) along the world direction (0, 1, 1)/sqrt(2) (sideways and
   vertical) and, in phase, a rotation of amplitude ``shake_angle`` (20 degrees) about the
   world x axis through the palm centre; the amplitude ramps up and down smoothly over
   ``ramp_time`` (0.25 s) at either end. Peak accelerations: 4.7 m/s^2 of translation and
   55 rad/s^2 of rotation.

Why the hand's root is moved by its constraint, not the arm by its joints: the motion is then
exactly the same for every draw and every grasp, whatever the arm's configuration (no IK, no
failure near a joint limit, no arm link hitting the object), and the stand-in for the arm
(:data:`~kinegrasp_env.physics.pybullet_world.ROOT_MASS` behind a stiff constraint) follows it
within 1.5 mm of the commanded place (measured at the shake's peak speed, 1 ms steps:
:attr:`LiftResult.tracking`).

The draw *holds* when the object's centre of mass stays within ``hold_distance`` (0.05 m) of
where it was in the palm's frame when the lift began, checked every :data:`HOLD_CHECK`
(10 ms) and at the end; the test stops at the first check where it does not (the object is
dropped).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.physics.pybullet_closing import MotorSettings, grip
from kinegrasp_env.physics.pybullet_world import PhysicsWorld
from kinegrasp_env.robot.kinematics import axis_angle_matrix
from kinegrasp_env.world.sim import matrix_to_pose

#: Direction of the shake's translation (world frame, unit).
SHAKE_DIRECTION = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
#: Axis of the shake's rotation (world frame, unit), through the palm centre.
SHAKE_AXIS = np.array([1.0, 0.0, 0.0])
#: How often the holding criterion is checked, seconds.
HOLD_CHECK = 0.01


def smoothstep(x: np.ndarray | float) -> np.ndarray:
    """Minimum-jerk ramp 10 x^3 - 15 x^4 + 6 x^5 of x clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


@dataclass(frozen=True)
class LiftProfile:
    """The hand's motion and the holding criterion (see the module docstring; metres,
    seconds, hertz, radians)."""

    height: float = 0.10
    lift_time: float = 1.0
    hold_time: float = 1.0
    shake_time: float = 1.5
    shake_frequency: float = 2.0
    shake_amplitude: float = 0.03
    shake_angle: float = np.radians(20.0)
    ramp_time: float = 0.25
    hold_distance: float = 0.05
    grip_time: float = 0.25

    def __post_init__(self) -> None:
        for name in ("height", "lift_time", "hold_time", "shake_time", "shake_frequency",
                     "shake_amplitude", "shake_angle", "ramp_time", "hold_distance",
                     "grip_time"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a number >= 0, got {value!r}")
        if self.hold_distance <= 0 or self.lift_time <= 0:
            raise ValueError("hold_distance and lift_time must be positive")

    @property
    def duration(self) -> float:
        return self.lift_time + self.hold_time + self.shake_time

    def motions(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The hand's displacement at times (s,) (seconds since the lift began):
        (translations (s, 3) of the palm centre, world frame, metres; rotation angles (s,)
        about :data:`SHAKE_AXIS` through the palm centre, radians)."""
        times = np.asarray(times, dtype=float)
        lift = self.height * smoothstep(times / self.lift_time)
        t_shake = times - self.lift_time - self.hold_time
        ramp = max(self.ramp_time, 1e-12)
        envelope = smoothstep(np.minimum(t_shake, self.shake_time - t_shake) / ramp)
        wave = np.where(t_shake > 0.0,
                        envelope * np.sin(2.0 * np.pi * self.shake_frequency * t_shake), 0.0)
        shifts = self.shake_amplitude * wave[:, None] * SHAKE_DIRECTION
        shifts[:, 2] += lift
        return shifts, self.shake_angle * wave

    def motion(self, t: float) -> tuple[np.ndarray, float]:
        """:meth:`motions` at one time t (s): (translation (3,), angle)."""
        shifts, angles = self.motions(np.array([t]))
        return shifts[0], float(angles[0])


def moved(root_pose: np.ndarray, centre: np.ndarray, translation: np.ndarray,
          angle: float) -> np.ndarray:
    """(4, 4) the hand root's pose ``root_pose`` rotated by ``angle`` about
    :data:`SHAKE_AXIS` through ``centre`` (3,), then translated by ``translation`` (3,)."""
    rotation = np.eye(4)
    rotation[:3, :3] = axis_angle_matrix(SHAKE_AXIS, np.array(angle))
    rotation[:3, 3] = centre + translation - rotation[:3, :3] @ centre
    return rotation @ root_pose


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products a b of quaternions (..., 4), pybullet's (x, y, z, w) order."""
    va, wa, vb, wb = a[..., :3], a[..., 3:], b[..., :3], b[..., 3:]
    return np.concatenate([wa * vb + wb * va + np.cross(va, vb),
                           wa * wb - np.sum(va * vb, axis=-1, keepdims=True)], axis=-1)


@dataclass(frozen=True)
class LiftResult:
    """Outcome of one lift test.

    Attributes:
        held: the object stayed within ``hold_distance`` of its place in the palm frame.
        max_offset: the largest distance it moved from there, metres (up to the drop).
        time: when the test ended, seconds since the lift began (the drop, or the end).
        tracking: the largest distance of the palm centre from its commanded place, metres.
    """

    held: bool
    max_offset: float
    time: float
    tracking: float


def object_in_palm(world: PhysicsWorld, palm: np.ndarray) -> np.ndarray:
    """(3,) the object's centre of mass in the frame ``palm`` (4, 4)."""
    com_world = world.object_pose() @ np.append(world.obj.center_of_mass, 1.0)
    return (np.linalg.inv(palm) @ com_world)[:3]


def hand_path(profile: LiftProfile, root_pose: np.ndarray, centre: np.ndarray,
              time_step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The commanded hand at every step of the test, for a hand whose root is at
    ``root_pose`` (4, 4) and palm centre at ``centre`` (3,) when the lift begins: (root
    positions (s, 3), root orientations (s, 4) quaternions x, y, z, w, palm centres (s, 3)),
    world frame (:func:`moved` at every step, batched)."""
    times = time_step * np.arange(1, round(profile.duration / time_step) + 1)
    shifts, angles = profile.motions(times)
    rotations = axis_angle_matrix(SHAKE_AXIS, angles)
    positions = (rotations @ (root_pose[:3, 3] - centre)) + centre + shifts
    half = angles[:, None] / 2.0
    turns = np.concatenate([np.sin(half) * SHAKE_AXIS, np.cos(half)], axis=1)
    _, start = matrix_to_pose(root_pose)
    return positions, quaternion_product(turns, np.asarray(start)), centre + shifts


def lift_test(world: PhysicsWorld, profile: LiftProfile | None = None,
              motors: MotorSettings | None = None) -> LiftResult:
    """Grip, then lift and shake the closed hand (see the module docstring).

    Args:
        world: a physics world right after the closing, object free.
        profile: :class:`LiftProfile` (defaults when None).
        motors: the finger motors' settings (defaults when None).

    Raises:
        ValueError: the world's object is fixed (there is nothing to lift).
    """
    if not world.settings.object_free:
        raise ValueError("the lift test needs a free object (object_free=True)")
    profile = profile or LiftProfile()
    dt = world.settings.time_step
    grip(world, motors or MotorSettings())
    world.step(round(profile.grip_time / dt))
    world.gravity(True)
    world.damp_object(False)
    palm = world.link_pose("palm")
    positions, orientations, centres = hand_path(profile, world.link_pose("hand_root"),
                                                 palm[:3, 3], dt)
    start = object_in_palm(world, palm)
    every = max(1, round(HOLD_CHECK / dt))
    worst = tracking = 0.0
    for step in range(1, len(positions) + 1):
        world.anchor_at(positions[step - 1].tolist(), orientations[step - 1].tolist())
        world.step()
        if step % every and step < len(positions):
            continue
        palm = world.link_pose("palm")
        tracking = max(tracking, float(np.linalg.norm(palm[:3, 3] - centres[step - 1])))
        worst = max(worst, float(np.linalg.norm(object_in_palm(world, palm) - start)))
        if worst > profile.hold_distance:
            return LiftResult(False, worst, step * dt, tracking)
    return LiftResult(True, worst, len(positions) * dt, tracking)
