"""The soft-finger contacts' torsional wrench primitives: a contact that also resists a
torque about its normal, up to gamma (metres) times its normal force, adds the wrenches
(n, s (p - c) x n +- s gamma n) to its friction cone's (conventions:
:mod:`kinegrasp_env.quality.wrenches`; the soft contact model:
:mod:`kinegrasp_env.quality.soft_contacts`)."""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit

__all__ = ["torsion_into", "torsion_wrenches", "torsions_into"]


@jit.kernel
def torsion_into(points, unit, torque_scale, center_x, center_y, center_z, gamma, out):
    """The soft contacts' torsional primitives into out (2 k, 6): rows 2 i and 2 i + 1 are
    contact i's (n, s (p - c) x n + s gamma n) and (n, s (p - c) x n - s gamma n) (points,
    unit normals (k, 3); s the torque scale, c the centre, gamma in metres)."""
    for i in range(points.shape[0]):
        n0, n1, n2 = unit[i, 0], unit[i, 1], unit[i, 2]
        l0 = (points[i, 0] - center_x) * torque_scale
        l1 = (points[i, 1] - center_y) * torque_scale
        l2 = (points[i, 2] - center_z) * torque_scale
        t0, t1, t2 = l1 * n2 - l2 * n1, l2 * n0 - l0 * n2, l0 * n1 - l1 * n0
        g = torque_scale * gamma
        for sign in range(2):
            row = out[2 * i + sign]
            twist = g if sign == 0 else -g
            row[0], row[1], row[2] = n0, n1, n2
            row[3], row[4], row[5] = t0 + twist * n0, t1 + twist * n1, t2 + twist * n2


@jit.kernel
def torsions_into(points, unit, torque_scale, center, gamma, out):
    """:func:`torsion_into` of B grasps: points, unit normals (B, k, 3), torque_scale (B,),
    center (B, 3), gamma (metres) -> out (B, 2 k, 6)."""
    for b in range(points.shape[0]):
        torsion_into(points[b], unit[b], torque_scale[b], center[b, 0], center[b, 1],
                     center[b, 2], gamma, out[b])


def torsion_wrenches(points: np.ndarray, normals: np.ndarray, torque_scale: np.ndarray,
                     center: np.ndarray, gamma: float) -> np.ndarray:
    """(B, 2 k, 6) soft contacts' torsional primitives (:func:`torsion_into`); points and
    unit normals (B, k, 3), torque_scale (B,), center (B, 3), gamma in metres."""
    batch, k = points.shape[:2]
    out = np.empty((batch, 2 * k, 6))
    torsions_into(np.ascontiguousarray(points, dtype=float),
                  np.ascontiguousarray(normals, dtype=float),
                  np.ascontiguousarray(torque_scale, dtype=float),
                  np.ascontiguousarray(center, dtype=float), float(gamma), out)
    return out
