"""Fingers of two capsule phalanxes closed by one compiled loop: the kernel of
:mod:`~kinegrasp_env.closing.close_kernel` (the distance grid far from the object, the exact
capsule-object pair within :data:`GRID_EXACT_BAND` of contact,
bisection, the touch polished to a zero gap) for any description robot's finger of that
kind, inside the batched closing of :class:`~kinegrasp_env.closing.generic_fast.FastRobotHand`.

A finger qualifies (:func:`capsule_finger`) when it is what the kernel models:

* two revolute closing joints, each closing at unit rate (a joint that closes as its value
  decreases is mirrored: its axis and value negated, the same rotation), the second joint's
  parent link the first one's child;
* its links with collision geometry exactly those two children, each a single capsule (or
  sphere);
* the generic touch rule reduced to the kernel's: a touch of the proximal phalanx stops the
  proximal joint, a touch of the distal one both (:attr:`FingerPath.stops`).

Its speed bounds (:class:`~kinegrasp_env.closing.close_rules.LinkSpeeds`) are the finger
path's (:func:`~kinegrasp_env.closing.finger_paths.link_speeds`): each phalanx's by both
joints turning, and the distal one's by its own joint alone. The generic loop
(:mod:`~kinegrasp_env.closing.finger_closing`) closes every other finger.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.close_kernel import (
    PAIR_SIZE,
    close_all,
    closing_rules,
    geometry_args,
    grid_args,
)
from kinegrasp_env.closing.close_rules import LinkSpeeds
from kinegrasp_env.closing.finger_paths import FingerPath, tree_poses
from kinegrasp_env.closing.link_geometry import LinkGeometry
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sdf import DistanceGrid

__all__ = ["GRID_EXACT_BAND", "CapsuleFinger", "CapsuleFingers", "capsule_finger"]

#: Capsule gaps within +-this (metres) are computed exactly: above the grid's largest
#: measured error (0.35 mm), so every decision near contact is the exact one.
GRID_EXACT_BAND = 1e-3


@dataclass(frozen=True)
class CapsuleFinger:
    """A finger the compiled capsule closing takes (:func:`capsule_finger`).

    Attributes:
        index: the finger's index among the description's fingers.
        path: its :class:`~kinegrasp_env.closing.finger_paths.FingerPath`.
        parent: the link the proximal joint hangs from.
        origin: (4, 4) the proximal joint's origin in ``parent``'s frame.
        axis_p, axis_d: (3,) the joints' axes (joint frames), negated for a mirrored joint.
        sign: (2,) +1 or -1: the kernel's flexion is ``sign`` times the joint value.
        distal_origin: (4, 4) the distal joint's origin in the proximal link's frame.
        ends_p, ends_d: (2, 3) the capsules' axis ends (link frames, metres).
        radius: (2,) the capsules' radii (metres).
        upper: (2,) the flexions' upper limits (radians).
        speeds: (3,) bounds (metres per radian): the proximal and distal phalanx while both
            joints close, the distal one alone.
    """

    index: int
    path: FingerPath
    parent: str
    origin: np.ndarray
    axis_p: np.ndarray
    axis_d: np.ndarray
    sign: np.ndarray
    distal_origin: np.ndarray
    ends_p: np.ndarray
    ends_d: np.ndarray
    radius: np.ndarray
    upper: np.ndarray
    speeds: np.ndarray


def capsule_finger(index: int, path: FingerPath, geometry: dict[str, LinkGeometry]
                   ) -> CapsuleFinger | None:
    """The finger ``path`` (the ``index``-th) as the compiled capsule closing takes it, or
    None where it is not of that kind (module docstring)."""
    if len(path.joints) != 2 or path.translating or len(path.links) != 2:
        return None
    if not np.array_equal(np.abs(path.rates), [1.0, 1.0]):
        return None
    prox_link, dist_link = path.links
    chain_p, chain_d = path.chains[prox_link], path.chains[dist_link]
    if (len(chain_d) != len(chain_p) + 1 or [j.name for j in chain_d[:-1]]
            != [j.name for j in chain_p] or chain_p[-1].name != path.joints[0]
            or chain_d[-1].name != path.joints[1]
            or any(j.kind not in ("revolute", "continuous") for j in chain_d[-2:])):
        return None
    if (path.stops.tolist() != [[True, False], [True, True]]
            or path.moves.tolist() != [[True, False], [True, True]]):
        return None
    parts = []
    for link in path.links:
        geom = geometry[link]
        if geom.parts or len(geom.rounded) != 1:
            return None
        parts.append(geom.rounded[0])
    joint_p, joint_d = chain_p[-1], chain_d[-1]
    sign = np.sign(path.rates)
    upper = np.where(sign > 0, path.upper, -path.lower)
    ends_p = np.array([parts[0].a, parts[0].b], dtype=float)
    ends_d = np.array([parts[1].a, parts[1].b], dtype=float)
    radius = np.array([parts[0].radius, parts[1].radius])
    # the path's bounds by the joints turning: both (phase 1), the distal one alone
    (prox_p, _), (dist_p, dist_d) = path.speeds
    return CapsuleFinger(index, path, joint_p.parent, np.asarray(joint_p.origin, dtype=float),
                         sign[0] * np.asarray(joint_p.axis, dtype=float),
                         sign[1] * np.asarray(joint_d.axis, dtype=float), sign,
                         np.asarray(joint_d.origin, dtype=float), ends_p, ends_d, radius,
                         np.asarray(upper, dtype=float),
                         np.array(LinkSpeeds(prox_p, dist_p + dist_d, dist_d)))


class CapsuleFingers:
    """The compiled closing of a hand's capsule fingers on one object.

    Args:
        fingers: the qualifying fingers (:func:`capsule_finger`).
        obj: the object; grid: its distance grid.
        palm_link: the description's palm link.
    """

    def __init__(self, fingers: list[CapsuleFinger], obj: GraspObject, grid: DistanceGrid,
                 palm_link: str) -> None:
        self.fingers, self.palm_link = fingers, palm_link
        self._head = (grid_args(grid, GRID_EXACT_BAND), geometry_args(obj), closing_rules())
        self._constants = tuple(
            np.ascontiguousarray(np.array([getattr(f, name) for f in fingers], dtype=float))
            for name in ("axis_p", "axis_d", "distal_origin", "ends_p", "ends_d", "radius",
                         "upper", "speeds"))

    def close(self, palm: np.ndarray, values0: dict[str, np.ndarray]) -> dict:
        """Close every qualifying finger of m draws: the palm at object-frame poses
        (m, 4, 4), the joints at ``values0`` (name -> (m,)).

        Returns:
            per finger index: (final values of its two joints (m, 2), gap (m,): its
            touching links' least, inf where none touches, travel (m,): the closing
            parameter where it stopped, per link (distance (m,), core point (m, 3), object
            point (m, 3), the object's convex part (m,)) of its touching links, distance inf
            and part -1 elsewhere).
        """
        m, count = palm.shape[0], len(self.fingers)
        frames = np.empty((m, count, 4, 4))
        start = np.empty((m, count, 2))
        for k, finger in enumerate(self.fingers):
            if finger.parent == self.palm_link:
                parent = palm
            else:
                parent = tree_poses(finger.path.tree, palm, values0, (finger.parent,))[
                    finger.parent]
            frames[:, k] = parent @ finger.origin
            start[:, k] = np.stack([finger.sign[j] * values0[finger.path.joints[j]]
                                    for j in range(2)], axis=1)
        found = np.zeros((m, count, 2), dtype=bool)
        pairs = np.zeros((m, count, 2, PAIR_SIZE))
        missed = np.zeros((m, count), dtype=bool)
        flexion = np.zeros((m, count, 2))
        close_all(*self._head, np.ascontiguousarray(frames),
                  np.ascontiguousarray(start[..., 0]), np.ascontiguousarray(start[..., 1]),
                  *self._constants, found, pairs, missed, flexion)
        out = {}
        for k, finger in enumerate(self.fingers):
            distance = np.where(found[:, k], pairs[:, k, :, 0] - finger.radius, np.inf)
            part = np.where(found[:, k], pairs[:, k, :, 7], -1).astype(np.int64)
            links = {link: (distance[:, j], pairs[:, k, j, 4:7], pairs[:, k, j, 1:4],
                            part[:, j])
                     for j, link in enumerate(finger.path.links)}
            moved = np.abs(flexion[:, k] - np.minimum(start[:, k], finger.upper))
            out[finger.index] = (flexion[:, k] * finger.sign, distance.min(axis=1),
                                 moved.max(axis=1), links)
        return out
