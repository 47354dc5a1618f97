"""Auto-close of any description robot, batched over draws: the closing model of
:mod:`~kinegrasp_env.closing.generic_reference` on the links' exact convex hulls.

**Geometry.** Each robot link's collision geometry is read once from pybullet
(:mod:`~kinegrasp_env.closing.link_geometry`: polytopes, and capsules and spheres as rounded
parts, :mod:`~kinegrasp_env.closing.rounded_links`), expressed in the link's URDF frame.
The distance of a link to the object is exact: the closest pair of two convex polytopes
apart has a vertex of one or a point on an edge of each, so it is the least of the link's hull
vertices against the object (:meth:`GraspObject.closest_points`) and of the object's edges
against the link's hulls (:func:`~kinegrasp_env.closing.hull_edges.edges_against_hull`;
:mod:`~kinegrasp_env.closing.link_distances`); where they overlap, the link's edges through
the object's parts too (an edge of each crossing, no vertex of either inside the other: the
depth of the deepest of these points, which is what the start-collision rule compares). A
certified
lower bound of the same distance, within 1e-8 of it (relative) where the link and the object
are apart, comes far cheaper from GJK on the hulls' vertices
(:func:`~kinegrasp_env.closing.convex_distance.hull_distance_bounds`); the exact pair is taken
only where that bound is within reach of a contact or says the two overlap.

**The closing** follows the reference step for step, every draw of a batch at once:

1. *Start collision*: some link at q penetrates the object deeper than ``start_tol`` (its
   closest pair with the object, exact; links whose bounding ball the distance grid puts
   clear of the object, or whose hulls GJK finds apart from it, are not examined).
2. *Closing*: each finger by its parameter t (its closing joints at the pre-shape value plus
   ``rate * t``, clipped at their limits, until a link that stops them touches), by
   conservative advancement (:mod:`~kinegrasp_env.closing.finger_closing`): t grows by the
   least over the moving links of each one's gap lower bound over its speed bound by the
   joints still turning (:func:`~kinegrasp_env.closing.finger_paths.link_speeds`). The
   lower bound is GJK's;
   where it is within ``contact_tol`` (or the hulls overlap) the exact distance replaces it.
   A finger whose closing joints are all prismatic translates its links: it steps at least
   as far as their separating planes allow, up to its first joint's limit; a revolute one at
   least the reference's smallest step, its touches polished to a zero gap.
3. *Contacts*: per touching finger link, its exact closest pair with the object (the
   closing's last one: a touching draw took it at its final joint values). On one
   face of the object (:func:`~kinegrasp_env.closing.pad_faces.faces_of`): that
   face's inward normal, the point moved to the pad's patch centre
   (:func:`~kinegrasp_env.closing.contact_patch.patch_centre`); so at an edge or a corner of
   the face a face of the pad lies on, crossing its plane by less than the depth a pad is
   pressed in (:func:`~kinegrasp_env.closing.pad_faces.flat_face`). Else, at an edge or
   a corner: the pair's direction (the link face's normal where the link point is inside
   one face; perpendicular to both edges for two edges; else the points' difference:
   :mod:`~kinegrasp_env.closing.pair_normals`, the reference's rule there too); a pad along
   an edge of the object, the point moved to the middle of the segment it presses
   (:mod:`~kinegrasp_env.closing.edge_contact`).

Fingers of two capsule phalanxes are closed by one compiled loop instead
(:mod:`~kinegrasp_env.closing.capsule_fingers`: the distance grid far from the object, the
exact pair near it, bisection, the touch polished to a zero gap), at the default contact
tolerance; steps 1 and 3 stay as above.

Results are the reference's :class:`~kinegrasp_env.closing.close_result.RobotCloseResult`
(``queries`` counts the exact link-object distances of steps 1 and 2, per draw; the
compiled loop's are not counted).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.capsule_fingers import CapsuleFingers, capsule_finger
from kinegrasp_env.closing.capsule_gap import centre_distances
from kinegrasp_env.closing.close_batch import RobotCloseBatch
from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.closing.close_rules import CONTACT_TOL, START_TOL
from kinegrasp_env.closing.contact_patch import PatchGeometry
from kinegrasp_env.closing.edge_contact import place_on_edges
from kinegrasp_env.closing.finger_closing import close_finger
from kinegrasp_env.closing.finger_paths import FingerPath, finger_paths
from kinegrasp_env.closing.generic_reference import EDGE_TOL
from kinegrasp_env.closing.hand_errors import (
    arm_to_object,
    flange_link,
    hand_links,
    world_to_object,
)
from kinegrasp_env.closing.hand_geometry import surface_contact
from kinegrasp_env.closing.link_distances import LinkDistances
from kinegrasp_env.closing.link_geometry import LinkGeometry, grid_error, robot_link_geometry
from kinegrasp_env.closing.pad_faces import faces_of, flat_face
from kinegrasp_env.closing.pair_normals import LINE_TOL, pair_normals
from kinegrasp_env.closing.rounded_links import contact_normals
from kinegrasp_env.closing.table_check import TableCheck
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sdf import DistanceGrid, grid_of

__all__ = ["FastRobotHand"]


class FastRobotHand:
    """The batched closing of a description robot on one object.

    Args:
        description: the robot.
        obj: the catalog object (at ``obj.pose`` in the robot's base frame).
        grid: the object's distance grid (default: :func:`~kinegrasp_env.world.sdf.grid_of`).
        geometry: link name -> :class:`LinkGeometry` (default: the robot's,
            :func:`~kinegrasp_env.closing.link_geometry.robot_link_geometry`).
        patch: place a contact on a face at its patch's centre (as ``RobotWorld(patch=)``).
        compiled: close the fingers of two capsule phalanxes in one compiled loop
            (:mod:`~kinegrasp_env.closing.capsule_fingers`; at the default contact
            tolerance); False: every finger by the batched loop.
    """

    def __init__(self, description: RobotDescription, obj: GraspObject, *,
                 grid: DistanceGrid | None = None,
                 geometry: dict[str, LinkGeometry] | None = None, patch: bool = True,
                 compiled: bool = True) -> None:
        self.description, self.obj, self.patch = description, obj, patch
        self.model = description.model
        self.grid = grid_of(obj) if grid is None else grid
        self.grid_err = grid_error(self.grid)
        self.geometry = robot_link_geometry(description) if geometry is None else geometry
        self.kinematics = Kinematics(self.model)
        self._links = list(self.geometry)
        spheres = [self.geometry[link].sphere for link in self._links]
        self._centres = np.array([centre[0] for centre, _ in spheres])  # (L, 3)
        self._radii = np.array([radius for _, radius in spheres])  # (L,)
        self.paths = finger_paths(description, self.geometry, self.kinematics)
        self.distances = LinkDistances(self.geometry, obj, self.grid)
        self._link_faces = {link: g.faces for link, g in self.geometry.items() if g.parts}
        self._patch = PatchGeometry(obj.parts)
        self._flange, self._hand = flange_link(description), hand_links(description)
        self._in_hand = np.array([link in self._hand for link in self._links])  # (L,)
        self._table = None if obj.table is None else TableCheck(self.geometry, obj)
        capsules = [found for f, path in enumerate(self.paths)
                    if (found := capsule_finger(f, path, self.geometry)) is not None]
        self._capsules = (CapsuleFingers(capsules, obj, self.grid, description.palm_link)
                          if capsules and compiled else None)

    # ------------------------------------------------------------------ distances
    def exact(self, poses: np.ndarray, link: str, below: float = np.inf,
              decide: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`~kinegrasp_env.closing.link_distances.LinkDistances.exact` of the
        robot's links."""
        return self.distances.exact(poses, link, below, decide)

    def new_hints(self, link: str, n: int) -> np.ndarray:
        """:meth:`~kinegrasp_env.closing.link_distances.LinkDistances.new_hints` of the
        robot's links: where :meth:`distance_bound` of ``link`` starts at n draws."""
        return self.distances.new_hints(link, n)

    def distance_bound(self, poses: np.ndarray, link: str, motion: np.ndarray | None = None,
                       short: float = 0.0, hints: np.ndarray | None = None,
                       enough: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`~kinegrasp_env.closing.link_distances.LinkDistances.distance_bound` of
        the robot's links."""
        return self.distances.distance_bound(poses, link, motion, short, hints, enough)

    def _object_poses(self, q: np.ndarray, maps: tuple[np.ndarray, np.ndarray] | None
                      ) -> np.ndarray:
        """(L, n, 4, 4) every link's pose at q (n, dof) in the true object's frame (``maps``:
        as in :meth:`start_collision`), links in the geometry's order."""
        world = self.kinematics.forward(q, self._links)
        stacked = np.stack([world[link] for link in self._links])
        if maps is None:
            return self.obj.pose_inverse @ stacked
        hand = self._in_hand
        poses = np.empty_like(stacked)
        poses[~hand], poses[hand] = maps[0] @ stacked[~hand], maps[1] @ stacked[hand]
        return poses

    def _in_table(self, poses: np.ndarray) -> np.ndarray:
        """(n,) bool: some link placed by ``poses`` (:meth:`_object_poses`) touches or enters
        the object's support table (all False without one)."""
        if self._table is None:
            return np.zeros(poses.shape[1], dtype=bool)
        return self._table.any_hits(self._links, poses)

    def table_hits(self, q: np.ndarray, maps: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> np.ndarray:
        """(n,) bool: at q (n, dof) some link touches or enters the object's support table
        (:class:`~kinegrasp_env.closing.table_check.TableCheck`; all False without one);
        ``maps`` as in :meth:`start_collision`."""
        return self._in_table(self._object_poses(q, maps))

    def start_collision(self, q: np.ndarray, start_tol: float = START_TOL,
                        maps: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """(n,) bool: some link at q (n, dof) deeper than ``start_tol`` in the object (a
        link whose bounding ball the grid puts clear of the object, or whose hulls are apart
        from the object's (:meth:`distance_bound`), is not examined exactly), or touching
        its support table (:meth:`table_hits`); ``maps``: the
        (n, 4, 4) maps of an arm link's and of a hand link's world pose to the true object's
        frame (:meth:`error_maps`; default: the believed object pose's inverse)."""
        poses = self._object_poses(q, maps)
        hit = self._in_table(poses)
        near = (centre_distances(self.grid, poses, self._centres) - self.grid_err
                < self._radii[:, None])
        for k in np.flatnonzero(near.any(axis=1)):
            link, pose = self._links[k], poses[k]
            rows = np.flatnonzero(~hit & near[k])
            if rows.size == 0:
                continue
            # only "deeper than start_tol?" is asked: no bound is sought above its answer
            bound = self.distance_bound(pose[rows], link, enough=max(0.0, -start_tol))[0]
            rows = rows[bound < -start_tol]
            if rows.size:
                dist = self.exact(pose[rows], link, -start_tol, decide=True)[0]
                hit[rows[dist < -start_tol]] = True
        return hit

    # ------------------------------------------------------------------ closing
    def close(self, q: np.ndarray, *, contact_tol: float = CONTACT_TOL,
              start_tol: float = START_TOL) -> list[RobotCloseResult]:
        """Close the hand of every configuration q (n, dof) (the module's model): one
        result per draw (:meth:`close_batch`'s, draw by draw)."""
        return self.close_batch(q, contact_tol=contact_tol, start_tol=start_tol).results()

    def error_maps(self, q: np.ndarray, palm: np.ndarray | None,
                   object_offset: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(arm map, hand map), each (n, 4, 4): an arm link's and a hand link's world pose at
        q (n, dof) to the true object's frame, under palm errors and object errors (n, 4, 4;
        None = exact) (:mod:`~kinegrasp_env.closing.hand_errors`)."""
        n = q.shape[0]
        flange = self.kinematics.pose(q, self._flange)
        return (arm_to_object(self.obj.pose, object_offset, n),
                world_to_object(flange, self.obj.pose, palm, object_offset))

    def close_batch(self, q: np.ndarray, *, contact_tol: float = CONTACT_TOL,
                    start_tol: float = START_TOL, palm: np.ndarray | None = None,
                    object_offset: np.ndarray | None = None) -> RobotCloseBatch:
        """Close the hand of every configuration q (n, dof) (the module's model), as
        arrays; ``palm``, ``object_offset``: per-draw palm and object errors (n, 4, 4)
        (:mod:`~kinegrasp_env.closing.hand_errors`; the contacts are in the true object's
        frame)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        n, fingers = q.shape[0], self.description.fingers
        maps = None
        if palm is not None or object_offset is not None:
            maps = self.error_maps(q, palm, object_offset)
        start = self.start_collision(q, start_tol, maps)
        values0 = self.model.expand(q)
        to_object = self.obj.pose_inverse if maps is None else maps[1]
        palm = to_object @ self.kinematics.pose(q, self.description.palm_link)
        gaps = np.full((n, len(fingers)), np.nan)
        travel = np.zeros((n, len(fingers)))
        final = {name: values0[name].copy() for name in values0}
        found: dict[str, list] = {  # each column's pieces, an empty one first
            "row": [np.empty(0, np.int64)], "finger": [np.empty(0, np.int64)],
            "link": [np.empty(0, np.int64)], "points": [np.empty((0, 3))],
            "normals": [np.empty((0, 3))], "distances": [np.empty(0)]}
        queries = np.zeros(n, dtype=np.int64)
        free = np.flatnonzero(~start)
        values_free = {k: v[free] for k, v in values0.items()}
        compiled = ({} if self._capsules is None or contact_tol != CONTACT_TOL
                    else self._capsules.close(palm[free], values_free))
        for f in range(len(fingers)):
            path = self.paths[f]
            if f in compiled:
                t, g, values, last = _compiled_finger(path, compiled[f])
            else:
                t, g, values, last = close_finger(self, path, palm[free], values_free,
                                                  contact_tol, queries, free)
            gaps[free, f], travel[free, f] = g, t
            for name in path.joints:
                final[name][free] = values[name]
            held = np.flatnonzero(g <= contact_tol)
            if held.size:  # the closing's last exact pairs are at the final joint values
                for k, link in enumerate(fingers[f].links):
                    if link not in self.geometry:
                        continue
                    pose, d, fp, op, rounded, *part = (a[held] for a in last[link])
                    on = d <= contact_tol
                    if on.any():
                        points, normals = self._contacts(link, pose[on], d[on], fp[on], op[on],
                                                         rounded[on], *(p[on] for p in part))
                        for key, value in (("row", free[held][on]), ("finger", f), ("link", k),
                                           ("points", points), ("normals", normals),
                                           ("distances", d[on])):
                            found[key].append(np.broadcast_to(value, points.shape[:1]
                                                              + np.shape(value)[1:]))
        columns = {key: np.concatenate(pieces) for key, pieces in found.items()}
        order = np.argsort(columns["row"], kind="stable")  # by finger, then link, per draw
        return RobotCloseBatch(start, np.where(start[:, None], False, gaps > contact_tol),
                               gaps, travel, final, queries,
                               **{key: value[order] for key, value in columns.items()})

    def _contacts(self, link: str, poses: np.ndarray, distance: np.ndarray,
                  finger_point: np.ndarray, point: np.ndarray, rounded: np.ndarray,
                  part: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(points (m, 3), unit normals (m, 3)) of the contacts of ``link`` at its
        object-frame poses (m, 4, 4) (closest pairs: distances (m,), link points and object
        points (m, 3); ``rounded`` (m,): the pair is a rounded part's, whose link point is
        its core's). A flat part's on a face
        (:func:`~kinegrasp_env.closing.pad_faces.faces_of`), or at an edge of the face
        it lies flat on (:func:`~kinegrasp_env.closing.pad_faces.flat_face`): that
        face's inward normal, the point moved to its
        patch centre; on an edge, the direction of the pair, as the reference's rule, the
        point moved to the middle of the segment a pad along the edge presses. A
        rounded part's, the point model's (:func:`~kinegrasp_env.closing.hand_geometry.
        surface_contact`): the face's inward normal where the direction from its core agrees
        with it, else that direction, on the object's convex part ``part`` (m,) of the pair
        where given (-1: the nearest one)."""
        parts = np.full(point.shape[0], -1) if part is None else part
        face, plane = np.full(point.shape[0], -1), np.zeros((point.shape[0], 4))
        if not rounded.all():  # a rounded part's contact: the point model's rule below
            face[~rounded], plane[~rounded] = faces_of(self.obj, point[~rounded], EDGE_TOL)
        normals = -plane[:, :3]
        points = point.copy()
        edge = np.flatnonzero((face < 0) & ~rounded)
        if edge.size:  # a pad flat on a face, at its edge: that face
            vertices = self.geometry[link].placed_vertices(poses[edge])
            flat_part, flat_plane = flat_face(self.obj, point[edge], vertices, EDGE_TOL)
            flat = flat_part >= 0
            face[edge[flat]], plane[edge[flat]] = flat_part[flat], flat_plane[flat]
            normals[edge[flat]] = -flat_plane[flat, :3]
            edge = edge[~flat]
        if edge.size:  # on the edge itself: the pair's direction
            planes, _, edges, starts = self._link_faces[link]
            found = np.empty((edge.size, 3))
            pair_normals(planes, edges, starts, self.distances.edges,
                         np.ascontiguousarray(poses[edge, :3, :3]),
                         np.ascontiguousarray(poses[edge, :3, 3]), finger_point[edge],
                         point[edge], distance[edge], EDGE_TOL, LINE_TOL, np.empty((2, 3)),
                         found)
            for i in np.flatnonzero(np.linalg.norm(found, axis=1) < 1e-12):
                found[i] = self.obj.surface(point[edge[i]][None])[1][0]
            normals[edge] = found
            if self.patch:  # a pad along the edge: the middle of the pressed segment
                points[edge], _ = place_on_edges(
                    self.geometry[link].vertices, poses[edge], self.distances.edges,
                    found / np.linalg.norm(found, axis=1, keepdims=True), point[edge])
        pad = (face >= 0) & ~rounded
        if self.patch and pad.any():
            placed, _ = self._patch.place(self.geometry[link].vertices, poses[pad],
                                          face[pad], plane[pad], point[pad])
            points[pad] = placed
        if rounded.any():  # the point model: the face's normal where the pair's agrees
            outward = -contact_normals(finger_point[rounded], point[rounded])
            on_part = parts[rounded]
            unknown = on_part < 0
            if unknown.any():
                on_part[unknown] = self.obj.nearest_part(point[rounded][unknown])
            points[rounded], normals[rounded] = surface_contact(self.obj, point[rounded],
                                                                outward, on_part)
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        return points, normals


def _compiled_finger(path: FingerPath, closed: tuple) -> tuple:
    """A compiled capsule finger's closing (:meth:`~kinegrasp_env.closing.capsule_fingers.
    CapsuleFingers.close`'s) as :func:`~kinegrasp_env.closing.finger_closing.close_finger`
    gives one: (t, gap, its joints' values, per link (pose: unused for a rounded part,
    distance, core point, object point, rounded, the object's part of the pair)))."""
    final, gap, travel, links = closed
    m = gap.shape[0]
    values = {name: final[:, j] for j, name in enumerate(path.joints)}
    last = {link: (np.full((m, 4, 4), np.nan), d, core, point, np.ones(m, dtype=bool), part)
            for link, (d, core, point, part) in links.items()}
    return travel, gap, values, last
