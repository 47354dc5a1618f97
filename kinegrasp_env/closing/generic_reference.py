"""Auto-close of any description robot, the reference: pybullet closest points on the URDF's
own collision geometry.

**The closing model.** The robot and the object stand in one pybullet world, the object
fixed (as in Dex-Net's jaw closing and this project's GraspIt-style closing):
:class:`~kinegrasp_env.closing.scene.RobotScene`, whose link distances this closing
reads (pybullet's, exact for a link of capsules and spheres near contact). A configuration q
(the description's actuated vector: arm joints, then hand joints) places the palm where
forward kinematics of the URDF puts it. Then:

1. *Start collision*: some robot link (arm or hand) penetrates the object by more than
   :data:`START_TOL` at q (the hand at its pre-shape).
2. *Closing*: each finger (:attr:`RobotDescription.fingers`: the chain palm -> fingertip)
   closes on its own, by a parameter t >= 0 (driver units: metres or radians): each closing
   joint takes the value it has when its driver moves from the pre-shape by ``close * t`` (a
   mimic follower through its multiplier), clipped at its limit, until a link that stops it
   touches (GraspIt's rule, :mod:`~kinegrasp_env.robot.touch_rule`: a touching proximal
   phalanx stops its own joint, the distal one goes on; a parallel gripper's coupled jaws
   close together, each stopping where it touches). t advances by conservative advancement:
   the least over the moving links of each one's gap
   (:meth:`~kinegrasp_env.closing.scene.RobotScene.link_gap`) over a bound on how fast
   any point of it moves per unit t by the joints still turning
   (:func:`~kinegrasp_env.closing.finger_paths.link_speeds`, the fast closing's, from the
   URDF's joint offsets and link extents), at least
   :data:`~kinegrasp_env.closing.close_rules.STEP` for a finger of several revolute degrees
   of freedom; a step that leaves a link deeper than :data:`CONTACT_TOL` is halved until it
   does not. A link *touches* when its gap is within :data:`CONTACT_TOL` (such a finger's
   touch then polished to a zero gap by secant steps:
   :func:`~kinegrasp_env.closing.close_rules.secant_root`: where a phalanx stops moves where
   the next one touches); a finger has *missed* when its joints have all stopped or reached
   their limits and no link touches.
3. *Contacts*: one per touching finger link (distance within :data:`CONTACT_TOL`), in the
   object frame. A link of capsules and spheres: the point model of the paper's fingertips
   (as every engine's rounded part,
   :func:`~kinegrasp_env.closing.hand_geometry.pair_contacts`): the exact closest point on
   the object, the normal its face's where the pair's direction agrees, else the pair's.
   Any other link: pybullet's closest pair of that link and the object, the point on the
   object. The normal into the object: where the point lies on one face of the object's exact
   convex parts (one face plane within :data:`EDGE_TOL`), that face's inward normal (the
   direction of a closest pair touching a face's interior; pybullet's own normal was measured
   4.6 degrees off there), and so at an edge or a corner of the face a face of the link lies
   on (:func:`~kinegrasp_env.closing.pad_faces.flat_face`, on the link's collision
   geometry as the fast closing reads it, placed by the robot model's kinematics); at any
   other edge or corner, the direction of the pair by the fast closing's rule
   (:mod:`~kinegrasp_env.closing.pair_normals`, on that geometry and pybullet's pair; a link
   without it: pybullet's ``-contactNormalOnB``). On a face, the point is moved to the
   centre of the finger's contact patch (:mod:`~kinegrasp_env.closing.contact_patch`: a flat
   pad's closest point is an arbitrary corner of the overlap), and along an edge to the
   middle of the segment the pad presses (:mod:`~kinegrasp_env.closing.edge_contact`);
   ``RobotWorld(patch=False)`` keeps pybullet's point.

The outcome (the engines' codes) follows: start collision, missed (a finger missed, or fewer
than two contacts), else force closure or not by the contacts' quality (scored above this
layer, with the robot's contact model).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_result import RobotCloseResult, RobotContact
from kinegrasp_env.closing.close_rules import (
    CONTACT_TOL,
    QUERY_DISTANCE,
    START_TOL,
    STEP,
    polish_window,
    secant_root,
)
from kinegrasp_env.closing.contact_patch import (
    PatchGeometry,
    face_patch_point,
    link_hull_vertices,
)
from kinegrasp_env.closing.convex_distance import stacked_faces
from kinegrasp_env.closing.edge_contact import place_on_edges
from kinegrasp_env.closing.finger_paths import finger_paths
from kinegrasp_env.closing.hand_geometry import pair_contacts
from kinegrasp_env.closing.hull_edges import point_hull
from kinegrasp_env.closing.link_geometry import robot_link_geometry
from kinegrasp_env.closing.pad_faces import faces_of, flat_face
from kinegrasp_env.closing.pair_normals import LINE_TOL, pair_normals
from kinegrasp_env.closing.scene import RobotScene
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import rigid_inverse
from kinegrasp_env.robot.touch_rule import moved_by, touch_stops
from kinegrasp_env.world.objects import GraspObject, frame_coordinates

#: Closing steps per finger at most (conservative advancement converges in a few for jaws).
MAX_STEPS = 200
#: Halvings of a step that pybullet reports as penetrating, at most.
MAX_HALVINGS = 30
#: A contact point within this of exactly one face plane lies on that face, metres.
EDGE_TOL = 5e-5

__all__ = ["CONTACT_TOL", "EDGE_TOL", "MAX_STEPS", "QUERY_DISTANCE", "START_TOL",
           "RobotCloseResult", "RobotContact", "RobotWorld", "face_of"]


def face_of(obj: GraspObject, point: np.ndarray, vertices: np.ndarray | None = None
            ) -> tuple[int, np.ndarray] | None:
    """(part, its face plane (4,): outward unit normal, offset) of the one face of ``obj``'s
    nearest convex part that the object-frame ``point`` (3,) lies on (within
    :data:`EDGE_TOL`), or None at an edge or a corner (two or more face planes that near) or
    off the surface: :func:`~kinegrasp_env.closing.pad_faces.faces_of`. Given the
    touching link's ``vertices`` (V, 3; object frame): of the faces at that edge or corner,
    the one the link lies flat on (:func:`~kinegrasp_env.closing.pad_faces.flat_face`),
    or None."""
    if vertices is None:
        part, plane = faces_of(obj, point[None], EDGE_TOL)
    else:
        part, plane = flat_face(obj, point[None], vertices[None], EDGE_TOL)
    return None if part[0] < 0 else (int(part[0]), plane[0])


class RobotWorld(RobotScene):
    """The reference closing of a description robot in its pybullet scene
    (:class:`~kinegrasp_env.closing.scene.RobotScene`; the module's model).

    Attributes:
        patch: place a contact on a face at its patch's centre (step 3 of the module).
    """

    def __init__(self, description: RobotDescription, obj: GraspObject,
                 gui: bool = False, patch: bool = True) -> None:
        super().__init__(description, obj, gui)
        self.patch = patch
        self._touch_rules = [(touch_stops(self.model, finger), moved_by(finger))
                             for finger in description.fingers]
        #: per finger, its links' speed bounds, those the fast closing steps by
        #: (:meth:`~kinegrasp_env.closing.finger_paths.FingerPath.speed_bounds`)
        #: each link's collision geometry, as the fast closing reads it (a pad's flat test)
        self.geometry = robot_link_geometry(description)
        self._object_edges = stacked_faces(obj.convex_parts)[2]
        self._patch = PatchGeometry(obj.parts)
        self._paths = finger_paths(description, self.geometry, self._tree)

    # ------------------------------------------------------------------ closing
    def auto_close(self, q: np.ndarray, *, contact_tol: float = CONTACT_TOL,
                   start_tol: float = START_TOL, palm: np.ndarray | None = None,
                   object_offset: np.ndarray | None = None) -> RobotCloseResult:
        """Close the hand of configuration q (dof,) on the object (the module's model);
        ``palm``, ``object_offset``: the draw's palm and object errors (4, 4)
        (:mod:`~kinegrasp_env.closing.hand_errors`), the contacts then in the true object's
        frame.

        The world is left at the final state (every finger where it stopped).
        """
        start = self.set_configuration(q)
        try:
            return self._close_placed(start, contact_tol, start_tol, palm, object_offset)
        finally:
            self.sync()  # the world shows the closed hand

    def _close_placed(self, start: dict[str, float], contact_tol: float, start_tol: float,
                      palm: np.ndarray | None, object_offset: np.ndarray | None
                      ) -> RobotCloseResult:
        """:meth:`auto_close` from the configuration set (joint values ``start``)."""
        if palm is None and object_offset is None:
            return self._close(start, contact_tol, start_tol)
        believed = self.obj.pose
        true = believed if object_offset is None else believed @ object_offset
        # the arm sees the object where it truly is; the hand, kept at its kinematic pose,
        # sees it moved by the inverse of its own error (the same relative pose)
        flange = self.link_pose(self._flange)
        seen = true if palm is None else flange @ rigid_inverse(palm) @ rigid_inverse(
            flange) @ true
        try:
            self.place_object(true)
            arm = self._arm_links
            if self.penetrates([row for link in arm for row in self.closest(0.0, link)],
                               start_tol) or self.in_table(arm):
                return self._collided(len(arm))
            self.place_object(seen)
            return self._close(start, contact_tol, start_tol, links=self._hand_links,
                               queries=len(arm))
        finally:
            self.place_object(believed)

    def _collided(self, queries: int) -> RobotCloseResult:
        """A closing that starts in collision."""
        return RobotCloseResult.collided(len(self.description.fingers), queries)

    def _close(self, start: dict[str, float], contact_tol: float, start_tol: float,
               links: list[str] | None = None, queries: int = 0) -> RobotCloseResult:
        """:meth:`auto_close` from the configuration set (joint values ``start``), the object
        where it stands: the start collision of ``links`` (default: the whole robot, one
        query), then the fingers closed."""
        if links is None:
            queries += 1
            rows = self.closest(0.0)
        else:
            queries += len(links)
            rows = [row for link in links for row in self.closest(0.0, link)]
        if self.penetrates(rows, start_tol) or self.in_table(links):
            return self._collided(queries)
        missed, gaps, travel, final = [], [], [], {}
        contacts: list[RobotContact] = []
        for f in range(len(self.description.fingers)):
            t, g, values, n = self._close_finger(f, start, contact_tol)
            queries += n
            missed.append(bool(g > contact_tol))
            gaps.append(g)
            travel.append(t)
            final.update(values)
            if g <= contact_tol:
                contacts += self._contacts(f, contact_tol)
        return RobotCloseResult(False, contacts, tuple(missed), np.array(gaps),
                                np.array(travel), final, queries)

    def _close_finger(self, f: int, start: dict[str, float], contact_tol: float
                      ) -> tuple[float, float, dict[str, float], int]:
        """Close finger f from the joint values ``start`` (step 2 of the module): (t, the
        finger's gap (its links' least; within the contact tolerance where one touched),
        its closing joints' final values, pybullet queries). Joint j moves with t until a
        link that stops it touches (:func:`~kinegrasp_env.robot.touch_rule.touch_stops`)."""
        finger = self.description.fingers[f]
        joints = finger.joints
        path = self._paths[f]  # its closing joints' rates and limits (closing_joints)
        rates, lo, hi = path.rates, path.lower, path.upper
        v0 = np.array([start[name] for name in joints])
        stops, moves = self._touch_rules[f]
        staged = not path.translating and not stops.all()
        least = STEP if staged else 0.0  # as in closing.finger_closing
        starts, ends = path.limit_times(v0)
        held = np.full(len(joints), np.inf)  # the t at which each joint stopped
        touched = np.zeros(len(finger.links), dtype=bool)

        def put(t: float) -> dict:
            values = dict(zip(joints, np.clip(v0 + rates * np.minimum(t, held), lo, hi)
                              .tolist(), strict=True))
            self.stage_joint_values(values)
            return values

        def moving() -> tuple[str, ...]:
            return tuple(link for k, link in enumerate(finger.links)
                         if not touched[k] and np.isinf(held[moves[k]]).any())

        t, queries, g = 0.0, 0, None
        values = put(t)
        for _ in range(MAX_STEPS):
            links = moving()
            t_end = float(np.max(ends, initial=0.0, where=np.isinf(held)))
            if not links or t >= t_end:
                break
            if g is None:  # the moving links' gap, unless the last step measured it
                g, n = self.gap(links)
                queries += n
            if g <= contact_tol and not staged:  # one degree of freedom: the finger stops
                break
            if g <= contact_tol:  # the links that touch stop their joints
                touching = tuple(link for link in links if self.gap((link,))[0] <= contact_tol)
                queries += len(links)

                def gap_at(s: float, links=touching) -> float:
                    put(s)
                    return self.gap(links)[0]

                # polished to a zero gap of the touching links
                t = float(secant_root(gap_at, t, g, *polish_window(t, t_end)))
                values = put(t)
                queries += len(touching)
                for k, link in enumerate(finger.links):
                    if link in touching and self.gap((link,))[0] <= contact_tol:
                        touched[k] = True
                        held[stops[k]] = np.minimum(held[stops[k]], t)
                g = None
                continue
            # each moving link's gap over its speed bound by the joints still turning, up
            # to a joint's limit
            turning, room = path.turning(held, t, starts, ends)
            speeds = path.speed_bounds(turning)
            travel = min(min((self.link_gap(link) / max(float(speeds[k]), 1e-9)
                              for k, link in enumerate(path.links) if link in links),
                             default=t_end - t), float(room))
            step = min(max(travel, least), t_end - t)
            for _ in range(MAX_HALVINGS):
                values = put(t + step)
                g, n = self.gap(links)
                queries += n
                if g >= -contact_tol:
                    break
                step *= 0.5
            t += step
        if staged or g is None:  # the whole finger's gap where it stopped
            values = put(t)
            g, n = self.gap(finger.links)
            queries += n
        return t, g, values, queries

    def _patch_point(self, link: str, face: tuple[int, np.ndarray],
                     point: np.ndarray) -> np.ndarray:
        """The centre of ``link``'s patch on the face (:mod:`~kinegrasp_env.closing.
        contact_patch`), or ``point`` where there is none."""
        self.sync()
        vertices = link_hull_vertices(self.bullet, self.bodies["robot"], self.link_index[link])
        if vertices is None:
            return point
        return face_patch_point(self._patch, frame_coordinates(self.placed, vertices), face,
                                point)

    def _contacts(self, f: int, contact_tol: float) -> list[RobotContact]:
        """The touching links of finger f at the current state, one contact each."""
        out = []
        rot = self.placed[:3, :3]
        for k, link in enumerate(self.description.fingers[f].links):
            if link in self.rounded:
                found = self._rounded_contact(f, k, link, contact_tol)
                out += [] if found is None else [found]
                continue
            rows = [r for r in self.closest(contact_tol, link)
                    if self.distance(r) <= contact_tol]
            if not rows:
                continue
            row = min(rows, key=self.distance)
            # pybullet's object point lies up to the object's collision margin off its
            # surface (mesh shapes): the exact surface point decides the face
            point = self.obj.closest_points(
                frame_coordinates(self.placed, np.array(row[6]))[None])[0][0]
            face = face_of(self.obj, point)
            if face is None and link in self.geometry:  # at an edge: the face a pad lies on
                pose = self._placed_inverse @ self.model_pose(link)
                face = face_of(self.obj, point, self.geometry[link].placed_vertices(pose))
            if face is None and link in self.geometry and self.geometry[link].faces:
                point, normal = self._edge_contact(link, row, point)
            elif face is None:
                normal = -np.array(row[7]) @ rot
            else:
                normal = -face[1][:3]
                if self.patch:
                    point = self._patch_point(link, face, point)
            out.append(RobotContact(f, k, point, normal / np.linalg.norm(normal),
                                    self.distance(row)))
        return out


    def _edge_contact(self, link: str, row: tuple, point: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """(point (3,), normal (3,)) of flat ``link``'s contact at an edge or a corner of
        the object, ``point`` (3,) the exact surface point of pybullet's closest pair ``row``
        (object frame): the pair's direction by the fast closing's rule
        (:mod:`~kinegrasp_env.closing.pair_normals`; pybullet's own normal there is that of
        two points a round-off apart where a pad lies along an edge), the point moved to the
        middle of the segment a pad along the edge presses
        (:mod:`~kinegrasp_env.closing.edge_contact`). The pair's link point is pybullet's
        where it lies on the link's hulls (a box's face: pybullet's box keeps its faces),
        else (a mesh's hull, which pybullet pads by its collision margin: its point lies
        that far off) the hulls' exact closest point to ``point``
        (:func:`~kinegrasp_env.closing.hull_edges.point_hull`)."""
        pose = self._placed_inverse @ self.model_pose(link)
        planes, _, edges, starts = self.geometry[link].faces
        link_point, gap = frame_coordinates(self.placed, np.array(row[5])), self.distance(row)
        on_hull, _ = self._hull_point(link, pose, link_point)
        if abs(on_hull) > LINE_TOL:  # pybullet's point is off the link's hulls
            gap, link_point = self._hull_point(link, pose, point)
        found = np.empty((1, 3))
        pair_normals(planes, edges, starts, self._object_edges,
                     np.ascontiguousarray(pose[None, :3, :3]),
                     np.ascontiguousarray(pose[None, :3, 3]), link_point[None], point[None],
                     np.array([gap]), EDGE_TOL, LINE_TOL, np.empty((2, 3)), found)
        normal = found[0]
        if np.linalg.norm(normal) < 1e-12:
            normal = self.obj.surface(point[None])[1][0]
        normal = normal / np.linalg.norm(normal)
        if self.patch:
            placed, _ = place_on_edges(self.geometry[link].vertices, pose[None],
                                       self._object_edges, normal[None], point[None])
            point = placed[0]
        return point, normal

    def _hull_point(self, link: str, pose: np.ndarray, point: np.ndarray
                    ) -> tuple[float, np.ndarray]:
        """(signed distance, (3,) closest point) from the object-frame ``point`` (3,) to
        ``link``'s hulls posed at ``pose`` (4, 4; object frame): exact
        (:func:`~kinegrasp_env.closing.hull_edges.point_hull`), the nearest hull's."""
        planes, plane_starts, edges, starts = self.geometry[link].faces
        local = (point - pose[:3, 3]) @ pose[:3, :3]
        gap, near = np.inf, local
        for p in range(len(plane_starts) - 1):
            d, *closest = point_hull(planes[plane_starts[p]:plane_starts[p + 1]],
                                     edges[starts[p]:starts[p + 1]], EDGE_TOL, *local, np.inf)
            if d < gap:
                gap, near = d, np.array(closest)
        return gap, pose[:3, :3] @ near + pose[:3, 3]

    def _rounded_contact(self, f: int, k: int, link: str, contact_tol: float
                         ) -> RobotContact | None:
        """The point model's contact of link k (of rounded parts) of finger f, where it
        touches (step 3 of the module), else None."""
        if self.link_gap(link) > contact_tol:
            return None
        gap, on_core, on_obj, part = self.rounded_pair(link)
        points, normals = pair_contacts(self.obj, on_obj[None], on_core[None],
                                        np.array([np.linalg.norm(on_core - on_obj)]),
                                        np.array([part]))
        return RobotContact(f, k, points[0], normals[0], gap)
