"""The patch contact model: a flat pad pressing on a face is scored as its whole patch.

A closing gives one contact per touching finger link: on a face of the object, the centre of
the pad's patch (:mod:`~kinegrasp_env.closing.contact_patch`). A pad presses over the whole
patch, and the pressure can move anywhere in it, so the forces it can apply are those of a
point contact with friction at any point of the patch: the cones at the patch's corners span
them (a force at an inner point is a convex combination of the same force at the corners, and
so is its torque). The patch model scores each such contact as up to
:data:`~kinegrasp_env.closing.contact_patch.PATCH_CORNERS` point contacts at the patch's
corners, each with the face's normal. A flat pad's contact off a face (on an edge or a
corner, or on a curved surface it touches along a line or at a point) stays the one point it
is, scored as a soft contact (:mod:`~kinegrasp_env.quality.soft_contacts`: the torsion a
small patch about it carries), as the ``soft`` model scores every contact; a contact of a
rounded fingertip (or of a link whose collision shape is not a mesh or a box) stays a point
contact, as the paper scores one. Two pads pinching a thin wall at centres that do not face
each other are then still in force closure where their patches overlap across the wall, and
two pads on a cylinder keep the torsion that holds it about the line between them.

The patch is recomputed from what every engine keeps of a closing (the configuration, the
closing joints' final values and the contacts): the finger link's pose from the palm, the
face the contact lies on, and the link's hull clipped to that face, so all engines score
alike.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.contact_patch import PATCH_CORNERS, PatchGeometry
from kinegrasp_env.closing.finger_paths import link_poses
from kinegrasp_env.closing.generic_reference import EDGE_TOL
from kinegrasp_env.closing.link_geometry import link_geometry
from kinegrasp_env.closing.pad_faces import faces_of
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.world.objects import GraspObject


class PatchContacts:
    """Contacts of a robot's closings on an object, expanded to their patches' corners.

    Args:
        description: the robot; obj: the catalog object.
    """

    def __init__(self, description: RobotDescription, obj: GraspObject) -> None:
        self.description, self.obj = description, obj
        self.kinematics = Kinematics(description.model)
        # a curved finger link (a capsule or cylinder tip) keeps its contacts as points
        self.geometry = {name: geometry for name, geometry in
                         link_geometry(description, tuple(description.finger_links)).items()
                         if not geometry.curved}
        self.patch = PatchGeometry(obj.parts)
        palm = len(self.kinematics.chain(description.palm_link))
        #: (finger, link index) -> (link name, joint chain from the palm)
        self.links = {(f, k): (link, self.kinematics.chain(link)[palm:])
                      for f, finger in enumerate(description.fingers)
                      for k, link in enumerate(finger.links)}

    def expand(self, q: np.ndarray, values: dict[str, np.ndarray], points: np.ndarray,
               normals: np.ndarray, finger: np.ndarray, link: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Each contact as C = PATCH_CORNERS contacts.

        Args:
            q: (B, dof) the draws' configurations; values: closing joint name -> (B,) final
                values (others from q).
            points, normals: (B, k, 3) contacts (object frame; NaN where absent).
            finger, link: (B, k) their finger and link index (-1 where absent).

        Returns:
            (points (B, k C, 3), normals (B, k C, 3), finger (B, k C), link (B, k C), soft
            (B, k C) bool): contact j's slots j C .. j C + C - 1 hold its patch's corners,
            padded with its centre (a point of the patch: the same set of forces), each a
            point contact (the corners carry the patch's torsion); a flat pad's contact off a
            face fills its slots with itself, ``soft`` (a soft contact); a rounded fingertip's
            fills them with itself, a point contact; absent contacts stay absent.
        """
        c = PATCH_CORNERS
        out_p = np.repeat(points, c, axis=1)
        out_n = np.repeat(normals, c, axis=1)
        out_f, out_l = np.repeat(finger, c, axis=1), np.repeat(link, c, axis=1)
        soft = np.zeros(out_f.shape, dtype=bool)
        present = finger >= 0
        if not present.any():
            return out_p, out_n, out_f, out_l, soft
        palm = self.obj.pose_inverse @ self.kinematics.pose(q, self.description.palm_link)
        full = self.description.model.expand(q)
        full.update({name: np.asarray(v, dtype=float) for name, v in values.items()})
        for (f, k), (name, chain) in self.links.items():
            rows, slots = np.nonzero(present & (finger == f) & (link == k))
            if rows.size == 0 or name not in self.geometry:
                continue
            soft[rows[:, None], slots[:, None] * c + np.arange(c)] = True  # until on a face
            poses = link_poses(palm[rows], {n: v[rows] for n, v in full.items()}, chain)
            part, plane = faces_of(self.obj, points[rows, slots], EDGE_TOL)
            on = part >= 0
            if not on.any():
                continue
            _, _, corners, counts = self.patch.patches(
                self.geometry[name].vertices, poses[on], part[on], plane[on],
                points[rows[on], slots[on]], c)
            for i, (r, s, n) in enumerate(zip(rows[on], slots[on], counts, strict=True)):
                if n > 0:
                    out_p[r, s * c:s * c + n] = corners[i, :n]
                    soft[r, s * c:s * c + c] = False
        return out_p, out_n, out_f, out_l, soft


def distinct_slots(points: np.ndarray, soft: np.ndarray, centres: np.ndarray) -> np.ndarray:
    """(B, k C) bool: the slots of :meth:`PatchContacts.expand`'s contacts that score them
    without repeats: a soft contact's first slot (its C slots are copies of it), a patch's
    corners and the first of the slots that pad it with its centre (the centre once: an
    engine's contact point need not lie inside its corners' polygon). Q and force closure
    of the kept slots are those of all of them (the same set of points, each once); repeated
    contacts only slow the quality's certified expansion down.

    Args:
        points: (B, k C, 3) the expanded contacts; soft: (B, k C) their soft slots;
        centres: (B, k, 3) the contacts as closed (the padding), NaN where absent.
    """
    c = PATCH_CORNERS
    batch, slots = soft.shape
    padding = np.all(points == np.repeat(centres, c, axis=1), axis=2).reshape(batch, -1, c)
    first_padding = padding & (np.cumsum(padding, axis=2) == 1)
    first = (np.arange(slots) % c == 0)[None, :]
    keep = np.where(soft, first, (~padding | first_padding).reshape(batch, slots))
    present = ~np.isnan(np.repeat(centres[..., 0], c, axis=1))
    return keep & present
