"""The pose error, the elbow angle and a joint's column of the geometric Jacobian, each
defined once as a compiled function of one row.

:mod:`kinegrasp_env.robot.kinematics` applies them to batches (``pose_error``,
``rotation_log``, ``elbow_angle``, ``Kinematics.jacobian_at``) and the compiled self-motion
Newton (:mod:`kinegrasp_env.robot.self_motion`) calls them inside its loop. Units: metres and
radians; frames: the world (robot base) frame.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit

#: Rotation angles (radians) beyond pi minus this take the rotation log's axis from the
#: symmetric part of the matrix (the antisymmetric part vanishes at pi).
NEAR_PI = 1e-4
#: Below this |sin(angle)| the rotation log's scale angle / (2 sin) takes its series.
SMALL_SIN = 1e-6
#: Below this length of the world z axis' part across the shoulder-wrist line, the elbow
#: angle is measured from the x axis instead.
DEGENERATE_REF = 1e-9


@jit.kernel
def rotation_log_into(m, out) -> None:
    """Rotation vector (axis * angle, radians) of a rotation m (3, 3) into out (3,)."""
    cos_angle = min(max((m[0, 0] + m[1, 1] + m[2, 2] - 1.0) / 2.0, -1.0), 1.0)
    angle = np.arccos(cos_angle)
    vx, vy, vz = m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]
    sin_angle = np.sin(angle)
    if sin_angle < SMALL_SIN:
        scale = 0.5 + angle * angle / 12.0
    else:
        scale = angle / (2.0 * sin_angle)
    out[0], out[1], out[2] = vx * scale, vy * scale, vz * scale
    if angle > np.pi - NEAR_PI:  # symmetric part = cos I + (1 - cos) a a^T: its largest row
        k = 0
        best = -np.inf
        for i in range(3):
            d = (m[i, i] - cos_angle) / (1.0 - cos_angle)
            if d > best:
                best, k = d, i
        row = np.empty(3)
        for c in range(3):
            row[c] = (0.5 * (m[k, c] + m[c, k]) - (cos_angle if c == k else 0.0)) / (
                1.0 - cos_angle)
        norm = np.sqrt(row[0] ** 2 + row[1] ** 2 + row[2] ** 2)
        sign = np.sign((row[0] * vx + row[1] * vy + row[2] * vz) / norm)
        if sign == 0.0:
            sign = 1.0
        for c in range(3):
            out[c] = row[c] / norm * angle * sign


@jit.kernel
def pose_error_into(current, target, out) -> None:
    """Twist-like error of pose current (4, 4) against target (4, 4) into out (6,): target
    position - current position, then the rotation vector of R_target R_current^T."""
    m = np.empty((3, 3))
    for r in range(3):
        out[r] = target[r, 3] - current[r, 3]
        for c in range(3):
            m[r, c] = (target[r, 0] * current[c, 0] + target[r, 1] * current[c, 1]
                       + target[r, 2] * current[c, 2])
    rotation_log_into(m, out[3:])


@jit.kernel
def rotation_logs(rot, out) -> None:
    """:func:`rotation_log_into` of rotations rot (n, 3, 3) into out (n, 3)."""
    for i in range(rot.shape[0]):
        rotation_log_into(rot[i], out[i])


@jit.kernel
def pose_errors(current, target, out) -> None:
    """:func:`pose_error_into` of poses current, target (n, 4, 4) into out (n, 6)."""
    for i in range(current.shape[0]):
        pose_error_into(current[i], target[i], out[i])


@jit.kernel
def elbow_angle_of(s0, s1, s2, e0, e1, e2, w0, w1, w2) -> float:
    """Elbow (arm) angle psi (radians) from the shoulder (s), elbow (e) and wrist (w)
    centres: the angle of the elbow about the shoulder-wrist line, from the plane through
    that line and the world z axis (the x axis where z lies along the line), positive by the
    right-hand rule about shoulder -> wrist; 0 where the elbow lies on the line."""
    ax, ay, az = w0 - s0, w1 - s1, w2 - s2
    norm = np.sqrt(ax * ax + ay * ay + az * az)
    ax, ay, az = ax / norm, ay / norm, az / norm
    rx, ry, rz = -az * ax, -az * ay, 1.0 - az * az  # z minus its part along the axis
    if np.sqrt(rx * rx + ry * ry + rz * rz) <= DEGENERATE_REF:
        rx, ry, rz = 1.0 - ax * ax, -ax * ay, -ax * az  # x minus its part along the axis
    norm = np.sqrt(rx * rx + ry * ry + rz * rz)
    rx, ry, rz = rx / norm, ry / norm, rz / norm
    sx, sy, sz = ay * rz - az * ry, az * rx - ax * rz, ax * ry - ay * rx
    ex, ey, ez = e0 - s0, e1 - s1, e2 - s2
    return np.arctan2(ex * sx + ey * sy + ez * sz, ex * rx + ey * ry + ez * rz)


@jit.kernel
def elbow_angles(shoulder, elbow, wrist, out) -> None:
    """:func:`elbow_angle_of` of centres (n, 3) each into out (n,)."""
    for i in range(out.shape[0]):
        out[i] = elbow_angle_of(shoulder[i, 0], shoulder[i, 1], shoulder[i, 2],
                                elbow[i, 0], elbow[i, 1], elbow[i, 2],
                                wrist[i, 0], wrist[i, 1], wrist[i, 2])


@jit.kernel
def add_joint_column(jac, k, mult, revolute, wx, wy, wz, dx, dy, dz) -> None:
    """Add one joint's part to column k of a geometric Jacobian jac (6, dof): world axis
    (wx, wy, wz), d = tracked point - joint origin (metres), driver multiplier mult. A
    revolute joint adds mult (w x d) to the linear rows and mult w to the angular ones, a
    prismatic joint mult w to the linear rows."""
    if revolute:
        jac[0, k] += mult * (wy * dz - wz * dy)
        jac[1, k] += mult * (wz * dx - wx * dz)
        jac[2, k] += mult * (wx * dy - wy * dx)
        jac[3, k] += mult * wx
        jac[4, k] += mult * wy
        jac[5, k] += mult * wz
    else:
        jac[0, k] += mult * wx
        jac[1, k] += mult * wy
        jac[2, k] += mult * wz


@jit.kernel
def add_joint_columns(jac, k, mult, revolute, origin, axis, point) -> None:
    """:func:`add_joint_column` for n rows: jac (n, 6, dof), joint origins, world axes and
    tracked points (n, 3)."""
    for i in range(jac.shape[0]):
        add_joint_column(jac[i], k, mult, revolute, axis[i, 0], axis[i, 1], axis[i, 2],
                         point[i, 0] - origin[i, 0], point[i, 1] - origin[i, 1],
                         point[i, 2] - origin[i, 2])
