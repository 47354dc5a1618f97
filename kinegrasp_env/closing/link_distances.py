"""Distances of a robot's links to one object, for the fast generic closing: exact closest
pairs and certified lower bounds, batched over poses.

A link's collision geometry (:mod:`~kinegrasp_env.closing.link_geometry`) is polytopes and
rounded parts. Its exact closest pair with the object is the least of its polytopes' (the
link's hull vertices against the object's convex parts and the object's edges against each
link hull: every closest pair of two convex polytopes apart has a vertex of one or a point on
an edge of each; where they overlap, the link's edges through the object's parts besides)
and its rounded parts' (:class:`~kinegrasp_env.closing.rounded_links.RoundedCores`). Its
lower bound: GJK on the hulls' vertices
(:func:`~kinegrasp_env.closing.convex_distance.hull_distance_bounds`), with how far the link
can move along a direction before a separating plane lets it near.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.convex_distance import (
    hint_shape,
    hull_distance_bounds,
    new_simplex,
    stacked_faces,
    stacked_vertices,
)
from kinegrasp_env.closing.hull_edges import edges_against_hull, vertices_against_parts
from kinegrasp_env.closing.link_geometry import LinkGeometry
from kinegrasp_env.closing.packed_geometry import pack_each
from kinegrasp_env.closing.rounded_links import RoundedCores
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.polytope import INSIDE_TOL
from kinegrasp_env.world.sdf import DistanceGrid

#: Golden-section steps along an object edge that meets a link's hull (its parameter to
#: 0.618**40 = 4e-9).
SEARCH = 40
GOLD = 0.5 * (np.sqrt(5.0) - 1.0)

__all__ = ["GOLD", "SEARCH", "LinkDistances"]


class LinkDistances:
    """The links of ``geometry`` (link name -> :class:`~kinegrasp_env.closing.link_geometry.
    LinkGeometry`) against the object ``obj`` (its distance grid ``grid``).

    Attributes:
        edges: the object's edges as the exact distances read them
            (:func:`~kinegrasp_env.closing.convex_distance.stacked_faces`).
        parts: the object's face planes and edges as
            :func:`~kinegrasp_env.closing.hull_edges.vertices_against_parts` reads them.
    """

    def __init__(self, geometry: dict[str, LinkGeometry], obj: GraspObject,
                 grid: DistanceGrid) -> None:
        self.geometry, self.obj = geometry, obj
        planes, plane_starts, self.edges, edge_starts = stacked_faces(obj.convex_parts)
        self._local_edges = np.empty_like(self.edges)
        self._object_hulls = stacked_vertices(obj.convex_parts)
        #: each object part packed as one hull (object frame), for the links' edges against
        #: it, as a link's are for the object's edges (its bounding ball: _object_hulls')
        self._object_packed = pack_each(obj.convex_parts)
        self._simplex = new_simplex()
        self._link_hulls = {link: g.hulls for link, g in geometry.items() if g.parts}
        self._rounded = {link: RoundedCores(g.rounded, self._object_hulls, self._simplex, grid)
                         for link, g in geometry.items() if g.rounded}
        self.parts = (planes, plane_starts, self.edges, edge_starts,
                      np.array([INSIDE_TOL * p.scale for p in obj.convex_parts]))
        if self._rounded:  # the bounded search of a rounded part's start check, loaded now
            far = np.full((1, 3), 10.0)  # (a held engine pays no compile or load mid-run)
            closest_to_segments(obj, far, far, 1e-3)

    def exact(self, poses: np.ndarray, link: str, below: float = np.inf,
               decide: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(signed distance (n,), link point (n, 3), object point (n, 3), rounded (n,) bool)
        of the closest pair of ``link`` placed by object-frame poses (n, 4, 4) and the
        object, exact: the least of its polytopes' (:meth:`polytopes`) and of its
        rounded parts' (:class:`~kinegrasp_env.closing.rounded_links.RoundedCores`: then
        ``rounded`` is set and the link point is the core's)."""
        n = poses.shape[0]
        if self.geometry[link].parts:
            dist, fp, op = self.polytopes(poses, link, below, decide)
        else:
            dist, fp, op = np.full(n, np.inf), np.full((n, 3), np.nan), np.full((n, 3), np.nan)
        rounded = np.zeros(n, dtype=bool)
        if link in self._rounded:
            d, core, on_obj = self._rounded[link].exact(self.obj, poses, below)
            rounded = d < dist
            dist[rounded], fp[rounded], op[rounded] = d[rounded], core[rounded], on_obj[rounded]
        return dist, fp, op, rounded

    def polytopes(self, poses: np.ndarray, link: str, below: float = np.inf,
                         decide: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(signed distance (n,), link point (n, 3), object point (n, 3)) of the closest
        pair of ``link``'s polytopes placed by object-frame poses (n, 4, 4) and the object,
        exact: the least of the link's hull vertices against the object and of the object's
        edges against each link hull (:func:`~kinegrasp_env.closing.hull_edges.
        edges_against_hull`: exact beside the hull, :data:`SEARCH` golden steps along an
        edge through it), and where they overlap of the link's edges through the object's
        parts (:meth:`_link_edges_through`). Every closest pair of two convex polytopes apart
        has a vertex of one or a point on an edge of each; two that overlap can do so with an
        edge of each crossing and no vertex of either inside the other. With
        ``below``, edges that cannot bring a distance under it are skipped (a distance left
        at or above ``below`` is then only an upper bound); with ``decide`` too, a draw whose
        vertices already bring it below ``below`` is not searched further (its distance then
        only an upper bound below ``below``: the answer to "is it below?")."""
        geom = self.geometry[link]
        n = poses.shape[0]
        rot, trans = poses[:, :3, :3], poses[:, :3, 3]
        rot, trans = np.ascontiguousarray(rot), np.ascontiguousarray(trans)
        dist, fp, op = np.empty(n), np.empty((n, 3)), np.empty((n, 3))
        vertices_against_parts(*self.parts, rot, trans, geom.vertices, float(below), dist, fp,
                               op)
        rows = np.flatnonzero(~(dist < below)) if decide else None
        if rows is not None:  # the edges of the undecided draws only
            rot, trans = rot[rows], trans[rows]
            d, f, o = dist[rows], fp[rows], op[rows]
        else:
            d, f, o = dist, fp, op
        for sphere, packed in zip(geom.hulls[2], geom.packed, strict=True):
            edges_against_hull(packed, sphere, np.empty((2, len(packed[0]))), rot, trans,
                               self.edges, float(below), SEARCH, GOLD, d, f, o,
                               self._local_edges, False)
        # where the two overlap, the link's edges through the object's parts: two polytopes
        # can overlap with no vertex of either inside the other and no edge of the object
        # through the link (a link edge across an object edge), which the above misses
        self._link_edges_through(link, rot, trans, below, d, f, o)
        if rows is not None:
            dist[rows], fp[rows], op[rows] = d, f, o
        return dist, fp, op

    def _link_edges_through(self, link: str, rot: np.ndarray, trans: np.ndarray,
                            below: float, d: np.ndarray, f: np.ndarray, o: np.ndarray) -> None:
        """Lower d (n,) to the least signed distance of ``link``'s hull edges that meet an
        object part (posed by the object-frame link poses rot (n, 3, 3), trans (n, 3)), with
        the link point f and the object point o (object frame): the object's parts posed in
        the link frame, the link's edges against each (``meeting_only``: an edge beside a
        part is no nearer than the closest pair the vertices and the object's edges give)."""
        ends = self.geometry[link].faces[2]  # the link's hull edges (link frame)
        if len(rot) == 0 or len(ends) == 0:
            return
        inv_rot = np.ascontiguousarray(np.swapaxes(rot, 1, 2))
        inv_trans = np.ascontiguousarray(-np.einsum("nji,nj->ni", rot, trans))
        local = np.empty_like(ends)
        best, on_part, on_edge = d.copy(), np.empty_like(f), np.empty_like(o)
        for packed, sphere in zip(self._object_packed, self._object_hulls[2], strict=True):
            edges_against_hull(packed, sphere, np.empty((2, len(packed[0]))), inv_rot,
                               inv_trans, ends, float(below), SEARCH, GOLD, best, on_part,
                               on_edge, local, True)
        took = best < d
        if took.any():  # the points found are in the link frame: back to the object's
            r, t = rot[took], trans[took]
            d[took] = best[took]
            f[took] = np.einsum("nij,nj->ni", r, on_edge[took]) + t
            o[took] = np.einsum("nij,nj->ni", r, on_part[took]) + t

    def new_hints(self, link: str, n: int) -> np.ndarray:
        """Where :meth:`distance_bound` of ``link`` starts at n draws: nowhere known yet
        (:func:`~kinegrasp_env.closing.convex_distance.new_hints`; (n, 0, 2) for a link
        without polytopes)."""
        return np.full(self._hint_shape(link, n), -1, dtype=np.int64)

    def _hint_shape(self, link: str, n: int) -> tuple[int, int, int]:
        """The shape of :meth:`new_hints`' array."""
        if link not in self._link_hulls:
            return n, 0, 2
        return hint_shape(n, self._link_hulls[link], self._object_hulls)

    def distance_bound(self, poses: np.ndarray, link: str, motion: np.ndarray | None = None,
                       short: float = 0.0, hints: np.ndarray | None = None,
                       enough: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """((n,) certified lower bound (metres) of the distance of ``link``'s hulls, placed
        by object-frame poses (n, 4, 4), to the object's convex parts, -inf where they touch
        or overlap; (n,) how far the link can be translated by ``motion`` (n, 3) per unit
        before a separating plane lets it come within ``short`` (metres), 0 without a
        motion)
        (:func:`~kinegrasp_env.closing.convex_distance.hull_distance_bounds`; a rounded
        part's: :class:`~kinegrasp_env.closing.rounded_links.RoundedCores`). ``hints``
        (:meth:`new_hints`, updated in place): where each draw's last bound of the link
        ended, the link moved a little since (a bound that starts there takes fewer
        iterations). ``enough``: a hull pair's bound is sought no higher than this (metres;
        inf: to full precision), for a caller that asks only whether the distance is below
        it."""
        n = poses.shape[0]
        out, travel = np.full(n, np.inf), np.full(n, 0.0 if motion is None else np.inf)
        if hints is not None and hints.shape != self._hint_shape(link, n):
            raise ValueError(f"hints of shape {hints.shape} for link {link!r} at {n} draws: "
                             f"expected {self._hint_shape(link, n)} (new_hints)")
        if link in self._link_hulls:
            move = np.zeros((n, 3)) if motion is None else np.ascontiguousarray(motion)
            hull_distance_bounds(*self._link_hulls[link],
                                 np.ascontiguousarray(poses[:, :3, :3]),
                                 np.ascontiguousarray(poses[:, :3, 3]), *self._object_hulls,
                                 move, float(short),
                                 self.new_hints(link, n) if hints is None else hints,
                                 self._simplex, out, travel, float(enough))
        if link in self._rounded:
            bound, far = self._rounded[link].bounds(poses, motion, short)
            out, travel = np.minimum(out, bound), np.minimum(travel, far)
        return out, travel
