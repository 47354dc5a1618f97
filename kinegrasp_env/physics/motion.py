"""The hand's motion in the lift and shake phases of the holding test (pure numpy, the same
for every simulator; :mod:`~kinegrasp_env.physics.protocol` states the phases).

The hand's root is moved, not the arm's joints: the motion is then exactly the same for every
draw and every grasp whatever the arm's configuration (no IK, no joint-limit failure, no arm
link hitting the object). A simulator moves the constraint (or mocap body) that holds the
hand's root along :func:`hand_path`.

* lift: up (world +z) by ``lift_height`` in ``lift_time``, a minimum-jerk profile (zero
  velocity and acceleration at both ends), then still for ``hold_time``;
* shake: for ``shake_time`` at ``shake_frequency``, a translation of amplitude
  ``shake_amplitude`` along :data:`SHAKE_DIRECTION` and, in phase, a rotation of amplitude
  ``shake_angle`` about :data:`SHAKE_AXIS` through the palm centre, the amplitude ramped up
  and down smoothly over ``ramp_time`` at either end (defaults: peak accelerations 4.7 m/s^2
  of translation and 55 rad/s^2 of rotation).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.physics.protocol import HoldProtocol
from kinegrasp_env.robot.kinematics import axis_angle_matrix
from kinegrasp_env.world.sim import matrix_to_pose

#: Direction of the shake's translation (world frame, unit).
SHAKE_DIRECTION = np.array([0.0, 1.0, 1.0]) / np.sqrt(2.0)
#: Axis of the shake's rotation (world frame, unit), through the palm centre.
SHAKE_AXIS = np.array([1.0, 0.0, 0.0])


def smoothstep(x: np.ndarray | float) -> np.ndarray:
    """Minimum-jerk ramp 10 x^3 - 15 x^4 + 6 x^5 of x clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def lift_motion(protocol: HoldProtocol, times: np.ndarray) -> np.ndarray:
    """(s, 3) the palm centre's displacement (world frame, metres) at times (s,) (seconds
    since the lift began): up by ``lift_height`` over ``lift_time``, then still."""
    times = np.asarray(times, dtype=float)
    shifts = np.zeros((times.size, 3))
    shifts[:, 2] = protocol.lift_height * smoothstep(times / protocol.lift_time)
    return shifts


def peak_lift_acceleration(protocol: HoldProtocol, samples: int = 4001) -> float:
    """The largest upward acceleration of the lift (m/s^2): the second derivative of
    :func:`lift_motion`'s height, by finite differences over ``samples`` times."""
    times = np.linspace(0.0, protocol.lift_time, samples)
    height = lift_motion(protocol, times)[:, 2]
    step = times[1] - times[0]
    return float(np.max(np.gradient(np.gradient(height, step), step)))


def shake_motion(protocol: HoldProtocol, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The shake at times (s,) (seconds since it began): (translations (s, 3) of the palm
    centre, world frame, metres; rotation angles (s,) about :data:`SHAKE_AXIS` through the
    palm centre, radians). Zero outside [0, ``shake_time``]."""
    times = np.asarray(times, dtype=float)
    ramp = max(protocol.ramp_time, 1e-12)
    envelope = smoothstep(np.minimum(times, protocol.shake_time - times) / ramp)
    wave = np.where(times > 0.0,
                    envelope * np.sin(2.0 * np.pi * protocol.shake_frequency * times), 0.0)
    return protocol.shake_amplitude * wave[:, None] * SHAKE_DIRECTION, protocol.shake_angle * wave


def moved(root_pose: np.ndarray, centre: np.ndarray, translation: np.ndarray,
          angle: float) -> np.ndarray:
    """(4, 4) the hand root's pose ``root_pose`` rotated by ``angle`` about
    :data:`SHAKE_AXIS` through ``centre`` (3,), then translated by ``translation`` (3,)."""
    rotation = np.eye(4)
    rotation[:3, :3] = axis_angle_matrix(SHAKE_AXIS, np.array(angle))
    rotation[:3, 3] = centre + translation - rotation[:3, :3] @ centre
    return rotation @ root_pose


def quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products a b of quaternions (..., 4), (x, y, z, w) order."""
    va, wa, vb, wb = a[..., :3], a[..., 3:], b[..., :3], b[..., 3:]
    return np.concatenate([wa * vb + wb * va + np.cross(va, vb),
                           wa * wb - np.sum(va * vb, axis=-1, keepdims=True)], axis=-1)


def hand_path(shifts: np.ndarray, angles: np.ndarray, root_pose: np.ndarray,
              centre: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The commanded hand at every step, for a hand whose root is at ``root_pose`` (4, 4)
    and palm centre at ``centre`` (3,) when the motion begins, given the palm centre's
    displacements ``shifts`` (s, 3) and rotation angles ``angles`` (s,) about
    :data:`SHAKE_AXIS`: (root positions (s, 3), root orientations (s, 4) quaternions x, y, z,
    w, palm centres (s, 3)), world frame (:func:`moved` at every step, batched)."""
    angles = np.asarray(angles, dtype=float)
    rotations = axis_angle_matrix(SHAKE_AXIS, angles)
    positions = (rotations @ (root_pose[:3, 3] - centre)) + centre + shifts
    half = angles[:, None] / 2.0
    turns = np.concatenate([np.sin(half) * SHAKE_AXIS, np.cos(half)], axis=1)
    _, start = matrix_to_pose(root_pose)
    return positions, quaternion_product(turns, np.asarray(start)), centre + shifts
