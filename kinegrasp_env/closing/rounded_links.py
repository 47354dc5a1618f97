"""Distances of a link's rounded parts (capsules, spheres: :class:`~kinegrasp_env.closing.
link_geometry.RoundedPart`) to the object, for the fast generic closing.

A rounded part is a ball of radius r swept along a segment (its *core*, one point for a
sphere), so its distance to the object is the core's less r:

* **bound**: the distance grid's along the core (:func:`~kinegrasp_env.closing.capsule_gap.
  sampled_bounds`, less the grid's error) where it is above :data:`GRID_CLEAR`, else GJK on
  the core (a hull of one or two vertices) against the object's convex parts
  (:func:`~kinegrasp_env.closing.convex_distance.hull_distance_bounds`), less r: a
  certified lower bound either way, -inf where the core meets a part;
* **exact**: the exact closest pair of the core segment and the object
  (:func:`~kinegrasp_env.closing.segment_distance.closest_to_segments`), less r, where the
  bound says the core is apart from the object; where the core meets it, the part is at
  least r deep (its distance is given as -r: a start collision for any tolerance below r).

A contact of a rounded part is the point model of the paper's fingertips: the closest point
on the object, its normal the direction from the core's closest point to it (inward).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.capsule_gap import sampled_bounds
from kinegrasp_env.closing.convex_distance import (
    hull_distance_bounds,
    new_hints,
    stacked_points,
)
from kinegrasp_env.closing.link_geometry import RoundedPart, grid_error
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sdf import DistanceGrid

#: A core whose grid bound is above this (metres) takes it (GJK below).
GRID_CLEAR = 5e-3

__all__ = ["RoundedCores", "contact_normals", "core_layout"]


class RoundedCores:
    """One link's rounded parts, their cores laid out for GJK.

    Args:
        parts: the link's rounded parts (link frame).
        object_hulls: the object's convex parts in GJK's layout
            (:func:`~kinegrasp_env.closing.convex_distance.stacked_vertices`).
        simplex: GJK's scratch (:func:`~kinegrasp_env.closing.convex_distance.new_simplex`).
        grid: the object's distance grid.
    """

    def __init__(self, parts: tuple[RoundedPart, ...], object_hulls: tuple, simplex,
                 grid: DistanceGrid) -> None:
        self.parts, self.grid, self._grid_err = parts, grid, grid_error(grid)
        self._cores = [core_layout(p) for p in parts]
        self._object_hulls, self._simplex = object_hulls, simplex

    def _core_bound(self, k: int, rot: np.ndarray, trans: np.ndarray, motion: np.ndarray | None,
                    short: float, clear: float = GRID_CLEAR) -> tuple[np.ndarray, np.ndarray]:
        """(a certified lower bound (n,) of part k's core's distance to the object, -inf
        where they meet; travel (n,) along ``motion`` before a plane lets it within
        ``short``, 0 without a motion): the grid's where it is above ``clear`` (metres; and
        no motion), GJK's elsewhere."""
        n = rot.shape[0]
        out, travel = np.full(n, -np.inf), np.zeros(n)
        todo = np.arange(n)
        if motion is None:
            part = self.parts[k]
            a, b = rot @ part.a + trans, rot @ part.b + trans
            out = sampled_bounds(self.grid, a, b) - self._grid_err
            todo = np.flatnonzero(~(out > clear))
            motion = np.zeros((n, 3))
        if todo.size:
            found, far = np.empty(todo.size), np.empty(todo.size)
            hull_distance_bounds(*self._cores[k], np.ascontiguousarray(rot[todo]),
                                 np.ascontiguousarray(trans[todo]), *self._object_hulls,
                                 np.ascontiguousarray(motion[todo]), float(short),
                                 new_hints(todo.size, self._cores[k], self._object_hulls),
                                 self._simplex, found, far, np.inf)
            out[todo], travel[todo] = found, far
        return out, travel

    def bounds(self, poses: np.ndarray, motion: np.ndarray | None = None, short: float = 0.0
               ) -> tuple[np.ndarray, np.ndarray]:
        """((n,) certified lower bound of the parts' least distance to the object, placed by
        object-frame poses (n, 4, 4), -inf where a core meets it; (n,) how far the link can
        be translated by ``motion`` (n, 3) per unit before a separating plane lets a part
        come within ``short``; inf without parts, 0 without a motion)."""
        n = poses.shape[0]
        best, far = np.full(n, np.inf), np.full(n, np.inf if motion is not None else 0.0)
        rot = np.ascontiguousarray(poses[:, :3, :3])
        trans = np.ascontiguousarray(poses[:, :3, 3])
        for k, part in enumerate(self.parts):
            out, travel = self._core_bound(k, rot, trans, motion, short + part.radius)
            best = np.minimum(best, out - part.radius)
            if motion is not None:
                far = np.minimum(far, travel)
        return best, far

    def exact(self, obj: GraspObject, poses: np.ndarray, below: float = np.inf
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(distance (n,), core point (n, 3), object point (n, 3)) of the parts' closest
        pair with the object at object-frame poses (n, 4, 4) (module docstring; where a
        core meets the object: -r and NaN points). With ``below`` (metres), exact where the
        distance is below it, and ``below`` with NaN points elsewhere (the distance is at
        least that)."""
        n = poses.shape[0]
        dist = np.full(n, np.inf)
        core_point, obj_point = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
        rot = np.ascontiguousarray(poses[:, :3, :3])
        trans = np.ascontiguousarray(poses[:, :3, 3])
        for k, part in enumerate(self.parts):
            apart, _ = self._core_bound(k, rot, trans, None, 0.0, clear=0.0)
            d = np.full(n, -part.radius)
            seg, on_obj = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
            rows = np.flatnonzero(apart > 0.0)  # the core is apart from the object
            if rows.size:
                a = np.einsum("nij,j->ni", rot[rows], part.a) + trans[rows]
                b = np.einsum("nij,j->ni", rot[rows], part.b) + trans[rows]
                limit = below + part.radius
                on_obj[rows], seg[rows], core_d, _ = closest_to_segments(obj, a, b, limit)
                d[rows] = np.where(core_d < limit, core_d - part.radius, below)
            better = d < dist
            dist[better], core_point[better], obj_point[better] = (
                d[better], seg[better], on_obj[better])
        return dist, core_point, obj_point


def core_layout(part: RoundedPart) -> tuple[np.ndarray, ...]:
    """A rounded part's core as a hull of one or two vertices, in the layout of
    :func:`~kinegrasp_env.closing.convex_distance.stacked_points`."""
    return stacked_points([np.stack([part.a, part.b]) if np.any(part.a != part.b)
                           else part.a[None]])


def contact_normals(core_point: np.ndarray, obj_point: np.ndarray) -> np.ndarray:
    """(m, 3) unit inward normals of rounded parts' contacts: from the core's closest
    points (m, 3) to the object's (m, 3)."""
    direction = obj_point - core_point
    return direction / np.linalg.norm(direction, axis=1, keepdims=True)
