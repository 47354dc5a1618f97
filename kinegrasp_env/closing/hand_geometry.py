"""The default robot's hand primitives (for its pybullet reference) and the point model's
contact of a rounded finger part (every engine's).

A finger link is a capsule: the points within ``radius`` of its axis segment. When a link
touches the object (its gap within the contact tolerance), the contact is the exact closest
pair between the axis segment and the object's convex parts
(:func:`~kinegrasp_env.closing.segment_distance.closest_to_segments`): the point on the object,
and as normal the direction from it to the axis (inward: towards the object), which on a
face interior is the face normal and at an edge or corner lies in the cone of the adjacent
faces (:func:`surface_contact`: the reference's :func:`pair_contacts` and the fast closing's
rounded parts use it, so they differ only in where the fingers stop).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from kinegrasp_env.assets import asset_path
from kinegrasp_env.robot.model import rpy_to_matrix
from kinegrasp_env.world.objects import GraspObject


@dataclass(frozen=True)
class Shape:
    """A collision primitive of a hand link, in the link frame.

    Attributes:
        link: link name.
        kind: ``capsule`` or ``cylinder``.
        radius, length: metres (capsule: length between the sphere centres).
        frame: (4, 4) shape frame in the link frame (axis = its z).
    """

    link: str
    kind: str
    radius: float
    length: float
    frame: np.ndarray

    def axis_points(self) -> tuple[np.ndarray, np.ndarray]:
        """(3,) end points of the axis in the link frame."""
        half = 0.5 * self.length * self.frame[:3, 2]
        return self.frame[:3, 3] - half, self.frame[:3, 3] + half

    def surface_samples(self, spacing: float) -> np.ndarray:
        """(P, 3) points covering a cylinder's surface (link frame), about ``spacing`` apart."""
        n_theta = max(8, int(np.ceil(2 * np.pi * self.radius / spacing)))
        n_z = max(2, int(np.ceil(self.length / spacing)) + 1)
        theta = 2 * np.pi * np.arange(n_theta) / n_theta
        z = np.linspace(-0.5 * self.length, 0.5 * self.length, n_z)
        side = np.stack([np.repeat(self.radius * np.cos(theta)[None], n_z, 0),
                         np.repeat(self.radius * np.sin(theta)[None], n_z, 0),
                         np.repeat(z[:, None], n_theta, 1)], axis=-1).reshape(-1, 3)
        caps = [side]
        n_ring = max(1, int(np.ceil(self.radius / spacing)))
        for ring in range(n_ring):
            rad = self.radius * ring / n_ring
            count = max(1, int(np.ceil(2 * np.pi * rad / spacing)))
            ang = 2 * np.pi * np.arange(count) / count
            for zc in (-0.5 * self.length, 0.5 * self.length):
                caps.append(np.stack([rad * np.cos(ang), rad * np.sin(ang),
                                      np.full(count, zc)], axis=-1))
        local = np.concatenate(caps)
        return local @ self.frame[:3, :3].T + self.frame[:3, 3]


@lru_cache(maxsize=1)
def hand_shapes() -> tuple[Shape, ...]:
    """The hand's collision primitives, read from ``sdh_hand.urdf``."""
    root = ET.parse(asset_path("robots", "sdh_hand.urdf")).getroot()
    shapes = []
    for link in root.findall("link"):
        for collision in link.findall("collision"):
            origin = collision.find("origin")
            frame = np.eye(4)
            if origin is not None:
                frame[:3, :3] = rpy_to_matrix(*map(float, origin.get("rpy", "0 0 0").split()))
                frame[:3, 3] = [float(v) for v in origin.get("xyz", "0 0 0").split()]
            geometry = collision.find("geometry")
            for kind in ("capsule", "cylinder"):
                element = geometry.find(kind)
                if element is not None:
                    shapes.append(Shape(link.get("name"), kind, float(element.get("radius")),
                                        float(element.get("length")), frame))
            if not any(geometry.find(k) is not None for k in ("capsule", "cylinder")):
                raise ValueError(f"unsupported collision geometry on hand link {link.get('name')}")
    return tuple(shapes)


def surface_contact(obj: GraspObject, points: np.ndarray, outward: np.ndarray,
                    part: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Contact points and inward normals (m, 3) from closest points on the object.

    Args:
        obj: the object.
        points: (m, 3) closest points on the object (object frame).
        outward: (m, 3) unit separating directions, object towards finger.
        part: (m,) part each point lies on (default: the nearest by plane distance).

    The point is projected on the face it lies on; the normal is that face's inward normal
    where the separating direction agrees with it (to 1e-6), else the separating direction
    (an edge or corner: it lies in the cone of the adjacent faces).
    """
    projected, face_normal = obj.surface(points, part)
    cosine = -(face_normal[:, 0] * outward[:, 0] + face_normal[:, 1] * outward[:, 1]
               + face_normal[:, 2] * outward[:, 2])
    agree = cosine > 1 - 1e-6
    return projected, np.where(agree[:, None], face_normal, -outward)


def pair_contacts(obj: GraspObject, on_obj: np.ndarray, on_seg: np.ndarray, dist: np.ndarray,
                  part: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Contacts (points, inward normals (m, 3)) from exact closest pairs (m, 3) of capsule
    axes and the object, their distances (m,) and the parts (m,) they touch."""
    outward = (on_seg - on_obj) / np.maximum(dist, 1e-300)[:, None]
    return surface_contact(obj, on_obj, outward, part)
