"""GraspIt-style kinematic auto-close of the three-finger hand, and contact extraction.

From the pre-grasp hand configuration the proximal and distal flexion joints of every finger
close together at the same rate (each stops at its own upper limit). When a link touches the
object, the joints proximal to it stop and the joints distal to it keep closing: a proximal
contact freezes the proximal joint while the distal joint goes on; a distal contact ends the
finger. Each contact is located by stepping (conservative advancement: a step never exceeds
the one that could close the current gap, but is at least ``STEP`` radians) and then bisection
until the gap is within ``CONTACT_TOL`` (0.2 mm). A finger whose joints all reach their
limits without touching has missed. The coupled spread keeps its pre-shape value.

Contacts are reported in the object frame: the point on the touched convex part (the
object's surface) and that face's inward normal; at an edge or corner of a part, where the
face normal is not unique, pybullet's separating direction for our fixed body order (finger
A, object B), which lies in the cone of the adjacent face normals.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from kinegrasp_env.robots import FINGERS, HAND_JOINTS, kuka_sdh
from kinegrasp_env.sim import GraspWorld

#: Largest gap (or penetration) at which a link counts as touching, metres.
CONTACT_TOL = 2e-4
#: Smallest closing step, radians (bisection takes over after an overshoot).
STEP = 0.02
#: Gaps beyond this are not computed exactly (the step is then bounded by it), metres.
QUERY_DISTANCE = 0.05
#: Penetration below which the pre-grasp pose counts as a start collision, metres.
START_TOL = CONTACT_TOL
#: Radius of the finger capsules plus margin, for the speed bound (metres).
_RADIUS_BOUND = 0.02
MAX_ITERATIONS = 400


@dataclass(frozen=True)
class Contact:
    """One finger-object contact (object frame).

    Attributes:
        finger: 0, 1, 2 (fingers f1, f2, f3).
        link: 0 proximal, 1 distal.
        point: (3,) on the object's surface, metres.
        normal: (3,) inward unit surface normal.
    """

    finger: int
    link: int
    point: np.ndarray
    normal: np.ndarray


@dataclass
class CloseResult:
    """Outcome of one auto-close.

    Attributes:
        start_collision: the hand penetrated the object before closing.
        contacts: contacts found (at most one per link).
        missed: per finger, True if it closed to its limits without touching.
        joints: final hand DOF (7,) in ``HAND_JOINTS`` order.
        iterations: collision queries used.
    """

    start_collision: bool
    contacts: list[Contact] = field(default_factory=list)
    missed: tuple[bool, bool, bool] = (False, False, False)
    joints: np.ndarray | None = None
    iterations: int = 0


def hand_joint_values(preshape: np.ndarray) -> dict[str, float]:
    """Every hand joint's value (coupled spread expanded) from the 7 hand DOF."""
    model = kuka_sdh()
    q = np.zeros(model.dof)
    q[model.index(HAND_JOINTS)] = preshape
    values = model.expand(q)
    return {name: float(values[name]) for name in values if not name.startswith("lbr_")}


@lru_cache(maxsize=1)
def _finger_geometry() -> tuple[float, float, float, float]:
    """(proximal length, distal length, upper limit proximal, upper limit distal)."""
    model = kuka_sdh()
    distal = model.joint("f1_distal").origin[:3, 3]
    tip = model.joint("f1_distal_to_tip").origin[:3, 3]
    return (float(np.linalg.norm(distal)), float(np.linalg.norm(tip)),
            model.joint("f1_proximal").upper, model.joint("f1_distal").upper)


class _Finger:
    """Closing state of one finger: a 1-D path per phase, bisection bracket [t_lo, t_hi]."""

    def __init__(self, index: int, prox: float, dist: float, geometry) -> None:
        length_p, length_d, self.upper_p, self.upper_d = geometry
        self.index = index
        self.joints, self.links = FINGERS[index][:2], FINGERS[index][2:]
        self.start = [min(prox, self.upper_p), min(dist, self.upper_d)]
        self.phase = 1  # 1: both joints close, 2: only the distal joint closes
        self.t = 0.0
        self.t_lo, self.t_hi = 0.0, None
        self.done = False
        self.missed = False
        self.contacts: list[Contact] = []
        reach_p = length_p + length_d + _RADIUS_BOUND
        reach_d = length_d + _RADIUS_BOUND
        self.speed = {1: (length_p + _RADIUS_BOUND, reach_p + reach_d), 2: (0.0, reach_d)}

    @property
    def moving_links(self) -> tuple[int, ...]:
        return (0, 1) if self.phase == 1 else (1,)

    @property
    def t_max(self) -> float:
        if self.phase == 1:
            return max(self.upper_p - self.start[0], self.upper_d - self.start[1], 0.0)
        return max(self.upper_d - self.start[1], 0.0)

    def values(self) -> dict[str, float]:
        prox = self.start[0] + (self.t if self.phase == 1 else 0.0)
        return {self.joints[0]: min(prox, self.upper_p),
                self.joints[1]: min(self.start[1] + self.t, self.upper_d)}

    def update(self, gaps: dict[str, tuple[float, tuple | None]], world: GraspWorld) -> None:
        """Advance from the gaps measured at the current t."""
        moving = [(link, *gaps.get(self.links[link], (QUERY_DISTANCE, None)))
                  for link in self.moving_links]
        gap = min(g for _, g, _ in moving)
        bracket_closed = self.t_hi is not None and self.t_hi - self.t_lo < 1e-9
        if -CONTACT_TOL <= gap <= CONTACT_TOL or (bracket_closed and gap <= CONTACT_TOL):
            touching = [(link, rec) for link, g, rec in moving if g <= CONTACT_TOL]
            for link, rec in touching:
                self.contacts.append(_contact(world, self.index, link, rec))
            if any(link == 1 for link, _ in touching):
                self.done = True
                return
            # proximal contact: freeze the proximal joint, the distal one goes on
            values = self.values()
            self.start = [values[self.joints[0]], values[self.joints[1]]]
            self.phase, self.t, self.t_lo, self.t_hi = 2, 0.0, 0.0, None
            if self.t_max <= 0.0:
                self.done = True
            else:
                self.t = min(STEP, self.t_max)
            return
        if gap > CONTACT_TOL:
            self.t_lo = self.t
            if self.t_hi is None:
                if self.t >= self.t_max:  # every joint at its limit, no contact
                    self.done = True
                    self.missed = not self.contacts
                    return
                speed = sum(self.speed[self.phase])
                self.t = min(self.t + max(gap / speed, STEP), self.t_max)
                return
        else:
            self.t_hi = self.t
        self.t = 0.5 * (self.t_lo + self.t_hi)


def _contact(world: GraspWorld, finger: int, link: int, record: tuple) -> Contact:
    obj = world.obj
    point = obj.to_object(np.asarray(record[6], dtype=float))
    part = obj.nearest_part(point[None])  # the part whose surface the point is on
    projected, face_normal = obj.surface(point[None], part)
    # pybullet's normal on B (the object) points from B to A (the finger) for our fixed body
    # order: the outward separating direction. On a face it is the face normal; at an edge
    # or corner it lies in the cone of the adjacent faces. Far from the face normal only
    # where the point is not on a face interior; use it there.
    outward = obj.pose[:3, :3].T @ np.asarray(record[7], dtype=float)
    outward /= max(np.linalg.norm(outward), 1e-300)
    normal = face_normal[0] if face_normal[0] @ -outward > 1 - 1e-6 else -outward
    return Contact(finger, link, projected[0], normal)


def auto_close(world: GraspWorld, root_pose: np.ndarray, preshape: np.ndarray) -> CloseResult:
    """Close the hand placed at ``root_pose`` from ``preshape`` until contact.

    Args:
        world: the grasp world (hand and object).
        root_pose: (4, 4) world pose of the hand root (the arm's flange frame).
        preshape: (7,) hand DOF: spread, f1 proximal, f1 distal, f2 ..., f3 ... (radians).
    """
    world.set_hand(root_pose, hand_joint_values(np.asarray(preshape, dtype=float)))
    if any(rec[8] < -START_TOL for rec in world.closest(0.0)):
        return CloseResult(start_collision=True)
    geometry = _finger_geometry()
    fingers = [_Finger(i, preshape[1 + 2 * i], preshape[2 + 2 * i], geometry) for i in range(3)]
    link_names = {world.link_index[link]: link for f in fingers for link in f.links}
    iterations = 0
    while iterations < MAX_ITERATIONS:
        active = [f for f in fingers if not f.done]
        if not active:
            break
        values: dict[str, float] = {}
        for finger in active:
            values.update(finger.values())
        world.set_joints(values)
        gaps: dict[str, tuple[float, tuple | None]] = {}
        for rec in world.closest(QUERY_DISTANCE):
            name = link_names.get(rec[3])
            if name is not None and (name not in gaps or rec[8] < gaps[name][0]):
                gaps[name] = (rec[8], rec)
        iterations += 1
        for finger in active:
            finger.update(gaps, world)
    for finger in fingers:  # out of iterations: whatever was found stands
        finger.done = True
    joints = np.array(preshape, dtype=float)
    for f in fingers:
        values = f.values()
        joints[1 + 2 * f.index], joints[2 + 2 * f.index] = values[f.joints[0]], values[f.joints[1]]
    contacts = [c for f in fingers for c in f.contacts]
    return CloseResult(False, contacts, tuple(f.missed for f in fingers), joints, iterations)
