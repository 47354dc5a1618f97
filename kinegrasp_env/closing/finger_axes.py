"""Capsule axes of a finger's two links for many flexions: one compiled kernel.

A finger link's capsule axis in the object frame is the link frame applied to the axis end
points in the link frame. The proximal link frame is the (fixed) joint frame rotated about
the proximal axis by the proximal flexion; the distal frame is the proximal frame times the
distal joint's origin, rotated about the distal axis by the distal flexion. The auto-close
evaluates this ~20 times per closing iteration, mostly for a few dozen rows, where numpy's
per-call cost dominates; the numba kernel does it in one call.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit


@jit.kernel(_nrt=False)
def _rotation(axis: np.ndarray, angle: float, out: np.ndarray) -> None:
    """Rodrigues rotation about unit ``axis`` (3,) by ``angle`` into ``out`` (3, 3)."""
    x, y, z = axis[0], axis[1], axis[2]
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    out[0, 0] = c + x * x * t
    out[0, 1] = x * y * t - z * s
    out[0, 2] = x * z * t + y * s
    out[1, 0] = y * x * t + z * s
    out[1, 1] = c + y * y * t
    out[1, 2] = y * z * t - x * s
    out[2, 0] = z * x * t - y * s
    out[2, 1] = z * y * t + x * s
    out[2, 2] = c + z * z * t


@jit.kernel(_nrt=False)
def axes_one(joint_frame, axis_p, prox, distal_origin, axis_d, dist, ends_p, ends_d, rot,
             frame_p, frame_d, tmp, out):
    """One row: out (4, 3) for joint_frame (4, 4) and flexions prox, dist; rot, tmp (3, 3),
    frame_p, frame_d (3, 4) are work buffers."""
    _rotation(axis_p, prox, rot)
    for r in range(3):
        for c in range(3):
            frame_p[r, c] = (joint_frame[r, 0] * rot[0, c] + joint_frame[r, 1] * rot[1, c]
                             + joint_frame[r, 2] * rot[2, c])
        frame_p[r, 3] = joint_frame[r, 3]
    for r in range(3):
        for c in range(4):
            v = (frame_p[r, 0] * distal_origin[0, c] + frame_p[r, 1] * distal_origin[1, c]
                 + frame_p[r, 2] * distal_origin[2, c])
            if c == 3:
                v += frame_p[r, 3]
            frame_d[r, c] = v
    _rotation(axis_d, dist, rot)
    for r in range(3):
        for c in range(3):
            tmp[r, c] = (frame_d[r, 0] * rot[0, c] + frame_d[r, 1] * rot[1, c]
                         + frame_d[r, 2] * rot[2, c])
    for r in range(3):
        for c in range(3):
            frame_d[r, c] = tmp[r, c]
    for k in range(2):
        for r in range(3):
            out[k, r] = (frame_p[r, 0] * ends_p[k, 0] + frame_p[r, 1] * ends_p[k, 1]
                         + frame_p[r, 2] * ends_p[k, 2] + frame_p[r, 3])
            out[2 + k, r] = (frame_d[r, 0] * ends_d[k, 0] + frame_d[r, 1] * ends_d[k, 1]
                             + frame_d[r, 2] * ends_d[k, 2] + frame_d[r, 3])


@jit.kernel
def _axes_kernel(joint_frames, axis_p, prox, distal_origin, axis_d, dist, ends_p, ends_d, out):
    """out (m, 4, 3): proximal a, b, distal a, b for each row."""
    rot = np.empty((3, 3))
    frame_p = np.empty((3, 4))
    frame_d = np.empty((3, 4))
    tmp = np.empty((3, 3))
    for i in range(prox.shape[0]):
        axes_one(joint_frames[i], axis_p, prox[i], distal_origin, axis_d, dist[i], ends_p,
                 ends_d, rot, frame_p, frame_d, tmp, out[i])


def finger_axes(joint_frames: np.ndarray, axis_p: np.ndarray, prox: np.ndarray,
                distal_origin: np.ndarray, axis_d: np.ndarray, dist: np.ndarray,
                ends_p: np.ndarray, ends_d: np.ndarray) -> np.ndarray:
    """Axis end points (m, 4, 3) [proximal a, proximal b, distal a, distal b] (object frame).

    Args:
        joint_frames: (m, 4, 4) proximal joint frames at zero flexion.
        axis_p, axis_d: (3,) unit joint axes; prox, dist: (m,) flexions (radians).
        distal_origin: (4, 4) distal joint origin in the proximal link frame.
        ends_p, ends_d: (2, 3) axis end points in each link's frame (metres).
    """
    out = np.empty((len(prox), 4, 3))
    _axes_kernel(np.ascontiguousarray(joint_frames, dtype=np.float64),
                 np.asarray(axis_p, np.float64), np.ascontiguousarray(prox, dtype=np.float64),
                 np.ascontiguousarray(distal_origin, dtype=np.float64),
                 np.asarray(axis_d, np.float64), np.ascontiguousarray(dist, dtype=np.float64),
                 ends_p, ends_d, out)
    return out
