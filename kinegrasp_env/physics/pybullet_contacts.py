"""Reading a hand's contacts from pybullet's contact records: each finger's normal force,
the finger links that touch, and one contact per touching link.

A contact record is pybullet's ``getContactPoints`` tuple: its link on the hand (index 3),
position on the object (6), normal from the object to the finger (7), distance (8) and normal
force (9) (MuJoCo's records are written in the same layout:
:meth:`~kinegrasp_env.physics.mujoco_world.MujocoWorld.contact_records`). A link touching on
a line or a patch has several records;
:func:`merge_records` makes them one contact, as the kinematic closing has one contact per
link: the deepest record (the kinematic closing's closest pair) gives the face, and the
records on that face are averaged. Normals point into the object (minus pybullet's
``contactNormalOnB``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from kinegrasp_env.physics.pybullet_world import PhysicsWorld

#: Contact records of one link whose normals are within this angle of the deepest record's
#: are merged into one contact (the same face), radians.
MERGE_ANGLE = np.radians(10.0)


def finger_forces(world: PhysicsWorld, links: dict[int, tuple[int, int]], fingers: int
                  ) -> np.ndarray:
    """(fingers,) each finger's total normal force on the object from the last step, newtons
    (the sum of pybullet's ``normalForce`` over the contact records of its links; ``links``:
    pybullet link index -> (finger, link), as :func:`~kinegrasp_env.physics.jaw_motors.
    finger_link_indices` gives them)."""
    forces = np.zeros(fingers)
    for rec in world.contact_points():
        if rec[3] in links:
            forces[links[rec[3]][0]] += rec[9]
    return forces


def touching_links(world: PhysicsWorld, links: dict[int, tuple[int, int]],
                   distance: float) -> set[tuple[int, int]]:
    """(finger, link) of the finger links with a contact record within ``distance`` (m)."""
    return {links[rec[3]] for rec in world.contact_points()
            if rec[3] in links and rec[8] <= distance}


def merge_records(records: list[tuple], max_angle: float = MERGE_ANGLE
                  ) -> tuple[np.ndarray, np.ndarray]:
    """One contact from a link's pybullet contact records (world frame): (point (3,), inward
    unit normal (3,)).

    The deepest record (smallest ``contactDistance``: pybullet's closest pair, the contact
    the kinematic closing takes) gives the face; the records whose normals are within
    ``max_angle`` (radians) of its normal (the same face: a line or patch contact) are
    averaged, weighted by their normal forces (plain average when every force is zero).
    """
    deepest = min(records, key=lambda rec: rec[8])
    face = np.asarray(deepest[7])
    same = [rec for rec in records
            if rec is deepest or np.dot(rec[7], face) >= np.cos(max_angle)]
    force = np.array([rec[9] for rec in same])
    weight = force / force.sum() if force.sum() > 0 else np.full(len(same), 1.0 / len(same))
    point = weight @ np.array([rec[6] for rec in same])
    normal = -(weight @ np.array([rec[7] for rec in same]))
    return point, normal / np.linalg.norm(normal)
